"""Fingerspelling handshapes on the corpus' hand model: the human side of notebook 12's gallery.

Each letter is a set of joint angles of the hand model of :mod:`nlo_lab.corpus.arm_kinematics`
(per finger, thumb..pinky: ``FINGER_JOINT_NAMES``; thumb: CMC flexion, CMC abduction, MCP, IP;
fingers: MCP flexion, spread, PIP, DIP), our own estimates of the one-handed manual alphabet's
shapes (American manual alphabet, letters without movement), written for this project. The hand is
held in front of the right shoulder, fingers up and the palm facing forward, as when spelling.

::

    from nlo_lab.corpus.fingerspelling import fingerspelling_demonstration
    demo = fingerspelling_demonstration("ABCLOVY")   # one frame per letter, a Demonstration
"""

from __future__ import annotations

import numpy as np

from nlo_lab.corpus.arm_kinematics import arm_fk
from nlo_lab.corpus.body import BodyParams
from nlo_lab.corpus.signs import HANDSHAPES, RELAXED
from nlo_lab.errors import SettingsError
from nlo_lab.human.demonstration import Demonstration

__all__ = ["LETTERS", "letter_angles", "fingerspelling_demonstration", "hand_landmarks", "SPELLING_ARM"]

_D = np.pi / 180.0
_EXT = [0, 0, 0, 0]
_CURL = [85, 0, 100, 70]  # a finger curled into the fist
_HALF = [60, 0, 80, 50]  # a finger bent towards the thumb (D, O-like)
_HOOK = [10, 0, 95, 65]  # bent at the middle and end joints only (X, E)
_THUMB_OVER = [15, 20, 40, 80]  # closed over the curled fingers
_THUMB_SIDE = [-5, 5, 5, 5]  # alongside the index
_THUMB_OUT = [-15, 25, 0, 0]  # stretched away
_THUMB_ACROSS = [45, 40, 45, 20]  # folded across the palm


def _deg(*fingers) -> np.ndarray:
    return np.array(fingers, dtype=np.float64) * _D  # (5, 4) [rad]


# letter -> (5, 4) [rad], thumb..pinky
LETTERS: dict[str, np.ndarray] = {
    "A": _deg(_THUMB_SIDE, _CURL, _CURL, _CURL, _CURL),
    "B": _deg(_THUMB_ACROSS, _EXT, _EXT, _EXT, _EXT),
    "C": HANDSHAPES["C"].copy(),
    "D": _deg([25, 50, 35, 30], _EXT, _HALF, _HALF, _HALF),
    "E": _deg([40, 35, 50, 45], _HOOK, _HOOK, _HOOK, _HOOK),
    "F": _deg([20, 45, 25, 40], [45, 0, 50, 30], [0, 3, 0, 0], [0, 10, 0, 0], [0, 16, 0, 0]),
    "I": HANDSHAPES["I"].copy(),
    "L": HANDSHAPES["L"].copy(),
    "O": HANDSHAPES["O"].copy(),
    "S": HANDSHAPES["fist"].copy(),
    "U": _deg(_THUMB_OVER, _EXT, _EXT, _CURL, _CURL),
    "V": _deg(_THUMB_OVER, [0, 15, 0, 0], [0, -12, 0, 0], _CURL, _CURL),
    "W": HANDSHAPES["W"].copy(),
    "X": _deg(_THUMB_OVER, _HOOK, _CURL, _CURL, _CURL),
    "Y": HANDSHAPES["Y"].copy(),
    "5": HANDSHAPES["spread"].copy(),
}
# right arm (``ARM_JOINT_NAMES``) holding the hand up in front of the shoulder, palm forward
SPELLING_ARM = np.array([50, 0, 0, 110, 80, 0, 0], dtype=np.float64) * _D
_RESTING_ARM = np.array([0, 10, 0, 20, 0, 0, 0], dtype=np.float64) * _D  # left arm hanging


def letter_angles(letter: str) -> np.ndarray:
    """``(5, 4)`` [rad] finger angles of a letter (a copy)."""
    if letter not in LETTERS:
        raise SettingsError(f"no handshape for letter {letter!r}; expected one of {''.join(LETTERS)}")
    return LETTERS[letter].copy()


def fingerspelling_demonstration(letters: str = "".join(LETTERS), body: BodyParams | None = None, fps: float = 2.0) -> Demonstration:
    """One frame per letter: the right hand spells, the left arm hangs with a relaxed hand.

    Args:
        letters: keys of ``LETTERS`` in order (repeats allowed).
        body: the signer's dimensions (default: the nominal adult of ``BodyParams()``).
        fps: the frame rate (letters are held, so slow).

    Returns:
        A :class:`~nlo_lab.human.Demonstration` with ``meta["letters"]``.
    """
    body = body or BodyParams()
    fingers = np.stack([letter_angles(c) for c in letters]) if letters else np.zeros((0, 5, 4))
    if not len(fingers):
        raise SettingsError("no letters to spell")
    T = len(letters)
    right = arm_fk(body, np.broadcast_to(SPELLING_ARM, (T, 7)), fingers, "right")
    left = arm_fk(body, np.broadcast_to(_RESTING_ARM, (T, 7)), np.broadcast_to(RELAXED, (T, 5, 4)), "left")
    poses = (left, right)
    return Demonstration(
        fps=fps,
        arm_positions=np.stack([np.stack([p.shoulder, p.elbow, p.wrist], axis=1) for p in poses], axis=1),
        arm_mask=np.ones((T, 2, 3), dtype=bool),
        wrist_rotations=np.stack([p.wrist_rotation for p in poses], axis=1),
        wrist_mask=np.ones((T, 2), dtype=bool),
        finger_positions=np.stack([np.stack([p.finger_base, p.finger_tip], axis=2) for p in poses], axis=1),
        finger_mask=np.ones((T, 2, 5), dtype=bool),
        name="fingerspelling " + letters,
        meta={"source": "nlo_lab fingerspelling handshapes", "letters": list(letters)},
    )


def hand_landmarks(letter: str, body: BodyParams | None = None) -> np.ndarray:
    """``(21, 3)`` [m] the letter's hand in MediaPipe's landmark order (0 wrist; per finger, thumb..pinky,
    four points: thumb CMC, MCP, IP, tip; fingers MCP, PIP, DIP, tip), in the wrist frame (x wrist ->
    middle knuckle, y little -> index knuckle, z = x × y)."""
    body = body or BodyParams()
    pose = arm_fk(body, SPELLING_ARM, letter_angles(letter), "right")
    points = np.concatenate([pose.wrist[None], pose.chain[:, 1:].reshape(20, 3)])
    return (points - pose.wrist) @ pose.wrist_rotation

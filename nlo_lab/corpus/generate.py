"""One sequence of the synthetic corpus: a sentence of signs with transitions, checked until plausible.

A sentence of 2-6 signs by one signer starts and ends at the signer's rest pose.
Transitions between signs (0.2-0.4 s, up to 0.6 s for the longest moves) and to/from rest
(0.4-0.9 s) are minimum-jerk in joint space. Every stretch is checked as it is added
(:func:`plausible`): joint angles inside ``ARM_RANGES`` / ``FINGER_RANGES``, every hand point at
least ``CLEARANCE`` from torso, neck and head, the elbows ``ELBOW_CLEARANCE`` outside the torso,
the two hands at least ``HAND_CLEARANCE`` apart, wrist speed and acceleration below
``WRIST_SPEED_LIMIT`` and ``WRIST_ACCEL_LIMIT``, fingertip acceleration below
``FINGERTIP_ACCEL_LIMIT``; a sign that fails is redrawn.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from nlo_lab.corpus.arm_kinematics import arm_fk, wrist_position
from nlo_lab.corpus.body import ARM_RANGES, FINGER_RANGES, BodyParams, body_signed_distance, torso_signed_distance
from nlo_lab.corpus.sign_motion import Signer, sign_segment
from nlo_lab.corpus.signs import RELAXED, Sign, minimum_jerk
from nlo_lab.human.demonstration import Demonstration

__all__ = [
    "CLEARANCE",
    "HAND_CLEARANCE",
    "ELBOW_CLEARANCE",
    "WRIST_ACCEL_LIMIT",
    "WRIST_SPEED_LIMIT",
    "FINGERTIP_ACCEL_LIMIT",
    "Clip",
    "plausible",
    "generate_sequence",
]

CLEARANCE = 0.01  # [m] minimum distance of any hand point to torso, neck or head
HAND_CLEARANCE = 0.01  # [m] minimum distance between points of the two hands
ELBOW_CLEARANCE = 0.03  # [m] minimum distance of the elbow joint centre from the torso (about the arm's radius)
WRIST_ACCEL_LIMIT = 25.0  # [m/s^2] generation bound on the finite-difference wrist acceleration
WRIST_SPEED_LIMIT = 2.2  # [m/s] generation bound on the wrist speed (fast signing peaks near 2 m/s)
FINGERTIP_ACCEL_LIMIT = 60.0  # [m/s^2] the same for fingertips (they also swing with wrist rotations)
_FPS_CHOICES = (15, 20, 25, 30)
_MIN_FRAMES, _MAX_FRAMES = 60, 250


@dataclass(frozen=True)
class Clip:
    """A generated sequence: the demonstration and the body-model angles that made it."""

    demo: Demonstration
    arm: np.ndarray  # (T, 2, 7) [rad], sides (left, right)
    fingers: np.ndarray  # (T, 2, 5, 4) [rad]


def _wrists(body: BodyParams, arm: np.ndarray, fingers=None) -> np.ndarray:
    """``(n, 2, 3)`` wrist positions (left, right)."""
    return np.stack([wrist_position(body, arm[:, s], side) for s, side in enumerate(("left", "right"))], 1)


_STAGGER = 0.3  # fraction of a transition by which one arm leads the other around a base hand


def _phases(tau: np.ndarray, lead: int | None) -> np.ndarray:
    """``(n, 2)`` minimum-jerk phases of the (left, right) arms; the ``lead`` arm moves first."""
    if lead is None:
        return np.repeat(minimum_jerk(tau)[:, None], 2, axis=1)
    early = minimum_jerk(tau / (1 - _STAGGER))
    late = minimum_jerk((tau - _STAGGER) / (1 - _STAGGER))
    return np.stack([early, late] if lead == 0 else [late, early], axis=1)


def _transition(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray], frames: int, lead: int | None = None):
    """``frames`` interior frames of a minimum-jerk joint-space move from the last frame of ``a`` to the first of ``b``."""
    s = _phases(np.arange(1, frames + 1) / (frames + 1), lead)  # (frames, 2)
    qa, qb = a[0][-1], b[0][0]
    fa, fb = a[1][-1], b[1][0]
    return qa + (qb - qa) * s[:, :, None], fa + (fb - fa) * s[:, :, None, None]


def _transition_frames(body, a, b, fps: float, rng: np.random.Generator, rest_move: bool, lead: int | None = None) -> int:
    """Interior frames of a transition, long enough for its path.

    The joint-space path's shape does not depend on the duration T, so its peak wrist speed
    and acceleration are ``k1 / T`` and ``k2 / T^2``; T is the shortest duration that keeps them
    near 2.0 m/s and 18 m/s^2, within 0.2-0.6 s between signs (0.2-0.4 s unless the move is
    long) and 0.4-0.9 s to or from the rest pose.
    """
    tau = np.linspace(0.0, 1.0, 41)
    s = _phases(tau, lead)
    qa, qb = a[0][-1], b[0][0]
    q = qa + (qb - qa) * s[:, :, None]  # (41, 2, 7)
    w = _wrists(body, q, None)  # (41, 2, 3)
    d1 = np.diff(w, axis=0) / (tau[1] - tau[0])
    k1 = np.linalg.norm(d1, axis=-1).max()
    k2 = np.linalg.norm(np.diff(d1, axis=0), axis=-1).max() / (tau[1] - tau[0])
    lo, hi = (0.4, 0.9) if rest_move else (0.2, 0.6)
    needed = max(k1 / 2.0, np.sqrt(k2 / 18.0))
    duration = float(np.clip(needed * rng.uniform(1.0, 1.15), lo, hi))
    return max(1, int(round(duration * fps)) - 1)


def _rest_segment(signer: Signer, frames: int):
    arm = np.broadcast_to(signer.rest, (frames, 2, 7)).copy()
    return arm, np.broadcast_to(RELAXED, (frames, 2, 5, 4)).copy()


def plausible(body: BodyParams, arm: np.ndarray, fingers: np.ndarray, fps: float) -> tuple[bool, list]:
    """The generator's checks; returns (ok, the two ArmPose objects)."""
    eps = 1e-9
    if np.any(arm < ARM_RANGES[:, 0] - eps) or np.any(arm > ARM_RANGES[:, 1] + eps):
        return False, []
    if np.any(fingers < FINGER_RANGES[..., 0] - eps) or np.any(fingers > FINGER_RANGES[..., 1] + eps):
        return False, []
    poses = [arm_fk(body, arm[:, s], fingers[:, s], side) for s, side in enumerate(("left", "right"))]
    pts = [p.hand_points() for p in poses]  # (T, 26, 3) each
    if min(body_signed_distance(body, p).min() for p in pts) < CLEARANCE:
        return False, poses
    if min(torso_signed_distance(body, p.elbow).min() for p in poses) < ELBOW_CLEARANCE:
        return False, poses
    near = np.linalg.norm(poses[0].wrist - poses[1].wrist, axis=-1) < 0.5  # two hands span < 0.25 m each
    if near.any():
        hand_gap = np.linalg.norm(pts[0][near][:, :, None, :] - pts[1][near][:, None, :, :], axis=-1).min()
        if hand_gap < HAND_CLEARANCE:
            return False, poses
    for p in poses:
        if np.linalg.norm(np.diff(p.wrist, axis=0), axis=-1).max() * fps > WRIST_SPEED_LIMIT:
            return False, poses
        if np.linalg.norm(np.diff(p.wrist, n=2, axis=0), axis=-1).max() * fps**2 > WRIST_ACCEL_LIMIT:
            return False, poses
        if np.linalg.norm(np.diff(p.finger_tip, n=2, axis=0), axis=-1).max() * fps**2 > FINGERTIP_ACCEL_LIMIT:
            return False, poses
    return True, poses


def generate_sequence(name: str, scenario: str, split: str, lexicon: Mapping[str, Sign], signers: Sequence[Signer],
                      rng: np.random.Generator, seed: int) -> Clip | None:
    """One sentence, built sign by sign: a sign whose transition or motion is implausible is redrawn.

    Args:
        name, scenario, split, seed: recorded in the demonstration (``name``, ``meta``).
        lexicon: the scenario's signs (gloss -> :class:`~nlo_lab.corpus.signs.Sign`).
        signers: the corpus' signers; one is drawn.
        rng: the only source of randomness (same stream, same sequence).

    Returns:
        The sequence, or None when this random stream gives no plausible sentence
        (the caller draws again with the next stream).
    """
    signer = signers[int(rng.integers(len(signers)))]
    body = signer.body
    fps = float(rng.choice(_FPS_CHOICES))
    glosses = list(lexicon)
    k = int(rng.integers(2, 7))
    head = _rest_segment(signer, int(round(rng.uniform(0.2, 0.5) * fps)) + 1)
    tail_frames = int(round(rng.uniform(0.2, 0.5) * fps)) + 1
    budget = _MAX_FRAMES - tail_frames - int(0.7 * fps) - 1  # room left for the way back to rest
    arms, fings, ranges, signs = [head[0]], [head[1]], [[0, len(head[0])]], []
    frames = len(head[0])
    for _ in range(4 * k):
        if len(signs) == k:
            break
        gloss = glosses[int(rng.integers(len(glosses)))]
        if signs and gloss == signs[-1].gloss:
            continue
        if frames + int(1.6 * fps) + 2 > budget:  # the longest sign and transition would not fit
            break
        sign = lexicon[gloss]
        seg = sign_segment(sign, signer, fps, rng)
        # around a base hand the base arrives first and the dominant hand leaves first
        dom = 0 if signer.dominant == "left" else 1
        lead = 1 - dom if sign.pattern == "base_hand" else (dom if signs and signs[-1].pattern == "base_hand" else None)
        prev = (arms[-1], fings[-1])
        qa, fa = _transition(prev, seg, _transition_frames(body, prev, seg, fps, rng, not signs, lead), lead)
        if frames + len(qa) + len(seg[0]) > budget:
            break
        window = (np.concatenate([arms[-1][-2:], qa, seg[0]]), np.concatenate([fings[-1][-2:], fa, seg[1]]))
        if not plausible(body, window[0], window[1], fps)[0]:
            continue
        arms += [qa, seg[0]]
        fings += [fa, seg[1]]
        ranges.append([frames + len(qa), frames + len(qa) + len(seg[0])])
        frames += len(qa) + len(seg[0])
        signs.append(sign)
    if len(signs) < 2:
        return None
    tail = _rest_segment(signer, max(tail_frames, _MIN_FRAMES - frames - int(0.7 * fps)))
    lead = (0 if signer.dominant == "left" else 1) if signs[-1].pattern == "base_hand" else None
    prev = (arms[-1], fings[-1])
    qa, fa = _transition(prev, tail, _transition_frames(body, prev, tail, fps, rng, True, lead), lead)
    window = (np.concatenate([arms[-1][-2:], qa, tail[0]]), np.concatenate([fings[-1][-2:], fa, tail[1]]))
    if not plausible(body, window[0], window[1], fps)[0]:
        return None
    arm = np.concatenate(arms + [qa, tail[0]])
    fingers = np.concatenate(fings + [fa, tail[1]])
    if not _MIN_FRAMES <= len(arm) <= _MAX_FRAMES:
        return None
    # every frame was checked in the overlapping windows above
    poses = [arm_fk(body, arm[:, s], fingers[:, s], side) for s, side in enumerate(("left", "right"))]
    T = len(arm)
    demo = Demonstration(
        fps=fps,
        arm_positions=np.stack([np.stack([p.shoulder, p.elbow, p.wrist], axis=1) for p in poses], axis=1),
        arm_mask=np.ones((T, 2, 3), dtype=bool),
        wrist_rotations=np.stack([p.wrist_rotation for p in poses], axis=1),
        wrist_mask=np.ones((T, 2), dtype=bool),
        finger_positions=np.stack([np.stack([p.finger_base, p.finger_tip], axis=2) for p in poses], axis=1),
        finger_mask=np.ones((T, 2, 5), dtype=bool),
        name=name,
        meta={
            "source": "nlo_lab synthetic sign corpus",
            "scenario": scenario,
            "split": split,
            "signer": signer.name,
            "dominant": signer.dominant,
            "body": asdict(signer.body),
            "signs": [s.gloss for s in signs],
            "sign_components": [s.as_dict() for s in signs],
            "sign_frames": ranges[1:],
            "seed": seed,
        },
    )
    return Clip(demo, arm, fingers)

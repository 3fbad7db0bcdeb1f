"""Forward and inverse kinematics of the synthetic signers' arms and hands (the body of :mod:`nlo_lab.corpus.body`).

Frame: the body frame of :mod:`nlo_lab.human.demonstration` (origin at the centre of
the shoulder joints, X forward, Y to the signer's left, Z up). Units: metres, radians.

Arm (per side, 7 angles, ``ARM_JOINT_NAMES``): 3-DOF shoulder as intrinsic Euler angles
``R_shoulder = Ry(-flexion) Rx(-abduction) Rz(rotation)`` (all zero = arm hanging
straight down, palm facing the thigh, thumb forward), elbow flexion, forearm pronation
(positive) / supination (negative) about the forearm axis, wrist flexion (towards the
palm) / extension and ulnar (positive) / radial deviation. The angles mean the same on
both sides: the left arm is the mirror image (Y -> -Y) of a right arm with the same angles.

Hand (per side, ``(5, 4)`` angles thumb..pinky, ``FINGER_JOINT_NAMES``): every finger is a
chain ``root -> j1 -> j2 -> j3 -> tip``. For index..pinky the root->j1 segment is the
metacarpal (fixed in the palm), j1 = MCP (flexion + spread), j2 = PIP, j3 = DIP. For the
thumb the root->j1 segment is a fixed carpal offset, j1 = CMC (flexion across the palm +
palmar abduction, with coupled axial rotation = opposition), j2 = MCP, j3 = IP. The
finger *base* of a Demonstration is the MCP joint: chain point 2 for the thumb, 1 otherwise
(``BASE_INDEX``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nlo_lab import rotations
from nlo_lab.corpus.body import BASE_INDEX, BodyParams
from nlo_lab.errors import SettingsError

__all__ = [
    "ArmPose",
    "rot_x",
    "rot_y",
    "rot_z",
    "arm_fk",
    "hand_frame",
    "arm_ik",
    "knuckle_centre",
    "wrist_position",
]

# Chain roots and j1 joints (MCP for fingers, CMC for the thumb) [fraction of hand length].
_ROOTS = np.array([[0.06, 0.03, -0.04], [0.05, 0.0, -0.06], [0.015, 0.0, -0.06], [-0.03, 0.0, -0.06], [-0.07, 0.0, -0.06]])
_J1 = np.array([[0.13, 0.08, -0.13], [0.125, 0.02, -0.365], [0.015, 0.0, -0.373], [-0.09, 0.02, -0.345], [-0.185, 0.04, -0.30]])
_SPREAD_SIGN = np.array([1.0, 1.0, 1.0, -1.0, -1.0])  # +spread = away from the middle finger (radial for index)


def _norm(v: np.ndarray, keepdims: bool = False) -> np.ndarray:
    """Euclidean norm over the last axis (cheaper than np.linalg.norm on small arrays)."""
    return np.sqrt(np.sum(v * v, axis=-1, keepdims=keepdims))


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis (cheaper than np.cross on small arrays)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _rot(a: np.ndarray, i: int, j: int) -> np.ndarray:
    """Rotations by ``a`` in the (i, j) coordinate plane, ``(...,) -> (..., 3, 3)``."""
    a = np.asarray(a, dtype=np.float64)
    r = np.zeros(a.shape + (3, 3))
    c, s = np.cos(a), np.sin(a)
    k = 3 - i - j
    r[..., k, k] = 1.0
    r[..., i, i] = c
    r[..., j, j] = c
    r[..., i, j] = -s
    r[..., j, i] = s
    return r


def rot_x(a: np.ndarray) -> np.ndarray:
    """Rotations about X, ``(...,) -> (..., 3, 3)``."""
    return _rot(a, 1, 2)


def rot_y(a: np.ndarray) -> np.ndarray:
    """Rotations about Y, ``(...,) -> (..., 3, 3)``."""
    return _rot(a, 2, 0)


def rot_z(a: np.ndarray) -> np.ndarray:
    """Rotations about Z, ``(...,) -> (..., 3, 3)``."""
    return _rot(a, 0, 1)


def _thumb_base() -> np.ndarray:
    """Rest frame of the thumb at the CMC joint, columns in hand coordinates.

    Local -z is the metacarpal (distal, radial, a little palmar); local +y the direction of
    CMC flexion (across the palm, ulnar and palmar); local +x the direction of palmar abduction.
    """
    down = np.array([0.5, 0.25, -0.83])
    down /= np.linalg.norm(down)
    flex = np.array([-0.85, 0.5, 0.0])
    flex -= flex.dot(down) * down
    flex /= np.linalg.norm(flex)
    z = -down
    return np.stack([np.cross(flex, z), flex, z], axis=-1)


_BASES = np.stack([_thumb_base()] + [np.eye(3)] * 4)  # (5, 3, 3)
_OPPOSITION = 0.6  # axial rotation of the thumb metacarpal per radian of palmar abduction


@dataclass(frozen=True)
class ArmPose:
    """Forward kinematics of one arm and hand; leading dimensions ``...`` as the angles.

    Attributes:
        shoulder, elbow, wrist: ``(..., 3)`` [m] joint centres in the body frame.
        chain: ``(..., 5, 5, 3)`` [m] per finger (thumb..pinky) the points root, j1, j2, j3, tip.
        wrist_rotation: ``(..., 3, 3)`` ``R_body_wrist`` in the Demonstration convention,
            computed from the hand points (wrist, middle and index/pinky MCPs).
    """

    shoulder: np.ndarray
    elbow: np.ndarray
    wrist: np.ndarray
    chain: np.ndarray
    wrist_rotation: np.ndarray

    @property
    def finger_base(self) -> np.ndarray:
        """``(..., 5, 3)`` MCP joints."""
        return self.chain[..., np.arange(5), BASE_INDEX, :]

    @property
    def finger_tip(self) -> np.ndarray:
        """``(..., 5, 3)`` fingertips."""
        return self.chain[..., 4, :]

    def hand_points(self) -> np.ndarray:
        """``(..., 26, 3)`` wrist and all finger chain points (for clearance checks)."""
        flat = self.chain.reshape(self.chain.shape[:-3] + (25, 3))
        return np.concatenate([self.wrist[..., None, :], flat], axis=-2)


_MIRROR = np.array([1.0, -1.0, 1.0])


def _side_sign(side: str) -> float:
    if side not in ("left", "right"):
        raise SettingsError(f"side must be 'left' or 'right', got {side!r}")
    return 1.0 if side == "left" else -1.0


def _forearm_and_hand(arm: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rotations of upper arm, forearm and hand (right-arm canonical), ``(..., 3, 3)`` each."""
    r_upper = rot_y(-arm[..., 0]) @ rot_x(-arm[..., 1]) @ rot_z(arm[..., 2])
    r_fore = r_upper @ rot_y(-arm[..., 3]) @ rot_z(arm[..., 4])
    r_hand = r_fore @ rot_x(arm[..., 5]) @ rot_y(arm[..., 6])
    return r_upper, r_fore, r_hand


def _finger_chain(params: BodyParams, fingers: np.ndarray) -> np.ndarray:
    """Finger chain points in hand coordinates (right hand), ``(..., 5, 4) -> (..., 5, 5, 3)``."""
    L = params.hand_length
    seg = params.segment_lengths()  # (5, 3)
    f1, spread, f2, f3 = (fingers[..., i] for i in range(4))  # (..., 5)
    twist = np.zeros_like(spread)
    twist[..., 0] = _OPPOSITION * spread[..., 0]
    spread_angle = spread * _SPREAD_SIGN
    # Spread: about the palm normal for the fingers; palmar abduction for the thumb (same local axis
    # of its base frame), then the thumb's coupled axial rotation (opposition), then flexion.
    r1 = _BASES @ rot_y(-spread_angle) @ rot_z(twist) @ rot_x(f1)
    down = np.array([0.0, 0.0, -1.0])
    p0 = np.broadcast_to(_ROOTS * L, fingers.shape[:-1] + (3,))
    p1 = np.broadcast_to(_J1 * L, fingers.shape[:-1] + (3,))
    p2 = p1 + (r1 @ down) * seg[:, 0, None]
    r2 = r1 @ rot_x(f2)
    p3 = p2 + (r2 @ down) * seg[:, 1, None]
    r3 = r2 @ rot_x(f3)
    tip = p3 + (r3 @ down) * seg[:, 2, None]
    return np.stack([p0, p1, p2, p3, tip], axis=-2)


def hand_frame(wrist: np.ndarray, finger_base: np.ndarray) -> np.ndarray:
    """``R_body_wrist`` from hand points, ``(..., 3), (..., 5, 3) -> (..., 3, 3)``: :func:`nlo_lab.rotations.hand_frame`
    of the middle, index and little finger bases (MCP joints)."""
    return rotations.hand_frame(wrist, finger_base[..., 2, :], finger_base[..., 1, :], finger_base[..., 4, :])


def arm_fk(params: BodyParams, arm: np.ndarray, fingers: np.ndarray, side: str) -> ArmPose:
    """Forward kinematics of one arm and hand.

    Args:
        params: the signer's dimensions.
        arm: ``(..., 7)`` [rad] angles in ``ARM_JOINT_NAMES`` order.
        fingers: ``(..., 5, 4)`` [rad] finger angles (thumb..pinky, ``FINGER_JOINT_NAMES``).
        side: ``"left"`` (+Y) or ``"right"`` (-Y).

    Returns:
        The joint centres, finger chains and wrist orientation in the body frame.
    """
    sign = _side_sign(side)
    arm = np.asarray(arm, dtype=np.float64)
    fingers = np.asarray(fingers, dtype=np.float64)
    if arm.shape[-1:] != (7,) or fingers.shape[-2:] != (5, 4) or arm.shape[:-1] != fingers.shape[:-2]:
        raise SettingsError(f"arm_fk needs arm (..., 7) and fingers (..., 5, 4) angles, got {arm.shape} and {fingers.shape}")
    shoulder, elbow, wrist, r_hand = _arm_chain(params, arm)
    local = _finger_chain(params, fingers)  # (..., 5, 5, 3)
    chain = wrist[..., None, None, :] + np.einsum("...ij,...fpj->...fpi", r_hand, local)
    if sign > 0:  # the left arm mirrors the right one
        shoulder, elbow, wrist, chain = (p * _MIRROR for p in (shoulder, elbow, wrist, chain))
    base = chain[..., np.arange(5), BASE_INDEX, :]
    return ArmPose(shoulder, elbow, wrist, chain, hand_frame(wrist, base))


def _arm_chain(params: BodyParams, arm: np.ndarray):
    """Shoulder, elbow, wrist ``(..., 3)`` and hand rotation ``(..., 3, 3)`` of a right arm."""
    r_upper, r_fore, r_hand = _forearm_and_hand(arm)
    shoulder = np.broadcast_to(np.array([0.0, -params.shoulder_width / 2, 0.0]), arm.shape[:-1] + (3,))
    elbow = shoulder - r_upper[..., :, 2] * params.upper_arm  # r @ (0, 0, -1) = -third column
    wrist = elbow - r_fore[..., :, 2] * params.forearm
    return shoulder, elbow, wrist, r_hand


def wrist_position(params: BodyParams, arm: np.ndarray, side: str) -> np.ndarray:
    """``(..., 3)`` [m] wrist joint centre for ``(..., 7)`` arm angles (cheap: no fingers)."""
    sign = _side_sign(side)
    wrist = _arm_chain(params, np.asarray(arm, dtype=np.float64))[2]
    return wrist * _MIRROR if sign > 0 else wrist


def knuckle_centre(params: BodyParams, arm: np.ndarray) -> np.ndarray:
    """``(..., 3)`` [m] mean of the index..little MCP joints of a *right* arm (cheap: no finger chain).

    The MCP joints of the four fingers are fixed in the palm, so their centre depends on the
    arm angles only. Mirror Y for the left arm.
    """
    _, _, wrist, r_hand = _arm_chain(params, np.asarray(arm, dtype=np.float64))
    return wrist + r_hand @ (_J1[1:].mean(axis=0) * params.hand_length)


def _euler_from_upper(r: np.ndarray) -> np.ndarray:
    """Shoulder angles (flexion, abduction, rotation) of ``r = Ry(-f) Rx(-a) Rz(r)``, ``(..., 3, 3) -> (..., 3)``."""
    beta = np.arcsin(np.clip(-r[..., 1, 2], -1.0, 1.0))
    alpha = np.arctan2(r[..., 0, 2], r[..., 2, 2])
    gamma = np.arctan2(r[..., 1, 0], r[..., 1, 1])
    return np.stack([-alpha, -beta, gamma], axis=-1)


def arm_ik(
    params: BodyParams,
    wrist_target: np.ndarray,
    side: str,
    distal: np.ndarray,
    elbow_out: float | np.ndarray = 0.5,
    elbow_forward: float | np.ndarray = 0.0,
) -> np.ndarray:
    """Analytic arm IK: shoulder and elbow angles that put the wrist on a target.

    The elbow swivel is chosen naturally: the elbow lies as far as possible along the
    reference direction ``(elbow_forward, elbow_out outwards, -1)``: down and a little out
    (raise ``elbow_forward`` to bring the elbow in front of the belly when reaching across).
    Targets beyond 97 % of the arm's reach are pulled in along the shoulder->target line.

    Args:
        params: the signer's dimensions.
        wrist_target: ``(..., 3)`` [m] in the body frame.
        side: ``"left"`` or ``"right"``.
        distal: ``(..., 3)`` [rad] forearm pronation, wrist flexion, wrist deviation (copied).
        elbow_out: sideways part of the elbow reference direction (0 = straight down).
        elbow_forward: forward part of the elbow reference direction.

    Returns:
        ``(..., 7)`` arm angles.
    """
    sign = _side_sign(side)
    target = np.asarray(wrist_target, dtype=np.float64)
    if sign > 0:
        target = target * _MIRROR  # solve as a right arm
    shoulder = np.array([0.0, -params.shoulder_width / 2, 0.0])
    lu, lf = params.upper_arm, params.forearm
    d = target - shoulder
    dist = _norm(d, True)
    axis = d / np.maximum(dist, 1e-9)
    dist = np.clip(dist, abs(lu - lf) + 0.05, 0.97 * (lu + lf))
    cos_e = (lu**2 + lf**2 - dist**2) / (2 * lu * lf)  # interior angle at the elbow
    elbow_flex = np.pi - np.arccos(np.clip(cos_e, -1.0, 1.0))[..., 0]
    # Elbow on the circle around the shoulder->wrist axis, nearest the reference direction.
    cos_a = (lu**2 + dist**2 - lf**2) / (2 * lu * dist)
    along = lu * cos_a
    radius = lu * np.sqrt(np.clip(1 - cos_a**2, 0.0, 1.0))
    out, fwd = np.broadcast_arrays(np.asarray(elbow_out, dtype=np.float64), np.asarray(elbow_forward, dtype=np.float64))
    ref = np.stack([fwd, -out, -np.ones_like(out)], axis=-1)  # down and out (right arm)
    ref = np.broadcast_to(ref, axis.shape)
    perp = ref - np.sum(ref * axis, axis=-1, keepdims=True) * axis
    perp = perp / np.maximum(_norm(perp, True), 1e-9)
    elbow = shoulder + axis * along + perp * radius
    wrist = shoulder + axis * dist
    u = (elbow - shoulder) / lu  # upper arm direction
    f = (wrist - elbow) / lf  # forearm direction
    se = np.sin(elbow_flex)[..., None]
    x = (f - np.cos(elbow_flex)[..., None] * u) / np.maximum(se, 1e-9)
    z = -u
    y = _cross(z, x)
    r_upper = np.stack([x, y, z], axis=-1)
    angles = np.concatenate([_euler_from_upper(r_upper), elbow_flex[..., None], np.asarray(distal, dtype=np.float64)], axis=-1)
    return angles

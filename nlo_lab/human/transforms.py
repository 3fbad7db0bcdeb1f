"""Geometric transforms of demonstrations: body frame, wrist frame, arm-length normalisation, resampling, robot mapping.

Conventions (see :mod:`nlo_lab.human.demonstration`): body frame with origin at
the centre of the shoulders, X forward, Y to the demonstrator's left, Z up;
metres; rotation matrices ``R_body_wrist`` whose columns are the wrist axes.
Quaternions are ``(x, y, z, w)`` (the authors' HDF5 order).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from nlo_lab.errors import DemonstrationError
from nlo_lab.human.demonstration import SIDES, Demonstration
from nlo_lab.rotations import hand_frame, matrix_to_quat, quat_to_matrix, slerp  # re-exported: their old home

__all__ = [
    "wrist_frame_from_hand",
    "body_frame_from_shoulders",
    "quat_to_matrix",
    "matrix_to_quat",
    "fill_gaps",
    "check_arm_lengths",
    "normalize_arm_lengths",
    "resample",
    "map_to_robot",
]

_EPS = 1e-9  # [m] below this a direction is undefined


def _normalize(v: np.ndarray) -> np.ndarray:
    """Unit vectors along the last axis; NaN where the norm is (near) zero."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > _EPS, v / np.where(n > _EPS, n, 1.0), np.nan)


def wrist_frame_from_hand(
    wrist: np.ndarray, index_base: np.ndarray, pinky_base: np.ndarray, middle_base: np.ndarray
) -> np.ndarray:
    """Wrist orientation ``(..., 3, 3)`` from four hand points ``(..., 3)``: :func:`nlo_lab.rotations.hand_frame`
    (x = wrist -> middle base, y = pinky base -> index base made orthogonal, z = x cross y; NaN where degenerate)."""
    return hand_frame(wrist, middle_base, index_base, pinky_base)


def body_frame_from_shoulders(
    left_shoulder: np.ndarray, right_shoulder: np.ndarray, up: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The body frame in a source frame, per frame.

    Y = right -> left shoulder (primary axis), Z = ``up`` made orthogonal to Y,
    X = Y x Z (forward). Origin = shoulder midpoint.

    Args:
        left_shoulder, right_shoulder: ``(T, 3)`` in the source frame.
        up: ``(3,)`` or ``(T, 3)`` an approximate up direction in the source frame.

    Returns:
        origin ``(T, 3)`` and ``R_src_body`` ``(T, 3, 3)`` (columns = body axes in source
        coordinates), so that ``p_body = R_src_body^T (p_src - origin)``. NaN where undefined.
    """
    ls, rs = np.asarray(left_shoulder, float), np.asarray(right_shoulder, float)
    y = _normalize(ls - rs)
    up = np.broadcast_to(np.asarray(up, float), y.shape)
    z = _normalize(up - np.sum(up * y, axis=-1, keepdims=True) * y)
    x = np.cross(y, z)
    return (ls + rs) / 2.0, np.stack([x, y, z], axis=-1)


# ----------------------------------------------------------------------------- gaps and checks
def fill_gaps(values: np.ndarray, valid: np.ndarray, max_gap: int) -> tuple[np.ndarray, np.ndarray]:
    """Linearly interpolate interior runs of invalid frames no longer than ``max_gap``.

    Runs touching the start or end of the clip are never filled (no extrapolation);
    longer runs stay invalid and are set to NaN.

    Args:
        values: ``(T, ...)`` samples (invalid ones may hold anything).
        valid: ``(T,)`` bool.
        max_gap: the longest run of missing frames to fill.

    Returns:
        ``(values, valid)``: new arrays, NaN where still invalid.
    """
    values = np.array(values, dtype=float, copy=True)
    valid = np.array(valid, dtype=bool, copy=True)
    T = valid.shape[0]
    t = 0
    while t < T:
        if valid[t]:
            t += 1
            continue
        start = t
        while t < T and not valid[t]:
            t += 1
        stop = t  # first valid frame after the run (or T)
        if start > 0 and stop < T and stop - start <= max_gap:
            a = (np.arange(start, stop) - (start - 1)) / (stop - (start - 1))
            a = a.reshape((-1,) + (1,) * (values.ndim - 1))
            values[start:stop] = (1 - a) * values[start - 1] + a * values[stop]
            valid[start:stop] = True
    values[~valid] = np.nan
    return values, valid


def check_arm_lengths(demo: Demonstration, path=None, min_length: float = 1e-6) -> None:
    """Raise :class:`DemonstrationError` if an arm is never fully observed (shoulder, elbow and wrist in one
    frame: retargeting scales by its lengths), or a valid frame has an upper arm or forearm shorter than
    ``min_length`` [m]. The readers' last check."""
    for s, side in enumerate(SIDES):
        p, m = demo.arm_positions[:, s], demo.arm_mask[:, s]
        if not m.all(axis=1).any():
            raise DemonstrationError(f"the {side} arm is never fully observed (shoulder, elbow and wrist in one frame)",
                                     path=path, field=f"{side}/arm")
        for (a, b), seg in (((0, 1), "upper_arm"), ((1, 2), "forearm")):
            ok = m[:, a] & m[:, b]
            length = np.linalg.norm(p[:, b] - p[:, a], axis=-1)
            bad = ok & (length < min_length)
            if bad.any():
                frame = int(np.argmax(bad))
                raise DemonstrationError(f"the {side} {seg} has zero length", path=path, frame=frame, field=f"{side}/{seg}")


# ----------------------------------------------------------------------------- transforms
def normalize_arm_lengths(demo: Demonstration, upper: float = 0.20, fore: float = 0.24) -> Demonstration:
    """Rescale each arm to the given segment lengths, keeping every segment's direction.

    Per frame the elbow is put at ``upper`` [m] from the shoulder along the observed
    shoulder->elbow direction and the wrist at ``fore`` [m] from the elbow along the
    observed elbow->wrist direction. The hand (finger points relative to the wrist)
    is scaled by ``(upper + fore) / human arm length`` (median lengths of that arm) and
    moved with the wrist. A point whose chain to the shoulder is broken (e.g. the elbow
    missing) becomes masked. Orientations are unchanged.

    Args:
        demo: the demonstration.
        upper: target upper-arm length [m] (> 0).
        fore: target forearm length [m] (> 0).

    Returns:
        A new :class:`Demonstration`; ``meta["arm_lengths_normalized"] = [upper, fore]``.
    """
    if not (upper > 0 and fore > 0):
        raise DemonstrationError(f"target arm lengths must be > 0, got upper={upper}, fore={fore}", field="arm_lengths")
    arms = demo.arm_positions.copy()
    arm_mask = demo.arm_mask.copy()
    fingers = demo.finger_positions.copy()
    finger_mask = demo.finger_mask.copy()
    for s, side in enumerate(SIDES):
        if not (arm_mask[:, s].all(axis=1)).any():
            continue  # never fully observed: nothing to rescale, keep the masks
        hu, hf = demo.arm_lengths(side)
        p = demo.arm_positions[:, s]
        m = demo.arm_mask[:, s]
        elbow_ok = m[:, 0] & m[:, 1]
        wrist_ok = elbow_ok & m[:, 2]
        with np.errstate(invalid="ignore"):
            new_elbow = p[:, 0] + upper * _normalize(p[:, 1] - p[:, 0])
            new_wrist = new_elbow + fore * _normalize(p[:, 2] - p[:, 1])
        elbow_ok &= np.isfinite(new_elbow).all(-1)
        wrist_ok &= elbow_ok & np.isfinite(new_wrist).all(-1)
        arms[:, s, 1] = np.where(elbow_ok[:, None], new_elbow, np.nan)
        arms[:, s, 2] = np.where(wrist_ok[:, None], new_wrist, np.nan)
        arm_mask[:, s, 1], arm_mask[:, s, 2] = elbow_ok, wrist_ok
        k = (upper + fore) / (hu + hf)
        rel = demo.finger_positions[:, s] - p[:, None, None, 2]  # (T, 5, 2, 3) relative to the old wrist
        fingers[:, s] = new_wrist[:, None, None] + k * rel
        finger_mask[:, s] &= wrist_ok[:, None]
    meta = dict(demo.meta)
    meta["arm_lengths_normalized"] = [float(upper), float(fore)]
    return Demonstration(demo.fps, arms, arm_mask, demo.wrist_rotations.copy(), demo.wrist_mask.copy(),
                         fingers, finger_mask, name=demo.name, meta=meta)


def resample(demo: Demonstration, fps: float) -> Demonstration:
    """The demonstration resampled at ``fps`` over the same time span.

    New frame ``k`` is at time ``k / fps``, for every time up to the last original
    frame. Positions are interpolated linearly, rotations by quaternion slerp. A
    resampled value is valid only if both original neighbours are valid (a time that
    falls exactly on an original frame takes that frame as it is).

    Args:
        demo: the demonstration.
        fps: the new frame rate (> 0).

    Returns:
        A new :class:`Demonstration` with ``fps`` frames per second.
    """
    try:
        fps = float(fps)
    except (TypeError, ValueError):
        raise DemonstrationError(f"fps must be a number, got {fps!r}", field="fps") from None
    if not np.isfinite(fps) or fps <= 0:
        raise DemonstrationError(f"fps must be > 0, got {fps!r}", field="fps")
    T = len(demo)
    n = int(np.floor((T - 1) * fps / demo.fps + 1e-9)) + 1
    x = np.arange(n) * demo.fps / fps  # positions on the original frame axis
    i0 = np.minimum(np.floor(x + 1e-9).astype(int), T - 1)
    a = np.clip(x - i0, 0.0, 1.0)
    exact = a < 1e-9
    i1 = np.where(exact, i0, np.minimum(i0 + 1, T - 1))
    a = np.where(exact, 0.0, a)

    def lerp(v: np.ndarray) -> np.ndarray:
        w = a.reshape((-1,) + (1,) * (v.ndim - 1))
        with np.errstate(invalid="ignore"):
            return np.where(exact.reshape(w.shape), v[i0], (1 - w) * v[i0] + w * v[i1])

    def both(m: np.ndarray) -> np.ndarray:
        return m[i0] & m[i1]

    R = demo.wrist_rotations
    wm = both(demo.wrist_mask)
    q = matrix_to_quat(np.where(demo.wrist_mask[..., None, None], R, np.eye(3)))  # (T, 2, 4)
    rot = quat_to_matrix(slerp(q[i0], q[i1], np.broadcast_to(a[:, None], wm.shape)))
    rot[~wm] = np.nan
    meta = dict(demo.meta)
    meta["resampled_from_fps"] = float(demo.fps)
    return Demonstration(
        fps,
        lerp(demo.arm_positions), both(demo.arm_mask),
        rot, wm,
        lerp(demo.finger_positions), both(demo.finger_mask),
        name=demo.name, meta=meta,
    )


def _to_numpy(x: Any) -> np.ndarray:
    if hasattr(x, "detach"):
        x = x.detach().cpu().numpy()
    return np.asarray(x, dtype=float)


def map_to_robot(demo: Demonstration, robot: Any) -> np.ndarray:
    """The human arm trajectories in the robot's frame (docs/DESIGN.md, "Metric").

    Per arm: positions relative to the shoulder, scaled by
    ``robot arm length / human arm length`` (upper + forearm; human: the median
    lengths of the demonstration, robot: ``robot.zero_pose_lengths(side)``), placed
    at ``robot.shoulder_position(side)``.

    Args:
        demo: the demonstration.
        robot: an object with ``zero_pose_lengths(side) -> (upper, fore)`` and
            ``shoulder_position(side) -> (3,)`` (a :class:`nlo_lab.robot.Robot`).

    Returns:
        ``(T, 2, 3, 3)`` float64 [m]: side x (shoulder, elbow, wrist) x xyz; NaN where masked.
    """
    out = np.full(demo.arm_positions.shape, np.nan)
    for s, side in enumerate(SIDES):
        hu, hf = demo.arm_lengths(side)
        ru, rf = (float(_to_numpy(v)) for v in robot.zero_pose_lengths(side))
        shoulder = _to_numpy(robot.shoulder_position(side)).reshape(3)
        k = (ru + rf) / (hu + hf)
        p = demo.arm_positions[:, s]
        m = demo.arm_mask[:, s] & demo.arm_mask[:, s, :1]  # needs the shoulder of the same frame
        mapped = shoulder + k * (p - p[:, :1])
        out[:, s] = np.where(m[..., None], mapped, np.nan)
    return out

"""Rotations, in one place, on :class:`scipy.spatial.transform.Rotation` (numpy side).

Conventions of the package:

* **RPY** as in URDF: roll, pitch, yaw about the *fixed* x, y, z axes, so
  ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (scipy's extrinsic ``"xyz"``).
* **Quaternions** ``(x, y, z, w)``, scalar last (scipy's and three.js's order),
  returned with ``w >= 0``.

Every function takes leading batch dimensions. The differentiable rotation
maths of the optimiser stays in torch (FK builds its rotations from the joint
axes with Rodrigues' formula, see :mod:`nlo_lab.robot.kinematics`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["rpy_to_matrix", "matrix_to_rpy", "quat_to_matrix", "matrix_to_quat", "slerp", "hand_frame"]

_EPS = 1e-9  # [m] below this length a hand direction is undefined


def _flat(a: np.ndarray, tail: tuple[int, ...]) -> tuple[np.ndarray, tuple[int, ...]]:
    """``a`` as ``(N, *tail)`` float64 for scipy (which wants one batch axis), and the batch shape."""
    a = np.asarray(a, dtype=np.float64)
    if a.shape[a.ndim - len(tail):] != tail:
        raise ValueError(f"expected an array of shape (..., {', '.join(map(str, tail))}), got {a.shape}")
    lead = a.shape[: a.ndim - len(tail)]
    return a.reshape((-1,) + tail), lead


def rpy_to_matrix(rpy: Sequence[float] | np.ndarray) -> np.ndarray:
    """URDF roll-pitch-yaw ``(..., 3)`` [rad] -> rotation matrices ``(..., 3, 3)`` ``Rz(y) Ry(p) Rx(r)``."""
    flat, lead = _flat(rpy, (3,))
    return Rotation.from_euler("xyz", flat).as_matrix().reshape(lead + (3, 3))


def matrix_to_rpy(R: np.ndarray) -> np.ndarray:
    """Inverse of :func:`rpy_to_matrix`: ``(..., 3, 3)`` -> ``(..., 3)`` [rad], pitch in [-pi/2, pi/2].

    Written out rather than scipy's ``as_euler``, because the angles are edge
    features of the robot graph that the shipped checkpoints were trained on:
    their branches must stay fixed. Two differ from scipy's: a yaw or roll of
    exactly ±pi comes out as ``atan2`` gives it for the matrix entries (scipy
    may return the other sign), and at gimbal lock (pitch = ±pi/2) the whole
    angle goes into yaw with roll 0 (scipy puts it into roll).
    """
    R = np.asarray(R, dtype=np.float64)
    # math.hypot, not np.hypot: they differ in the last bit, and these numbers reach the checkpoints.
    hypot = np.vectorize(math.hypot, otypes=[np.float64])
    pitch = np.arctan2(-R[..., 2, 0], hypot(R[..., 0, 0], R[..., 1, 0]))
    locked = np.abs(np.cos(pitch)) < 1e-9
    roll = np.where(locked, 0.0, np.arctan2(R[..., 2, 1], R[..., 2, 2]))
    yaw = np.where(locked, np.arctan2(-R[..., 0, 1], R[..., 1, 1]), np.arctan2(R[..., 1, 0], R[..., 0, 0]))
    return np.stack([roll, pitch, yaw], axis=-1) + 0.0  # + 0.0: no -0.0


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Quaternions ``(..., 4)`` ``(x, y, z, w)`` (normalised here) -> rotation matrices ``(..., 3, 3)``."""
    flat, lead = _flat(q, (4,))
    return Rotation.from_quat(flat).as_matrix().reshape(lead + (3, 3))


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` -> unit quaternions ``(..., 4)`` ``(x, y, z, w)`` with ``w >= 0``."""
    flat, lead = _flat(R, (3, 3))
    q = Rotation.from_matrix(flat).as_quat()
    q = np.where(q[:, 3:] < 0, -q, q)  # one of the two equal quaternions, always the same
    return q.reshape(lead + (4,))


def slerp(q0: np.ndarray, q1: np.ndarray, a: np.ndarray | float) -> np.ndarray:
    """Spherical linear interpolation of quaternions ``(..., 4)``, element by element, at fractions ``a`` ``(...,)``.

    Along the shorter arc: ``q0`` at ``a = 0``, ``q1`` at ``a = 1``; ``(x, y, z, w)``, ``w >= 0``.
    """
    q0, q1 = np.broadcast_arrays(np.asarray(q0, dtype=np.float64), np.asarray(q1, dtype=np.float64))
    f0, lead = _flat(q0, (4,))
    f1, _ = _flat(q1, (4,))
    a = np.broadcast_to(np.asarray(a, dtype=np.float64), lead).reshape(-1)
    r0 = Rotation.from_quat(f0)
    step = (r0.inv() * Rotation.from_quat(f1)).as_rotvec()  # the relative rotation, at most pi (shorter arc)
    q = (r0 * Rotation.from_rotvec(step * a[:, None])).as_quat()
    return np.where(q[:, 3:] < 0, -q, q).reshape(lead + (4,))


def hand_frame(wrist: np.ndarray, middle_base: np.ndarray, index_base: np.ndarray, pinky_base: np.ndarray) -> np.ndarray:
    """The hand's frame from four hand points: the wrist convention of the whole package.

    Columns: x = wrist -> middle-finger base, y = pinky base -> index base made
    orthogonal to x, z = x cross y (a proper rotation for either hand).

    Args:
        wrist, middle_base, index_base, pinky_base: ``(..., 3)`` points [m] in any frame.

    Returns:
        ``(..., 3, 3)`` rotation matrices in that frame; NaN where the points are
        degenerate (coincident or collinear).
    """
    x = _unit(np.asarray(middle_base, dtype=np.float64) - np.asarray(wrist, dtype=np.float64))
    across = np.asarray(index_base, dtype=np.float64) - np.asarray(pinky_base, dtype=np.float64)
    y = _unit(across - np.sum(across * x, axis=-1, keepdims=True) * x)
    z = np.stack([x[..., 1] * y[..., 2] - x[..., 2] * y[..., 1], x[..., 2] * y[..., 0] - x[..., 0] * y[..., 2], x[..., 0] * y[..., 1] - x[..., 1] * y[..., 0]], -1)
    return np.stack([x, y, z], axis=-1)  # (..., 3, 3)


def _unit(v: np.ndarray) -> np.ndarray:
    """Unit vectors along the last axis; NaN where the length is below :data:`_EPS`."""
    n = np.sqrt(np.sum(v * v, axis=-1, keepdims=True))  # not np.linalg.norm: cheaper on small arrays
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > _EPS, v / np.where(n > _EPS, n, 1.0), np.nan)

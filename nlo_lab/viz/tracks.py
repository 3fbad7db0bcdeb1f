"""Small meshcat building blocks shared by the scenes: poses, materials and animation tracks."""

from __future__ import annotations

from typing import Sequence

import numpy as np

import meshcat.geometry as g
from meshcat.animation import Animation, AnimationClip, AnimationTrack

__all__ = ["matrix_to_quaternion", "add_track", "add_pose_tracks", "add_visible_track", "material", "translation", "Y_TO_Z"]

Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])  # R_x(+90°): meshcat Y -> URDF Z


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` to unit quaternions ``(..., 4)`` in (x, y, z, w) order (three.js)."""
    R = np.asarray(R, dtype=np.float64)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = m00 + m11 + m22
    # Four candidate formulas; pick per entry the one with the largest (stable) pivot.
    cands = np.stack([
        np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1], 1 + tr], -1),
        np.stack([1 + m00 - m11 - m22, R[..., 0, 1] + R[..., 1, 0], R[..., 0, 2] + R[..., 2, 0], R[..., 2, 1] - R[..., 1, 2]], -1),
        np.stack([R[..., 0, 1] + R[..., 1, 0], 1 - m00 + m11 - m22, R[..., 1, 2] + R[..., 2, 1], R[..., 0, 2] - R[..., 2, 0]], -1),
        np.stack([R[..., 0, 2] + R[..., 2, 0], R[..., 1, 2] + R[..., 2, 1], 1 - m00 - m11 + m22, R[..., 1, 0] - R[..., 0, 1]], -1),
    ], -2)  # (..., 4, 4)
    pivots = np.stack([1 + tr, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
    best = np.argmax(pivots, axis=-1)
    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., 3:4] < 0, -q, q)


def add_track(anim: Animation, path, name: str, jstype: str, values) -> None:
    """One keyframe track (one key per frame) for ``path`` in ``anim``."""
    clip = anim.clips.get(path)
    if clip is None:
        clip = anim.clips[path] = AnimationClip(fps=anim.default_framerate)
    vals = np.asarray(values)
    vals = vals.astype(bool) if jstype == "boolean" else vals.astype(np.float64)
    clip.tracks[name] = AnimationTrack(name, jstype, frames=list(range(len(vals))), values=vals.tolist())


def add_pose_tracks(anim: Animation, path, T: np.ndarray, scale: np.ndarray | None = None) -> None:
    """Position and quaternion tracks from ``(F, 4, 4)`` poses; optional ``(F, 3)`` scale."""
    add_track(anim, path, "position", "vector3", T[:, :3, 3])
    add_track(anim, path, "quaternion", "quaternion", matrix_to_quaternion(T[:, :3, :3]))
    if scale is not None:
        add_track(anim, path, "scale", "vector3", scale)


def add_visible_track(anim: Animation, path, visible: np.ndarray) -> None:
    """A ``visible`` track ``(F,)`` (three.js BooleanKeyframeTrack, step-wise): hide a node in some frames."""
    add_track(anim, path, "visible", "boolean", np.asarray(visible, dtype=bool))


def material(colour: int, opacity: float = 1.0) -> g.MeshLambertMaterial:
    """A shaded material of ``colour`` (0xRRGGBB); transparent below opacity 1."""
    return g.MeshLambertMaterial(color=colour, opacity=opacity, transparent=opacity < 1.0)


def translation(offset: Sequence[float]) -> np.ndarray:
    """``(4, 4)`` homogeneous translation by ``offset`` ``(3,)`` [m]."""
    T = np.eye(4)
    T[:3, 3] = offset
    return T

"""Small meshcat building blocks shared by the scenes: poses, materials and animation tracks."""

from __future__ import annotations

from typing import Sequence

import numpy as np

import meshcat.geometry as g
from meshcat.animation import Animation, AnimationClip, AnimationTrack

from nlo_lab.rotations import matrix_to_quat as matrix_to_quaternion  # (x, y, z, w), three.js's order

__all__ = ["matrix_to_quaternion", "add_track", "add_pose_tracks", "add_visible_track", "material", "translation", "Y_TO_Z"]

Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])  # R_x(+90°): meshcat Y -> URDF Z


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

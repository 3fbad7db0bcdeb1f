"""Small meshcat building blocks shared by the scenes: poses, materials and animation tracks."""

from __future__ import annotations

from typing import Sequence

import numpy as np

import meshcat.geometry as g
from meshcat.animation import Animation, AnimationClip, AnimationTrack

from nlo_lab.rotations import matrix_to_quat as matrix_to_quaternion  # (x, y, z, w), three.js's order

__all__ = ["matrix_to_quaternion", "add_track", "add_pose_tracks", "add_visible_track", "set_key_times", "material",
           "translation", "Y_TO_Z"]

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


def set_key_times(anim: Animation, times) -> None:
    """Put key ``i`` of every track at ``times[i]`` seconds instead of frame ``i``.

    The tracks hold one key per frame, at frame numbers; the page plays a key at
    ``frame / clip.fps`` seconds. A retimed trajectory (``RobotTrajectory.time``) plays
    its frames at their own times, so each key becomes ``times[i] * clip.fps``: the
    animation then shows the motion as the robot would play it, slowed where it is.
    """
    t = np.asarray(times, dtype=np.float64)
    if t.ndim != 1 or not np.isfinite(t).all() or (np.diff(t) <= 0).any():
        raise ValueError("times must be finite and strictly increasing")
    for clip in anim.clips.values():
        for track in clip.tracks.values():
            if len(track.frames) != len(t):
                raise ValueError(f"times has {len(t)} entries for a track of {len(track.frames)} keys")
            track.frames = (t * clip.fps).tolist()


def material(colour: int, opacity: float = 1.0) -> g.MeshLambertMaterial:
    """A shaded material of ``colour`` (0xRRGGBB); transparent below opacity 1."""
    return g.MeshLambertMaterial(color=colour, opacity=opacity, transparent=opacity < 1.0)


def translation(offset: Sequence[float]) -> np.ndarray:
    """``(4, 4)`` homogeneous translation by ``offset`` ``(3,)`` [m]."""
    T = np.eye(4)
    T[:3, 3] = offset
    return T

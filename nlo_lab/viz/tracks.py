"""Small meshcat building blocks shared by the scenes: poses, materials and animation tracks."""

from __future__ import annotations

from collections.abc import Sequence

import meshcat.geometry as g
import numpy as np
from meshcat.animation import Animation, AnimationClip, AnimationTrack

from nlo_lab.rotations import matrix_to_quat as matrix_to_quaternion  # (x, y, z, w), three.js's order

__all__ = ["LOOP", "matrix_to_quaternion", "add_track", "add_pose_tracks", "add_visible_track", "set_key_times", "material",
           "translation", "Y_TO_Z", "tick_ms", "DETAILS", "SEGMENTS", "detail_of", "sphere", "cylinder"]

# ``repetitions`` of an animation that plays until paused: three.js's LoopRepeat stops after ``repetitions``
# passes, so 0 (or 1) plays once; msgpack carries infinity as a float, which the page reads as Infinity.
LOOP = float("inf")

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


def tick_ms(times) -> int:
    """The mean frame period [ms] of ``(T,)`` key times [s]: a Play widget ticking at it ends with the animation."""
    t = np.asarray(times, dtype=np.float64)
    return max(1, round(1000 * float(t[-1] - t[0]) / max(len(t) - 1, 1)))


# How finely spheres and cylinders are tessellated in the page: (sphere width, sphere height, cylinder radial)
# segments. "full" is meshcat's own (20, 20, 50): about 760 triangles per sphere, 200 per cylinder.
# "light" draws the same primitives with about 5x fewer triangles, for the live view: a browser drawing
# WebGL in software (no GPU) spends its frame on them. Only the picture changes: sizes, poses,
# collision capsules and FK are the same.
DETAILS = ("full", "light")
SEGMENTS = {"full": (20, 20, 50), "light": (12, 8, 12)}


class _Sphere(g.Sphere):
    """meshcat's Sphere with a chosen tessellation (meshcat's own is fixed at 20 x 20 segments)."""

    def __init__(self, radius: float, width_segments: int, height_segments: int):
        super().__init__(radius)
        self.segments = (int(width_segments), int(height_segments))

    def lower(self, object_data):
        data = super().lower(object_data)
        data["widthSegments"], data["heightSegments"] = self.segments
        return data


def detail_of(vis) -> str:
    """The tessellation a Visualizer's window asks for (``window.detail``); ``"full"`` if it says nothing."""
    detail = getattr(getattr(vis, "window", None), "detail", "full")
    return detail if detail in DETAILS else "full"


def sphere(radius: float, detail: str = "full") -> g.Sphere:
    """A sphere of ``radius`` [m] at ``detail`` (see :data:`SEGMENTS`)."""
    width, height, _ = SEGMENTS[detail]
    return g.Sphere(radius) if detail == "full" else _Sphere(radius, width, height)


def cylinder(length: float, radius: float, detail: str = "full") -> g.Cylinder:
    """A cylinder along Y of ``length`` and ``radius`` [m] at ``detail`` (see :data:`SEGMENTS`)."""
    shape = g.Cylinder(length, radius)
    shape.radialSegments = SEGMENTS[detail][2]
    return shape


def material(colour: int, opacity: float = 1.0) -> g.MeshLambertMaterial:
    """A shaded material of ``colour`` (0xRRGGBB); transparent below opacity 1."""
    return g.MeshLambertMaterial(color=colour, opacity=opacity, transparent=opacity < 1.0)


def translation(offset: Sequence[float]) -> np.ndarray:
    """``(4, 4)`` homogeneous translation by ``offset`` ``(3,)`` [m]."""
    T = np.eye(4)
    T[:3, 3] = offset
    return T

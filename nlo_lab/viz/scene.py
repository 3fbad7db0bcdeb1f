"""meshcat scenes of a robot (from its URDF's primitive visuals) and of the human skeleton.

A scene draws its geometry once (``draw``), then moves it: one frame at a time
(``set_frame``) or as a meshcat animation with one key per frame (``add_to``)
that the viewer plays and scrubs. Scenes write to any meshcat ``Visualizer``:
the live one of :mod:`nlo_lab.viz.server` or the in-process recorder of
:mod:`nlo_lab.viz.export`.

meshcat is Z-up like the body frame (X forward, Y left, Z up) [m].
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

import meshcat.geometry as g
from meshcat.animation import Animation, AnimationClip, AnimationTrack

from nlo_lab.errors import NloLabError, RobotDescriptionError

__all__ = [
    "GROUP_COLOURS",
    "HUMAN_COLOURS",
    "Visual",
    "robot_visuals",
    "link_groups",
    "urdf_path_of",
    "RobotScene",
    "HumanScene",
    "RetargetScene",
    "matrix_to_quaternion",
    "style_viewer",
]

# One colour per link group (0xRRGGBB); saturated hues so that a screenshot test can find them.
GROUP_COLOURS = {
    "arm": 0xE8731A,  # orange
    "hand": 0x2CA02C,  # green
    "torso": 0x4C72B0,  # blue
    "head": 0x9467BD,  # purple
}
HUMAN_COLOURS = {
    "joint": 0xD62728,  # red
    "bone": 0x555555,  # dark grey
    "finger": 0xE377C2,  # pink
}

_Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])  # R_x(+90°): meshcat Y -> URDF Z


@dataclass(frozen=True)
class Visual:
    """One primitive visual of a URDF link.

    Attributes:
        link: the link's name.
        kind: ``"box"``, ``"cylinder"`` or ``"sphere"``.
        size: box (x, y, z) lengths; cylinder (radius, length); sphere (radius,) [m].
        T_link_visual: ``(4, 4)`` pose of the primitive in the link frame (URDF convention: cylinder along Z).
    """

    link: str
    kind: str
    size: tuple[float, ...]
    T_link_visual: np.ndarray


# ------------------------------------------------------------------ URDF side
def urdf_path_of(robot: Any) -> Path:
    """The URDF file of a robot object (``nlo_lab.robots.Robot``) or a path given directly."""
    if isinstance(robot, (str, os.PathLike)):
        return Path(robot)
    for owner in (robot, getattr(robot, "spec", None)):
        if owner is None:
            continue
        for attr in ("urdf_path", "urdf_file", "urdf"):
            value = getattr(owner, attr, None)
            if isinstance(value, (str, os.PathLike)) and str(value).endswith(".urdf"):
                path = Path(value)
                if not path.is_absolute():
                    spec_path = getattr(getattr(robot, "spec", None), "path", None)
                    if spec_path is not None:
                        path = Path(spec_path).parent / path
                    else:
                        from nlo_lab.paths import ROBOTS_DIR

                        path = ROBOTS_DIR / path
                return path
    name = getattr(robot, "name", None)
    if name:
        from nlo_lab.paths import ROBOTS_DIR

        candidate = ROBOTS_DIR / f"{name}.urdf"
        if candidate.is_file():
            return candidate
    raise RobotDescriptionError(f"cannot find the URDF of robot {getattr(robot, 'name', robot)!r}")


def _load_urdf(path: Path):
    import yourdfpy

    if not path.is_file():
        raise RobotDescriptionError(f"URDF not found: {path}")
    try:
        return yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False)
    except Exception as exc:  # yourdfpy raises assorted errors on a malformed file
        raise RobotDescriptionError(f"cannot parse URDF {path}: {exc}") from None


def robot_visuals(urdf: Any) -> list[Visual]:
    """The primitive visuals (box, cylinder, sphere) of every link; meshes are skipped.

    Args:
        urdf: a URDF path, a robot object, or a loaded ``yourdfpy.URDF``.
    """
    model = urdf if hasattr(urdf, "robot") and hasattr(urdf.robot, "links") else _load_urdf(urdf_path_of(urdf))
    out: list[Visual] = []
    for link in model.robot.links:
        for vis in link.visuals or []:
            geom = vis.geometry
            T = np.eye(4) if vis.origin is None else np.asarray(vis.origin, dtype=np.float64)
            if geom.box is not None:
                out.append(Visual(link.name, "box", tuple(float(v) for v in geom.box.size), T))
            elif geom.cylinder is not None:
                out.append(Visual(link.name, "cylinder", (float(geom.cylinder.radius), float(geom.cylinder.length)), T))
            elif geom.sphere is not None:
                out.append(Visual(link.name, "sphere", (float(geom.sphere.radius),), T))
    return out


def _name_group(name: str) -> str:
    n = name.lower()
    if any(k in n for k in ("head", "neck", "camera", "eye")):
        return "head"
    if any(k in n for k in ("hand", "finger", "thumb", "index", "middle", "ring", "pinky", "little", "palm", "gripper", "tip")):
        return "hand"
    if any(k in n for k in ("shoulder", "bicep", "elbow", "forearm", "arm", "wrist", "link_")):
        return "arm"
    return "torso"


def link_groups(urdf: Any, arms: dict[str, tuple[str, str]] | None = None) -> dict[str, str]:
    """Group every link: ``arm``, ``hand``, ``torso`` or ``head``.

    With ``arms`` (side -> (shoulder link, wrist link)) the chain shoulder..wrist
    is ``arm`` and everything below the wrist is ``hand``; other links (and all
    links without ``arms``) are grouped by name.
    """
    model = urdf if hasattr(urdf, "robot") and hasattr(urdf.robot, "links") else _load_urdf(urdf_path_of(urdf))
    groups = {link.name: _name_group(link.name) for link in model.robot.links}
    parent = {j.child: j.parent for j in model.robot.joints}
    children: dict[str, list[str]] = {}
    for j in model.robot.joints:
        children.setdefault(j.parent, []).append(j.child)
    for shoulder, wrist in (arms or {}).values():
        chain, link = [], wrist
        while link is not None:
            chain.append(link)
            if link == shoulder:
                break
            link = parent.get(link)
        else:
            chain = [wrist]  # shoulder is not an ancestor: colour just the wrist
        for link in chain:
            groups[link] = "arm"
        stack = list(children.get(wrist, []))
        while stack:
            link = stack.pop()
            groups[link] = "hand"
            stack.extend(children.get(link, []))
    return groups


def _robot_arms(robot: Any) -> dict[str, tuple[str, str]] | None:
    try:
        return {side: (robot.arm(side).shoulder, robot.arm(side).wrist) for side in ("left", "right")}
    except Exception:
        return None


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


def _add_track(anim: Animation, path, name: str, jstype: str, values: np.ndarray) -> None:
    """One keyframe track (one key per frame) for ``path`` in ``anim``."""
    clip = anim.clips.get(path)
    if clip is None:
        clip = anim.clips[path] = AnimationClip(fps=anim.default_framerate)
    vals = np.asarray(values, dtype=np.float64)
    clip.tracks[name] = AnimationTrack(name, jstype, frames=list(range(len(vals))), values=vals.tolist())


def _add_pose_tracks(anim: Animation, path, T: np.ndarray, scale: np.ndarray | None = None) -> None:
    """Position and quaternion tracks from ``(F, 4, 4)`` poses; optional ``(F, 3)`` scale."""
    _add_track(anim, path, "position", "vector3", T[:, :3, 3])
    _add_track(anim, path, "quaternion", "quaternion", matrix_to_quaternion(T[:, :3, :3]))
    if scale is not None:
        _add_track(anim, path, "scale", "vector3", scale)


def _material(colour: int, opacity: float = 1.0) -> g.MeshLambertMaterial:
    return g.MeshLambertMaterial(color=colour, opacity=opacity, transparent=opacity < 1.0)


def _translation(offset: Sequence[float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = offset
    return T


def style_viewer(vis, camera: Sequence[float] = (2.0, -0.6, 0.6), background: Sequence[float] = (1.0, 1.0, 1.0)) -> None:
    """A light background (the group colours stand out) and a camera in front of the robot.

    Args:
        vis: a meshcat ``Visualizer``.
        camera: ``(3,)`` camera position in the body frame (X forward, Y left, Z up) [m]; it looks at the origin.
        background: ``(3,)`` RGB in [0, 1] of the top of the background gradient (the bottom is slightly darker).
    """
    top = [float(c) for c in background]
    vis["/Background"].set_property("top_color", top)
    vis["/Background"].set_property("bottom_color", [0.85 * c for c in top])
    x, y, z = (float(c) for c in camera)
    # The camera lives under a node that turns three.js' Y-up into meshcat's Z-up: (x, y, z) -> (x, z, -y).
    vis["/Cameras/default/rotated/<object>"].set_property("position", [x, z, -y])


# ---------------------------------------------------------------- robot scene
class RobotScene:
    """A robot drawn from its URDF's primitives and posed by its forward kinematics.

    Args:
        vis: a meshcat ``Visualizer``.
        robot: a ``nlo_lab.robots.Robot`` (needs ``forward_kinematics``, ``n_joints``,
            and a URDF reachable by :func:`urdf_path_of`).
        path: the scene-tree folder.
        origin: ``(3,)`` position of the robot's base in the viewer [m].
        opacity: 1 for solid; below 1 to see an overlaid human through it.
    """

    def __init__(self, vis, robot: Any, path: str = "robot", origin: Sequence[float] = (0.0, 0.0, 0.0), opacity: float = 1.0):
        self.vis = vis
        self.robot = robot
        self.path = path
        self.origin = _translation(origin)
        self.opacity = float(opacity)
        model = _load_urdf(urdf_path_of(robot))
        self.visuals = robot_visuals(model)
        if not self.visuals:
            raise RobotDescriptionError(f"robot {getattr(robot, 'name', '?')!r}: its URDF has no box, cylinder or sphere visuals to draw")
        self.groups = link_groups(model, _robot_arms(robot))
        self.links = sorted({v.link for v in self.visuals})

    def draw(self) -> "RobotScene":
        """Create every primitive under ``path/link/i`` (coloured by link group)."""
        root = self.vis[self.path]
        for i, v in enumerate(self.visuals):
            node = root[v.link][f"v{i}"]
            colour = GROUP_COLOURS[self.groups.get(v.link, "torso")]
            if v.kind == "box":
                node.set_object(g.Box(list(v.size)), _material(colour, self.opacity))
                node.set_transform(v.T_link_visual)
            elif v.kind == "cylinder":
                radius, length = v.size
                node.set_object(g.Cylinder(length, radius), _material(colour, self.opacity))
                node.set_transform(v.T_link_visual @ _Y_TO_Z)
            else:
                node.set_object(g.Sphere(v.size[0]), _material(colour, self.opacity))
                node.set_transform(v.T_link_visual)
        return self

    def link_poses(self, angles: Any) -> dict[str, np.ndarray]:
        """``{link: (F, 4, 4)}`` viewer poses of the drawn links for ``(F, n)`` (or ``(n,)``) angles [rad]."""
        import torch

        q = np.asarray(angles, dtype=np.float64)
        if q.ndim == 1:
            q = q[None]
        n = self.robot.n_joints
        if q.ndim != 2 or q.shape[1] != n:
            raise NloLabError(f"angles must be (T, {n}) for robot {self.robot.name!r}, got shape {np.shape(angles)}")
        ref = getattr(self.robot, "lower_limits", None)
        dtype = ref.dtype if isinstance(ref, torch.Tensor) else torch.float64
        device = ref.device if isinstance(ref, torch.Tensor) else None
        with torch.no_grad():
            fk = self.robot.forward_kinematics(torch.as_tensor(q, dtype=dtype, device=device))
        eye = np.broadcast_to(np.eye(4), (q.shape[0], 4, 4))
        out = {}
        for link in self.links:
            T = fk.get(link)
            T = eye if T is None else T.detach().cpu().double().numpy()  # base links may be absent from FK
            out[link] = self.origin @ T
        return out

    def set_pose(self, q: Any) -> None:
        """Show joint angles ``(n,)`` [rad]."""
        root = self.vis[self.path]
        for link, T in self.link_poses(q).items():
            root[link].set_transform(T[0])

    def add_to(self, anim: Animation, angles: Any) -> None:
        """Add one key per frame of ``(T, n)`` angles to ``anim``."""
        root = self.vis[self.path]
        for link, T in self.link_poses(angles).items():
            _add_pose_tracks(anim, root[link].path, T)


# ---------------------------------------------------------------- human scene
def _hold_valid(x: np.ndarray) -> np.ndarray:
    """Fill NaN points along time with the last (or, before any, the first) valid value."""
    x = np.array(x, dtype=np.float64)  # (T, ..., 3)
    flat = x.reshape(x.shape[0], -1, 3)
    for k in range(flat.shape[1]):
        ok = np.isfinite(flat[:, k]).all(-1)
        if not ok.any():
            continue
        idx = np.where(ok, np.arange(len(ok)), -1)
        idx = np.maximum.accumulate(idx)
        idx[idx < 0] = int(np.argmax(ok))
        flat[:, k] = flat[idx, k]
    return flat.reshape(x.shape)


def _bone_poses(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Poses ``(F, 4, 4)`` and scales ``(F, 3)`` that stretch a unit Y-cylinder from ``a`` to ``b`` (F, 3)."""
    d = b - a
    length = np.linalg.norm(d, axis=-1)  # (F,)
    y = d / np.maximum(length, 1e-9)[:, None]
    y[length < 1e-9] = [0.0, 1.0, 0.0]
    helper = np.where(np.abs(y[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    x = np.cross(y, helper)
    x /= np.linalg.norm(x, axis=-1, keepdims=True)
    z = np.cross(x, y)
    T = np.tile(np.eye(4), (len(d), 1, 1))
    T[:, :3, 0], T[:, :3, 1], T[:, :3, 2] = x, y, z
    T[:, :3, 3] = 0.5 * (a + b)
    scale = np.ones((len(d), 3))
    scale[:, 1] = np.maximum(length, 1e-6)
    return T, scale


class HumanScene:
    """The human skeleton: arm joints and finger points as spheres, bones as thin cylinders.

    Args:
        vis: a meshcat ``Visualizer``.
        demo: the ``Demonstration`` shown.
        path: the scene-tree folder.
        offset: ``(3,)`` translation of the body frame in the viewer [m] (side by side layout).
        mapped: optional ``(T, 2, 3, 3)`` arm positions to show instead of the raw ones
            (e.g. ``nlo_lab.human.map_to_robot(demo, robot)``); fingers then follow their wrist.
    """

    def __init__(self, vis, demo: Any, path: str = "human", offset: Sequence[float] = (0.0, 0.0, 0.0), mapped: np.ndarray | None = None):
        self.vis = vis
        self.demo = demo
        self.path = path
        arms = demo.arm_positions if mapped is None else np.asarray(mapped, dtype=np.float64)
        fingers = demo.finger_positions.copy()  # (T, 2, 5, 2, 3)
        if mapped is not None:  # move the hand with its mapped wrist
            fingers += (arms[:, :, 2] - demo.arm_positions[:, :, 2])[:, :, None, None, :]
        arms = arms.copy()
        arms[~demo.arm_mask] = np.nan
        fingers[~demo.finger_mask] = np.nan
        off = np.asarray(offset, dtype=np.float64)
        self.arms = _hold_valid(arms) + off  # (T, 2, 3, 3)
        self.fingers = _hold_valid(fingers) + off  # (T, 2, 5, 2, 3)
        self.has_fingers = bool(demo.finger_mask.any())

    def _points(self) -> dict[str, np.ndarray]:
        pts = {}
        for s, side in enumerate(("left", "right")):
            for j, joint in enumerate(("shoulder", "elbow", "wrist")):
                pts[f"{side}_{joint}"] = self.arms[:, s, j]
            if self.has_fingers:
                for f in range(5):
                    for k, kind in enumerate(("base", "tip")):
                        pts[f"{side}_f{f}_{kind}"] = self.fingers[:, s, f, k]
        return pts

    def _bones(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        A = self.arms
        bones = {"shoulders": (A[:, 0, 0], A[:, 1, 0])}
        for s, side in enumerate(("left", "right")):
            bones[f"{side}_upper"] = (A[:, s, 0], A[:, s, 1])
            bones[f"{side}_fore"] = (A[:, s, 1], A[:, s, 2])
            if self.has_fingers:
                for f in range(5):
                    bones[f"{side}_palm{f}"] = (A[:, s, 2], self.fingers[:, s, f, 0])
                    bones[f"{side}_finger{f}"] = (self.fingers[:, s, f, 0], self.fingers[:, s, f, 1])
        return bones

    def draw(self) -> "HumanScene":
        """Create spheres and bones (hidden if a point is never observed)."""
        root = self.vis[self.path]
        for name, p in self._points().items():
            finger = "_f" in name
            colour = HUMAN_COLOURS["finger" if finger else "joint"]
            root["points"][name].set_object(g.Sphere(0.008 if finger else 0.025), _material(colour))
        for name, (a, b) in self._bones().items():
            finger = "palm" in name or "finger" in name
            root["bones"][name].set_object(g.Cylinder(1.0, 0.004 if finger else 0.012), _material(HUMAN_COLOURS["bone"]))
        self.set_frame(0)
        return self

    def set_frame(self, t: int) -> None:
        """Show frame ``t``."""
        root = self.vis[self.path]
        for name, p in self._points().items():
            if np.isfinite(p[t]).all():
                root["points"][name].set_transform(_translation(p[t]))
        for name, (a, b) in self._bones().items():
            if np.isfinite(a[t]).all() and np.isfinite(b[t]).all():
                T, scale = _bone_poses(a[t:t + 1], b[t:t + 1])
                root["bones"][name].set_transform(T[0] @ np.diag([*scale[0], 1.0]))

    def add_to(self, anim: Animation) -> None:
        """Add one key per frame of the demonstration to ``anim``."""
        root = self.vis[self.path]
        T_frames = self.arms.shape[0]
        for name, p in self._points().items():
            if np.isfinite(p).all():
                T = np.tile(np.eye(4), (T_frames, 1, 1))
                T[:, :3, 3] = p
                _add_pose_tracks(anim, root["points"][name].path, T)
        for name, (a, b) in self._bones().items():
            if np.isfinite(a).all() and np.isfinite(b).all():
                T, scale = _bone_poses(a, b)
                _add_pose_tracks(anim, root["bones"][name].path, T, scale)


# ------------------------------------------------------------- the two together
class RetargetScene:
    """Robot and (optionally) human, side by side or overlaid, one frame or animated.

    Args:
        vis: a meshcat ``Visualizer``.
        robot: a ``nlo_lab.robots.Robot``.
        angles: ``(T, n)`` robot joint angles [rad].
        demo: optional ``Demonstration`` with the same number of frames.
        layout: ``"side"`` (human beside the robot) or ``"overlay"`` (human mapped into the robot's frame).
        offset: side-by-side shift of the human [m]: a float along ``-Y`` (to the robot's right) or an ``(x, y, z)``.
        fps: animation rate; defaults to the demonstration's, else 30.
    """

    def __init__(self, vis, robot: Any, angles: Any, demo: Any = None, layout: str = "side", offset: float | Sequence[float] = 0.9, fps: float | None = None):
        if layout not in ("side", "overlay"):
            raise NloLabError(f"layout must be 'side' or 'overlay', got {layout!r}")
        q = np.asarray(angles, dtype=np.float64)
        if q.ndim == 1:
            q = q[None]
        if demo is not None and len(demo) != q.shape[0]:
            raise NloLabError(f"angles have {q.shape[0]} frames but the demonstration {demo.name!r} has {len(demo)}")
        self.vis = vis
        self.angles = q
        self.fps = float(fps if fps is not None else (demo.fps if demo is not None else 30.0))
        if not np.isfinite(self.fps) or self.fps <= 0:
            raise NloLabError(f"fps must be > 0, got {fps!r}")
        self.robot_scene = RobotScene(vis, robot, opacity=0.6 if (layout == "overlay" and demo is not None) else 1.0)
        self.human_scene = None
        if demo is not None:
            if layout == "side":
                off = (0.0, -float(offset), 0.0) if np.isscalar(offset) else tuple(offset)
                self.human_scene = HumanScene(vis, demo, offset=off)
            else:
                from nlo_lab.metrics import _mapped_human

                self.human_scene = HumanScene(vis, demo, mapped=_mapped_human(demo, robot))
        style_viewer(vis, camera=self._camera(layout == "side" and demo is not None))
        self.robot_scene.draw()
        if self.human_scene is not None:
            self.human_scene.draw()
        self.set_frame(0)

    def __len__(self) -> int:
        return int(self.angles.shape[0])

    def _camera(self, side_by_side: bool) -> tuple[float, float, float]:
        """A camera in front, far enough to see every link (and the human) of frame 0 [m]."""
        pts = [T[0, :3, 3] for T in self.robot_scene.link_poses(self.angles[:1]).values()]
        if self.human_scene is not None:
            pts.extend(self.human_scene.arms[0].reshape(-1, 3))
        radius = float(np.max(np.linalg.norm(np.asarray(pts), axis=-1)))
        return (max(1.0, 2.8 * radius), -0.45 if side_by_side else 0.0, 0.2 + 0.3 * radius)

    def set_frame(self, t: int) -> None:
        """Show frame ``t`` (robot pose and human skeleton)."""
        if not 0 <= t < len(self):
            raise NloLabError(f"frame {t} is outside 0..{len(self) - 1}")
        self.robot_scene.set_pose(self.angles[t])
        if self.human_scene is not None:
            self.human_scene.set_frame(t)

    def set_angles(self, q: Any, t: int | None = None) -> None:
        """Replace the angles of frame ``t`` (or show ``q`` without storing it if ``t`` is None)."""
        q = np.asarray(q, dtype=np.float64)
        if t is not None:
            self.angles[t] = q
        self.robot_scene.set_pose(q)

    def animation(self) -> Animation:
        """A meshcat ``Animation`` with one key per frame at ``fps``."""
        anim = Animation(default_framerate=self.fps)
        self.robot_scene.add_to(anim, self.angles)
        if self.human_scene is not None:
            self.human_scene.add_to(anim)
        return anim

    def animate(self, play: bool = False, repetitions: int = 1) -> Animation:
        """Send the animation to the viewer (its controls play and scrub it)."""
        anim = self.animation()
        self.vis.set_animation(anim, play=play, repetitions=repetitions)
        return anim

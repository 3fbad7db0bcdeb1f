"""meshcat scenes of a robot (from its URDF's visuals: primitives, meshes decimated) and of the robot with its human.

A scene draws its geometry once (``draw``), then moves it: one frame at a time
(``set_frame``) or as a meshcat animation with one key per frame (``add_to``)
that the viewer plays and scrubs. Scenes write to any meshcat ``Visualizer``:
the notebook widget's (:mod:`nlo_lab.viz.widget`) or the in-process recorder of
:mod:`nlo_lab.viz.export`. The human is drawn by :mod:`nlo_lab.viz.human_scene`
and the camera framed by :mod:`nlo_lab.viz.camera`.

meshcat is Z-up like the body frame (X forward, Y left, Z up) [m].
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import meshcat.geometry as g
import numpy as np
from meshcat.animation import Animation

from nlo_lab.errors import RobotDescriptionError, SettingsError
from nlo_lab.human import map_to_robot
from nlo_lab.paths import ROBOTS_DIR
from nlo_lab.robot.urdf import load_urdf
from nlo_lab.viz.camera import CameraView, frame_points, style_viewer
from nlo_lab.viz.human_scene import HUMAN_COLOURS, HumanScene
from nlo_lab.viz.robot_visuals import Visual, robot_visuals_of
from nlo_lab.viz.tracks import Y_TO_Z, add_pose_tracks, cylinder, detail_of, material, matrix_to_quaternion, sphere, translation

__all__ = [
    "GROUP_COLOURS",
    "HUMAN_COLOURS",
    "HUMAN_SCALES",
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
HUMAN_SCALES = ("robot", "human")  # the human mapped to the robot's size and shoulders, or as recorded


# ------------------------------------------------------------------ URDF side
def urdf_path_of(robot: Any) -> Path:
    """The URDF file of a robot object (``nlo_lab.robot.Robot``) or a path given directly."""
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
                        path = ROBOTS_DIR / path
                return path
    name = getattr(robot, "name", None)
    if name:
        candidate = ROBOTS_DIR / f"{name}.urdf"
        if candidate.is_file():
            return candidate
    raise RobotDescriptionError(f"cannot find the URDF of robot {getattr(robot, 'name', robot)!r}")


def _load_urdf(path: Path):
    return load_urdf(path)


def robot_visuals(urdf: Any) -> list[Visual]:
    """The visuals of every link: primitives, and meshes decimated to a face budget
    (:func:`nlo_lab.viz.robot_visuals.robot_visuals_of`).

    Args:
        urdf: a robot object (its parsed model is reused), a URDF path, or a loaded
            ``yourdfpy.URDF`` (primitives only: without its file, meshes cannot be found).
    """
    model = getattr(urdf, "model", None)  # a Robot keeps its parsed URDFModel
    if model is not None and hasattr(model, "urdf"):
        return robot_visuals_of(model)
    if hasattr(urdf, "robot") and hasattr(urdf.robot, "links"):
        return _primitive_visuals(urdf)
    from nlo_lab.robot.urdf import parse_urdf

    return robot_visuals_of(parse_urdf(urdf_path_of(urdf)))


def _primitive_visuals(urdf) -> list[Visual]:
    """The box, cylinder and sphere visuals of a loaded ``yourdfpy.URDF``."""
    out: list[Visual] = []
    for link in urdf.robot.links:
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
    model = getattr(getattr(urdf, "model", None), "urdf", None)  # a Robot keeps the yourdfpy.URDF it was parsed into
    if model is None:
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


# ---------------------------------------------------------------- robot scene
class RobotScene:
    """A robot drawn from its URDF's visuals (primitives; meshes decimated to a face budget,
    :mod:`nlo_lab.viz.robot_visuals`) and posed by its forward kinematics.

    Args:
        vis: a meshcat ``Visualizer``.
        robot: a ``nlo_lab.robot.Robot`` (needs ``forward_kinematics``, ``n_joints``,
            and a URDF reachable by :func:`urdf_path_of`).
        path: the scene-tree folder.
        origin: ``(3,)`` position of the robot's base in the viewer [m].
        opacity: 1 for solid; below 1 to see an overlaid human through it.
    """

    def __init__(self, vis, robot: Any, path: str = "robot", origin: Sequence[float] = (0.0, 0.0, 0.0), opacity: float = 1.0):
        self.vis = vis
        self.robot = robot
        self.path = path
        self.origin = translation(origin)
        self.opacity = float(opacity)
        parsed = getattr(getattr(robot, "model", None), "urdf", None)  # a Robot keeps the yourdfpy.URDF it was parsed into
        model = parsed if parsed is not None else _load_urdf(urdf_path_of(robot))
        self.visuals = robot_visuals(robot if parsed is not None else model)
        if not self.visuals:
            raise RobotDescriptionError(f"robot {getattr(robot, 'name', '?')!r}: its URDF has no visuals to draw")
        self.groups = link_groups(model, _robot_arms(robot))
        self.links = sorted({v.link for v in self.visuals})

    def draw(self) -> RobotScene:
        """Create every primitive under ``path/link/i`` (coloured by link group)."""
        root = self.vis[self.path]
        detail = detail_of(self.vis)  # the live view draws lighter spheres and cylinders
        for i, v in enumerate(self.visuals):
            node = root[v.link][f"v{i}"]
            colour = GROUP_COLOURS[self.groups.get(v.link, "torso")]
            if v.kind == "box":
                node.set_object(g.Box(list(v.size)), material(colour, self.opacity))
                node.set_transform(v.T_link_visual)
            elif v.kind == "cylinder":
                radius, length = v.size
                node.set_object(cylinder(length, radius, detail), material(colour, self.opacity))
                node.set_transform(v.T_link_visual @ Y_TO_Z)
            elif v.kind == "mesh":  # decimated already (nlo_lab.viz.robot_visuals)
                node.set_object(g.TriangularMeshGeometry(v.vertices, v.faces), material(colour, self.opacity))
                node.set_transform(v.T_link_visual)
            else:
                node.set_object(sphere(v.size[0], detail), material(colour, self.opacity))
                node.set_transform(v.T_link_visual)
        return self

    def link_poses(self, angles: Any) -> dict[str, np.ndarray]:
        """``{link: (F, 4, 4)}`` viewer poses of the drawn links for ``(F, n)`` (or ``(n,)``) angles [rad]."""
        # lazy: torch: the command line's --help and bad flags do not wait for it
        import torch

        q = np.array(angles, dtype=np.float64)  # a copy: torch.as_tensor warns on read-only arrays
        if q.ndim == 1:
            q = q[None]
        n = self.robot.n_joints
        if q.ndim != 2 or q.shape[1] != n:
            raise SettingsError(f"angles must be (T, {n}) for robot {self.robot.name!r}, got shape {np.shape(angles)}")
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
            add_pose_tracks(anim, root[link].path, T)


    def extent_points(self, angles: Any, max_frames: int = 120) -> np.ndarray:
        """``(N, 3)`` corners of every visual's bounding box over (up to ``max_frames`` evenly spread) frames [m]."""
        q = np.array(angles, dtype=np.float64)
        if q.ndim == 1:
            q = q[None]
        if len(q) > max_frames:
            q = q[np.unique(np.linspace(0, len(q) - 1, max_frames).round().astype(int))]
        poses = self.link_poses(q)
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)  # (8, 3)
        chunks = []
        for v in self.visuals:
            if v.kind == "mesh":
                lo, hi = v.vertices.min(0).astype(np.float64), v.vertices.max(0).astype(np.float64)
                local = (lo + hi) / 2 + signs * (hi - lo) / 2  # the corners of the mesh's box
                T = poses[v.link] @ v.T_link_visual
                chunks.append(np.einsum("fij,kj->fki", T[:, :3, :3], local) + T[:, None, :3, 3])
                continue
            if v.kind == "box":
                half = 0.5 * np.asarray(v.size)
            elif v.kind == "cylinder":
                half = np.array([v.size[0], v.size[0], 0.5 * v.size[1]])  # URDF cylinders run along Z
            else:
                half = np.full(3, v.size[0])
            local = signs * half  # (8, 3) in the visual's frame
            T = poses[v.link] @ v.T_link_visual  # (F, 4, 4)
            chunks.append(np.einsum("fij,kj->fki", T[:, :3, :3], local) + T[:, None, :3, 3])
        return np.concatenate([c.reshape(-1, 3) for c in chunks])


# ------------------------------------------------------------- the two together
class RetargetScene:
    """Robot and (optionally) human, side by side or overlaid, one frame or animated, framed by the camera.

    Args:
        vis: a meshcat ``Visualizer``.
        robot: a ``nlo_lab.robot.Robot``.
        angles: ``(T, n)`` robot joint angles [rad].
        demo: optional ``Demonstration`` with the same number of frames.
        layout: ``"side"`` (human beside the robot) or ``"overlay"`` (human mapped onto the robot).
        offset: side-by-side shift of the human [m]: a float along ``-Y`` (to the robot's right),
            an ``(x, y, z)``, or ``None`` to put the human just beside the robot (gap: a quarter of the scene's height).
        fps: animation rate; defaults to the demonstration's, else 30.
        human_scale: ``"robot"`` (the human mapped into the robot's frame and size as the metric does,
            :func:`nlo_lab.human.map_to_robot`) or ``"human"`` (as recorded; side layout only).
        camera: ``None`` to frame the whole trajectory (robot and human) from the front-side,
            or a :class:`~nlo_lab.viz.camera.CameraView`.
    """

    def __init__(
        self,
        vis,
        robot: Any,
        angles: Any,
        demo: Any = None,
        layout: str = "side",
        offset: float | Sequence[float] | None = None,
        fps: float | None = None,
        human_scale: str = "robot",
        camera: CameraView | None = None,
    ):
        if layout not in ("side", "overlay"):
            raise SettingsError(f"layout must be 'side' or 'overlay', got {layout!r}")
        if human_scale not in HUMAN_SCALES:
            raise SettingsError(f"human_scale must be one of {HUMAN_SCALES}, got {human_scale!r}")
        if layout == "overlay" and human_scale != "robot":
            raise SettingsError("layout='overlay' draws the human in the robot's frame: it needs human_scale='robot'")
        q = np.array(angles, dtype=np.float64)  # a private, writable copy (set_angles edits it)
        if q.ndim == 1:
            q = q[None]
        if demo is not None and len(demo) != q.shape[0]:
            raise SettingsError(f"angles have {q.shape[0]} frames but the demonstration {demo.name!r} has {len(demo)}")
        self.vis = vis
        self.angles = q
        self.layout = layout
        self.fps = float(fps if fps is not None else (demo.fps if demo is not None else 30.0))
        if not np.isfinite(self.fps) or self.fps <= 0:
            raise SettingsError(f"fps must be > 0, got {fps!r}")
        self.robot_scene = RobotScene(vis, robot, opacity=0.6 if (layout == "overlay" and demo is not None) else 1.0)
        self.robot_scene.link_poses(q[:1])  # check the angles' shape before the work below
        robot_pts = self.robot_scene.extent_points(q)
        self.human_scene = None
        if demo is not None:
            mapped = None
            if human_scale == "robot":
                mapped = map_to_robot(demo, robot)  # (T, 2, 3, 3), NaN where masked
            self.human_scene = HumanScene(vis, demo, mapped=mapped, body=layout == "side")
            if layout == "side":
                self.human_scene.offset = self._side_offset(offset, robot_pts, self.human_scene.extent_points())
        pts = robot_pts if self.human_scene is None else np.concatenate([robot_pts, self.human_scene.extent_points()])
        self.camera = camera if camera is not None else frame_points(pts)
        style_viewer(vis, camera=self.camera)
        self.robot_scene.draw()
        if self.human_scene is not None:
            self.human_scene.draw()
        self.set_frame(0)

    @staticmethod
    def _side_offset(offset, robot_pts: np.ndarray, human_pts: np.ndarray) -> np.ndarray:
        """The human's shift [m]: given, or just to the robot's right (-Y) with a gap of a quarter of the height."""
        if offset is not None:
            return np.array([0.0, -float(offset), 0.0]) if np.isscalar(offset) else np.asarray(offset, dtype=np.float64).reshape(3)
        if len(human_pts) == 0:
            return np.zeros(3)
        height = max(float(np.ptp(robot_pts[:, 2])), float(np.ptp(human_pts[:, 2])))
        gap = 0.25 * height
        return np.array([0.0, robot_pts[:, 1].min() - human_pts[:, 1].max() - gap, 0.0])

    def __len__(self) -> int:
        return int(self.angles.shape[0])

    def set_frame(self, t: int) -> None:
        """Show frame ``t`` (robot pose and human skeleton)."""
        if not 0 <= t < len(self):
            raise SettingsError(f"frame {t} is outside 0..{len(self) - 1}")
        self.robot_scene.set_pose(self.angles[t])
        if self.human_scene is not None:
            self.human_scene.set_frame(t)

    def set_angles(self, q: Any, t: int | None = None) -> None:
        """Replace the angles of frame ``t`` (or show ``q`` without storing it if ``t`` is None)."""
        q = np.array(q, dtype=np.float64)
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

"""The human in the viewer: arm joints, bones, fingers, and a simple torso and head.

Positions come either as recorded (body frame, human size) or mapped into the
robot's frame (``nlo_lab.human.map_to_robot``: per arm, shoulder-relative, scaled
by robot/human arm length, at the robot's shoulder). The hands follow their mapped
wrist and are scaled by the same per-arm factor about the wrist, and the torso and
head by the mean of the two factors, so a mapped human has the robot's size.

A point that the demonstration masks (NaN) is hidden in that frame: the scene
animates each node's ``visible`` flag (a three.js boolean track) and holds its
last valid position meanwhile, so nothing is drawn at a stale place.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import meshcat.geometry as g
import numpy as np
from meshcat.animation import Animation

from nlo_lab.errors import NloLabError, SettingsError
from nlo_lab.viz.tracks import add_pose_tracks, add_visible_track, cylinder, detail_of, material, sphere, translation

__all__ = ["HUMAN_COLOURS", "HumanScene", "arm_factors"]

HUMAN_COLOURS = {
    "joint": 0xD62728,  # red
    "bone": 0x555555,  # dark grey
    "finger": 0xE377C2,  # pink
    "torso": 0xC8C8C8,  # light grey, translucent: low saturation, so never mistaken for a robot colour
    "head": 0xE6D3C3,  # pale skin tone (saturation 0.15)
}

# Body proportions relative to the arm length L = upper arm + forearm [m/m] (adult: L ~ 0.56 m).
_TORSO_LENGTH = 0.9  # shoulder line to hips ~ 0.5 m
_HEAD_RADIUS = 0.17  # ~ 0.095 m
_HEAD_HEIGHT = 0.45  # head centre above the shoulder midpoint ~ 0.25 m
_TORSO_WIDTH = 0.8  # of the shoulder distance: the shoulder joints stay visible outside the box
_TORSO_DEPTH = 0.5  # of the shoulder distance
_SIZES = {"joint": 0.025, "finger": 0.008, "bone": 0.012, "finger_bone": 0.004}  # radii at human size [m]


def _hold_valid(x: np.ndarray) -> np.ndarray:
    """Fill NaN points along time with the last (or, before any, the first) valid value; 0 where never valid."""
    x = np.array(x, dtype=np.float64)  # (T, ..., 3)
    flat = x.reshape(x.shape[0], -1, 3)
    for k in range(flat.shape[1]):
        ok = np.isfinite(flat[:, k]).all(-1)
        if not ok.any():
            flat[:, k] = 0.0  # never shown
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


def arm_factors(raw: np.ndarray, mapped: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Per-arm scale ``(2,)`` of a shoulder-relative mapping: median |mapped - shoulder| / |raw - shoulder|.

    Args:
        raw: ``(T, 2, 3, 3)`` recorded arm positions [m].
        mapped: ``(T, 2, 3, 3)`` the same points mapped into the robot's frame [m].
        valid: ``(T, 2, 3)`` where both are valid.
    """
    k = np.ones(2)
    for s in range(2):
        ok = valid[:, s, 0, None] & valid[:, s, 1:]  # (T, 2): elbow, wrist with their shoulder
        num = np.linalg.norm(mapped[:, s, 1:] - mapped[:, s, :1], axis=-1)[ok]
        den = np.linalg.norm(raw[:, s, 1:] - raw[:, s, :1], axis=-1)[ok]
        good = den > 1e-6
        if good.any():
            k[s] = float(np.median(num[good] / den[good]))
    return k


class HumanScene:
    """The human: arm joints and finger points as spheres, bones as thin cylinders, a torso box and a head.

    Args:
        vis: a meshcat ``Visualizer``.
        demo: the ``Demonstration`` shown.
        path: the scene-tree folder.
        offset: ``(3,)`` translation in the viewer [m] (side by side layout); settable later as ``.offset``.
        mapped: optional ``(T, 2, 3, 3)`` arm positions to show instead of the recorded ones
            (``nlo_lab.human.map_to_robot(demo, robot)``); hands, torso and head then follow
            at the robot's size (see the module doc).
        body: draw the torso and head (off for an overlay on the robot).
    """

    def __init__(self, vis, demo: Any, path: str = "human", offset: Sequence[float] = (0.0, 0.0, 0.0), mapped: np.ndarray | None = None, body: bool = True):
        self.vis = vis
        self.demo = demo
        self.path = path
        raw = np.asarray(demo.arm_positions, dtype=np.float64)  # (T, 2, 3, 3)
        arm_ok = np.asarray(demo.arm_mask, dtype=bool) & np.isfinite(raw).all(-1)  # (T, 2, 3)
        fingers = np.asarray(demo.finger_positions, dtype=np.float64)  # (T, 2, 5, 2, 3)
        finger_ok = np.asarray(demo.finger_mask, dtype=bool)[..., None] & np.isfinite(fingers).all(-1)  # (T, 2, 5, 2)
        if mapped is None:
            arms, self.factors = raw, np.ones(2)
        else:
            arms = np.asarray(mapped, dtype=np.float64)
            if arms.shape != raw.shape:
                raise SettingsError(f"mapped arm positions must have shape {raw.shape} (those of {demo.name!r}), got {arms.shape}")
            arm_ok &= np.isfinite(arms).all(-1)
            self.factors = arm_factors(raw, arms, arm_ok)
            wrist_raw, wrist_new = raw[:, :, 2, None, None, :], arms[:, :, 2, None, None, :]
            fingers = wrist_new + self.factors[None, :, None, None, None] * (fingers - wrist_raw)  # about the wrist
            finger_ok &= arm_ok[:, :, 2, None, None]  # a hand is placed by its wrist
        self.scale = float(np.mean(self.factors))  # size of the drawing relative to the human
        self.arm_length = self.scale * _arm_length(demo)  # [m] as drawn
        self.arm_visible = arm_ok  # (T, 2, 3)
        self.finger_visible = finger_ok  # (T, 2, 5, 2)
        self._arms = _hold_valid(np.where(arm_ok[..., None], arms, np.nan))  # (T, 2, 3, 3) without offset
        self._fingers = _hold_valid(np.where(finger_ok[..., None], fingers, np.nan))  # (T, 2, 5, 2, 3)
        self.has_fingers = bool(finger_ok.any())
        self.body = bool(body)
        self.offset = np.asarray(offset, dtype=np.float64).reshape(3)
        self._shown: dict[str, bool] = {}
        self._cache: tuple[tuple[float, ...], dict] | None = None

    def __len__(self) -> int:
        return int(self._arms.shape[0])

    @property
    def arms(self) -> np.ndarray:
        """``(T, 2, 3, 3)`` shown arm positions (last valid held where masked) [m]."""
        return self._arms + self.offset

    @property
    def fingers(self) -> np.ndarray:
        """``(T, 2, 5, 2, 3)`` shown finger base and tip positions [m]."""
        return self._fingers + self.offset

    # ------------------------------------------------------------ geometry per frame
    def _points(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """name -> (positions (T, 3), visible (T,))."""
        A, F = self.arms, self.fingers
        pts = {}
        for s, side in enumerate(("left", "right")):
            for j, joint in enumerate(("shoulder", "elbow", "wrist")):
                pts[f"{side}_{joint}"] = (A[:, s, j], self.arm_visible[:, s, j])
            if self.has_fingers:
                for f in range(5):
                    for k, kind in enumerate(("base", "tip")):
                        pts[f"{side}_f{f}_{kind}"] = (F[:, s, f, k], self.finger_visible[:, s, f, k])
        return pts

    def _bones(self) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """name -> (start (T, 3), end (T, 3), visible (T,))."""
        A, F, av, fv = self.arms, self.fingers, self.arm_visible, self.finger_visible
        bones = {"shoulders": (A[:, 0, 0], A[:, 1, 0], av[:, 0, 0] & av[:, 1, 0])}
        for s, side in enumerate(("left", "right")):
            bones[f"{side}_upper"] = (A[:, s, 0], A[:, s, 1], av[:, s, 0] & av[:, s, 1])
            bones[f"{side}_fore"] = (A[:, s, 1], A[:, s, 2], av[:, s, 1] & av[:, s, 2])
            if self.has_fingers:
                for f in range(5):
                    bones[f"{side}_palm{f}"] = (A[:, s, 2], F[:, s, f, 0], av[:, s, 2] & fv[:, s, f, 0])
                    bones[f"{side}_finger{f}"] = (F[:, s, f, 0], F[:, s, f, 1], fv[:, s, f, 0] & fv[:, s, f, 1])
        if self.body:
            _, _, head, visible = self._body_frames()
            mid = 0.5 * (A[:, 0, 0] + A[:, 1, 0])
            neck_top = head - np.array([0.0, 0.0, _HEAD_RADIUS * self.arm_length])
            bones["neck"] = (mid, neck_top, visible)
        return bones

    def _body_frames(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Torso box poses ``(T, 4, 4)`` and scales ``(T, 3)``, head centres ``(T, 3)``, visible ``(T,)``.

        The torso hangs from the shoulder line (its Y axis) with Z as close to up as the
        shoulders allow; the head sits above the shoulder midpoint.
        """
        A = self.arms
        left, right = A[:, 0, 0], A[:, 1, 0]  # (T, 3)
        mid = 0.5 * (left + right)
        across = left - right
        width = np.linalg.norm(across, axis=-1)  # (T,)
        y = across / np.maximum(width, 1e-9)[:, None]
        y[width < 1e-9] = [0.0, 1.0, 0.0]
        z = np.array([0.0, 0.0, 1.0]) - y[:, 2:3] * y  # up, made orthogonal to the shoulder line
        z /= np.maximum(np.linalg.norm(z, axis=-1, keepdims=True), 1e-9)
        x = np.cross(y, z)
        length = _TORSO_LENGTH * self.arm_length
        T = np.tile(np.eye(4), (len(A), 1, 1))
        T[:, :3, 0], T[:, :3, 1], T[:, :3, 2] = x, y, z
        T[:, :3, 3] = mid - 0.5 * length * z
        scale = np.stack([_TORSO_DEPTH * width, _TORSO_WIDTH * width, np.full_like(width, length)], -1)
        head = mid + _HEAD_HEIGHT * self.arm_length * z
        visible = self.arm_visible[:, 0, 0] & self.arm_visible[:, 1, 0]
        return T, scale, head, visible

    def extent_points(self) -> np.ndarray:
        """``(N, 3)`` points that bound everything drawn, over all frames where it is visible [m]."""
        chunks = [p[v] for p, v in self._points().values()]
        if self.body:
            T, scale, head, visible = self._body_frames()
            r = _HEAD_RADIUS * self.arm_length
            chunks += [head[visible] + d for d in r * np.vstack([np.eye(3), -np.eye(3)])]
            for sx in (-0.5, 0.5):
                for sy in (-0.5, 0.5):
                    for sz in (-0.5, 0.5):
                        corner = np.einsum("tij,tj->ti", T[:, :3, :3], scale * [sx, sy, sz]) + T[:, :3, 3]
                        chunks.append(corner[visible])
        pts = np.concatenate([c.reshape(-1, 3) for c in chunks]) if chunks else np.zeros((0, 3))
        return pts

    # ------------------------------------------------------------ meshcat
    def draw(self) -> HumanScene:
        """Create spheres, bones, torso and head (sized by :attr:`scale`), then show frame 0."""
        root = self.vis[self.path]
        s = self.scale
        detail = detail_of(self.vis)  # the live view draws lighter spheres and cylinders
        for name in self._points():
            finger = "_f" in name
            root["points"][name].set_object(sphere(s * _SIZES["finger" if finger else "joint"], detail), material(HUMAN_COLOURS["finger" if finger else "joint"]))
        for name in self._bones():
            finger = "palm" in name or "finger" in name
            radius = s * _SIZES["finger_bone" if finger else "bone"]
            root["bones"][name].set_object(cylinder(1.0, radius, detail), material(HUMAN_COLOURS["bone"]))
        if self.body:
            root["body"]["torso"].set_object(g.Box([1.0, 1.0, 1.0]), material(HUMAN_COLOURS["torso"], opacity=0.55))
            root["body"]["head"].set_object(sphere(_HEAD_RADIUS * self.arm_length, detail), material(HUMAN_COLOURS["head"]))
        self._shown = {}
        self.set_frame(0)
        return self

    def _nodes(self) -> dict[str, tuple[np.ndarray, np.ndarray | None, np.ndarray]]:
        """scene path (relative) -> (poses (T, 4, 4), scales (T, 3) or None, visible (T,)); cached per offset."""
        key = tuple(self.offset.tolist())
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        out = {}
        for name, (p, v) in self._points().items():
            T = np.tile(np.eye(4), (len(p), 1, 1))
            T[:, :3, 3] = p
            out[f"points/{name}"] = (T, None, v)
        for name, (a, b, v) in self._bones().items():
            T, scale = _bone_poses(a, b)
            out[f"bones/{name}"] = (T, scale, v)
        if self.body:
            T, scale, head, v = self._body_frames()
            out["body/torso"] = (T, scale, v)
            out["body/head"] = (np.stack([translation(h) for h in head]), None, v)
        self._cache = (key, out)
        return out

    def set_frame(self, t: int) -> None:
        """Show frame ``t``: nodes masked in it are hidden."""
        if not 0 <= t < len(self):
            raise SettingsError(f"frame {t} is outside 0..{len(self) - 1}")
        root = self.vis[self.path]
        for name, (T, scale, visible) in self._nodes().items():
            node = root[name]
            shown = bool(visible[t])
            if self._shown.get(name) != shown:  # only changes go over the wire
                node.set_property("visible", shown)
                self._shown[name] = shown
            if shown:
                node.set_transform(T[t] if scale is None else T[t] @ np.diag([*scale[t], 1.0]))

    def add_to(self, anim: Animation) -> None:
        """Add one key per frame to ``anim``: poses, and a ``visible`` track for nodes masked in some frames."""
        root = self.vis[self.path]
        for name, (T, scale, visible) in self._nodes().items():
            if not visible.any():
                continue  # hidden by draw() for good
            path = root[name].path
            add_pose_tracks(anim, path, T, scale)
            if not visible.all():
                add_visible_track(anim, path, visible)


def _arm_length(demo: Any) -> float:
    """Mean recorded arm length (upper + forearm) over the observed sides [m]; 0.56 m (adult) if none."""
    lengths = []
    for side in ("left", "right"):
        try:
            lengths.append(sum(demo.arm_lengths(side)))
        except NloLabError:
            continue
    return float(np.mean(lengths)) if lengths else 0.56

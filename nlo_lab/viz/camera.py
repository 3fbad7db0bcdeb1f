"""Where the viewer's camera stands: framed on a scene's points, from the front-side, slightly above.

meshcat 0.3.2's viewer (three.js ``OrbitControls``) always aims the camera at the
*world* origin: moving ``/Cameras/default`` moves the camera but not what it looks
at (measured: a robot at the origin stays centred when ``/Cameras/default`` is moved
2 m sideways). So to look at a scene centre ``c`` we shift the content instead:
the visualizer's root (``/meshcat``), the grid and the axes are translated by
``-c``, and the camera is placed at ``camera - c``. Orbiting then turns about the
scene centre. Scene nodes keep their body-frame poses below the root.

The body frame is X forward, Y left, Z up [m]; robots face +X.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from nlo_lab.errors import SettingsError, SettingsTypeError
from nlo_lab.viz.tracks import translation

__all__ = ["CameraView", "frame_points", "style_viewer", "apply_view", "DEFAULT_FOV"]

DEFAULT_FOV = 75.0  # [deg] meshcat's own vertical field of view
_ASPECT = 4.0 / 3.0  # assumed pane width / height: wider panes only gain margin left and right


@dataclass(frozen=True)
class CameraView:
    """A camera looking at ``target`` from ``position`` (body frame) [m].

    Attributes:
        target: ``(3,)`` the point looked at (the scene centre) [m].
        position: ``(3,)`` the camera [m].
        fov: vertical field of view [deg].
        floor: height of the grid [m] (the lowest point of the scene).
    """

    target: tuple[float, float, float]
    position: tuple[float, float, float]
    fov: float = DEFAULT_FOV
    floor: float = 0.0

    def __post_init__(self) -> None:
        for name in ("target", "position"):
            v = tuple(float(x) for x in getattr(self, name))
            if len(v) != 3 or not all(math.isfinite(x) for x in v):
                raise SettingsError(f"CameraView.{name} must be 3 finite numbers, got {getattr(self, name)!r}")
            object.__setattr__(self, name, v)
        if not 1.0 <= float(self.fov) <= 170.0:
            raise SettingsError(f"CameraView.fov must be in [1, 170] degrees, got {self.fov!r}")
        if not math.isfinite(float(self.floor)):
            raise SettingsError(f"CameraView.floor must be finite, got {self.floor!r}")
        if np.allclose(self.target, self.position):
            raise SettingsError("CameraView: the camera stands on its target")
        object.__setattr__(self, "fov", float(self.fov))
        object.__setattr__(self, "floor", float(self.floor))

    def project(self, points: np.ndarray, aspect: float = _ASPECT) -> np.ndarray:
        """Normalised screen coordinates ``(N, 2)`` of body-frame ``points`` ``(N, 3)``: the view is [-1, 1]²."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        eye, target = np.asarray(self.position), np.asarray(self.target)
        f = (target - eye) / np.linalg.norm(target - eye)
        right = np.cross(f, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, f)
        rel = p - eye
        depth = rel @ f
        t = math.tan(math.radians(self.fov) / 2)
        return np.stack([(rel @ right) / (depth * t * aspect), (rel @ up) / (depth * t)], -1)


def _basis(azimuth: float, elevation: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors: ``d`` from target to camera, screen ``right`` and ``up``."""
    az, el = math.radians(azimuth), math.radians(elevation)
    d = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    right = np.cross(-d, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return d, right, np.cross(right, -d)


def frame_points(
    points: np.ndarray,
    azimuth: float = 25.0,
    elevation: float = 15.0,
    fov: float = 35.0,
    fill: float = 0.85,
    aspect: float = _ASPECT,
) -> CameraView:
    """A camera that sees every point and fills ``fill`` of the view's tighter dimension.

    Args:
        points: ``(N, 3)`` body-frame points of the scene (NaN rows ignored) [m].
        azimuth: camera direction from the scene centre, turned from +X (the robot's front)
            towards +Y (its left) [deg].
        elevation: camera height above the horizontal through the centre [deg].
        fov: vertical field of view [deg]; narrower than meshcat's 75° for less perspective distortion.
        fill: fraction of the view (width or height, whichever binds) the scene spans.
        aspect: the pane's width / height assumed when fitting the width.

    Returns:
        The :class:`CameraView`.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    p = p[np.isfinite(p).all(-1)]
    if len(p) == 0:
        raise SettingsError("cannot frame a camera on a scene without finite points")
    if not 0.05 <= fill <= 1.0:
        raise SettingsError(f"fill must be in [0.05, 1], got {fill!r}")
    if not -80.0 <= elevation <= 80.0:
        raise SettingsError(f"elevation must be in [-80, 80] degrees (the view's up is +Z), got {elevation!r}")
    if not 1.0 <= fov <= 170.0 or aspect <= 0:
        raise SettingsError(f"fov must be in [1, 170] degrees and aspect > 0, got fov={fov!r}, aspect={aspect!r}")
    d, right, up = _basis(azimuth, elevation)
    tv = math.tan(math.radians(fov) / 2) * fill  # tan of the half-angle the scene may use, vertically
    th = tv * aspect
    extent = float(np.ptp(p, axis=0).max())
    centre = 0.5 * (p.min(0) + p.max(0))
    dist = 1.0
    for _ in range(4):  # perspective makes the near side bigger: re-centre on the projected extent
        rel = p - centre
        a, x, y = rel @ d, rel @ right, rel @ up
        dist = float(max(np.max(a + np.abs(x) / th), np.max(a + np.abs(y) / tv), np.max(a) + 0.1 * extent, 0.05))
        depth = dist - a
        sx, sy = x / depth, y / depth
        centre = centre + right * 0.5 * (sx.min() + sx.max()) * dist + up * 0.5 * (sy.min() + sy.max()) * dist
    rel = p - centre
    a, x, y = rel @ d, rel @ right, rel @ up
    dist = float(max(np.max(a + np.abs(x) / th), np.max(a + np.abs(y) / tv), np.max(a) + 0.1 * extent, 0.05))
    return CameraView(tuple(centre), tuple(centre + dist * d), fov=fov, floor=float(p[:, 2].min()))


def apply_view(vis, view: CameraView) -> None:
    """Aim the viewer: shift the content by ``-target`` (see module doc), place the camera, set its field of view."""
    c = np.asarray(view.target)
    vis.set_transform(translation(-c))  # the visualizer's root (``/meshcat`` for a root Visualizer)
    vis["/Grid"].set_transform(translation([-c[0], -c[1], view.floor - c[2]]))  # the grid is the floor
    vis["/Axes"].set_transform(translation(-c))  # the axes mark the body frame's origin ...
    vis["/Axes"].set_property("visible", False)  # ... hidden: 0.5 m long they cross a small robot (Open Controls shows them)
    x, y, z = (np.asarray(view.position) - c).tolist()
    # The camera lives under a node that turns three.js' Y-up into meshcat's Z-up: (x, y, z) -> (x, z, -y).
    camera = vis["/Cameras/default/rotated/<object>"]
    camera.set_property("position", [x, z, -y])
    camera.set_property("fov", float(view.fov))  # the viewer updates the projection every frame


def style_viewer(
    vis,
    camera: Sequence[float] | CameraView = (2.0, -0.6, 0.6),
    background: Sequence[float] = (1.0, 1.0, 1.0),
) -> None:
    """A light background (the group colours stand out) and a camera.

    Args:
        vis: a meshcat ``Visualizer``.
        camera: a :class:`CameraView` (e.g. from :func:`frame_points`), or a ``(3,)`` camera
            position in the body frame [m] looking at the origin with meshcat's field of view.
        background: ``(3,)`` RGB in [0, 1] of the top of the background gradient (the bottom is slightly darker).
    """
    top = [float(c) for c in background]
    vis["/Background"].set_property("top_color", top)
    vis["/Background"].set_property("bottom_color", [0.85 * c for c in top])
    if not isinstance(camera, CameraView):
        pos = tuple(float(c) for c in camera)
        if len(pos) != 3:
            raise SettingsTypeError(f"camera must be a CameraView or an (x, y, z) position, got {camera!r}")
        camera = CameraView((0.0, 0.0, 0.0), pos, fov=DEFAULT_FOV, floor=0.0)
    apply_view(vis, camera)

"""A robot's collision capsules drawn over it: what the self-collision term sees.

:func:`draw_capsules` adds each capsule of the spec (a cylinder and two spheres, translucent)
under its link's node of a drawn :class:`~nlo_lab.viz.scene.RobotScene`, so the capsules move
with the links the scene poses; thinned copies (``CAPSULE~Nmm``) are left out (they are the same
capsules, thinner, for one pair).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from nlo_lab.viz.tracks import cylinder, detail_of, material, sphere

__all__ = ["CAPSULE_COLOUR", "draw_capsules"]

CAPSULE_COLOUR = 0xD62728  # red, translucent over the robot's own colours


def _along_y(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """``(4, 4)`` a frame at the segment's middle whose Y runs along it (meshcat's cylinders run along Y)."""
    T = np.eye(4)
    T[:3, 3] = (p0 + p1) / 2
    d = p1 - p0
    n = float(np.linalg.norm(d))
    if n > 1e-9:
        y = d / n
        x = np.cross(y, [0.0, 0.0, 1.0] if abs(y[2]) < 0.9 else [1.0, 0.0, 0.0])
        x /= np.linalg.norm(x)
        T[:3, :3] = np.stack([x, y, np.cross(x, y)], axis=1)
    return T


def draw_capsules(vis, robot: Any, path: str = "robot", opacity: float = 0.35) -> int:
    """Draw every capsule of ``robot``'s spec under ``vis[path][link]``; returns how many."""
    detail = detail_of(vis)
    count = 0
    for c in robot.spec.capsules:
        if "~" in c.name:
            continue
        p0, p1 = np.asarray(c.p0, dtype=np.float64), np.asarray(c.p1, dtype=np.float64)
        node = vis[path][c.link][f"capsule_{c.name}"]
        length = float(np.linalg.norm(p1 - p0))
        if length > 1e-6:
            node["body"].set_object(cylinder(length, c.radius, detail), material(CAPSULE_COLOUR, opacity))
            node["body"].set_transform(_along_y(p0, p1))
        for k, end in enumerate((p0, p1)):
            T = np.eye(4)
            T[:3, 3] = end
            node[f"end{k}"].set_object(sphere(c.radius, detail), material(CAPSULE_COLOUR, opacity))
            node[f"end{k}"].set_transform(T)
        count += 1
    return count


"""What the 3-D view draws of a robot: its URDF's ``<visual>`` elements, meshes decimated to a budget.

Primitives (box, cylinder, sphere) are drawn as they are: the bundled robots have nothing else.
Mesh files (STL, COLLADA, OBJ; found and bounded by :mod:`nlo_lab.robot.mesh_files`) are read
with trimesh and decimated with its quadric decimation (corners merged first) so that all the
meshes of one robot together keep about :data:`MESH_FACE_BUDGET` triangles (each a share by its
size, at least :data:`MIN_MESH_FACES`; Baxter's 440,000 become 43,000): a scene stays light in a
browser without a GPU, and a ``viewer.html`` small (Baxter's: 2.1 MB). A mesh file that is missing or unreadable gives one warning and a
stand-in: the link's primitive collision shapes if it has any, else a small sphere.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from nlo_lab.errors import RobotDescriptionError

__all__ = ["MESH_FACE_BUDGET", "MIN_MESH_FACES", "STAND_IN_RADIUS", "Visual", "robot_visuals_of"]

MESH_FACE_BUDGET = 40_000  # triangles of all of a robot's meshes together (YuMi's primitives draw 10k-45k)
MIN_MESH_FACES = 100  # a mesh keeps at least this many triangles (or all it has)
STAND_IN_RADIUS = 0.03  # [m] the sphere drawn for a missing mesh when the link has no primitive collision shape


@dataclass(frozen=True)
class Visual:
    """One visual of a URDF link.

    Attributes:
        link: the link's name.
        kind: ``"box"``, ``"cylinder"``, ``"sphere"`` or ``"mesh"``.
        size: box (x, y, z) lengths; cylinder (radius, length); sphere (radius,) [m]; ``()`` for a mesh.
        T_link_visual: ``(4, 4)`` pose of the primitive in the link frame (URDF convention: cylinder
            along Z); the identity for a mesh, whose vertices are in the link frame already.
        vertices: ``(k, 3)`` float32 [m] of a mesh (link frame), else None.
        faces: ``(m, 3)`` int32 vertex indices of a mesh, else None.
        rgba: the URDF material's colour, or None.
    """

    link: str
    kind: str
    size: tuple[float, ...]
    T_link_visual: np.ndarray
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None
    rgba: tuple[float, float, float, float] | None = None


def _primitive(shape) -> Visual:
    return Visual(shape.link, shape.kind, tuple(shape.size), shape.T_link_shape, rgba=shape.rgba)


def _stand_in(shape, collision: list) -> list[Visual]:
    prims = [_primitive(c) for c in collision if c.link == shape.link and c.kind != "mesh"]
    return prims or [Visual(shape.link, "sphere", (STAND_IN_RADIUS,), shape.T_link_shape, rgba=shape.rgba)]


def robot_visuals_of(model: Any, budget: int = MESH_FACE_BUDGET) -> list[Visual]:
    """Every visual of every link of a parsed URDF model (or a ``Robot``), meshes decimated (see the module docstring).

    Raises:
        RobotDescriptionError: a mesh path outside the URDF's folder tree (never drawn, never read).
    """
    from nlo_lab.robot.geometry import decimate, link_shapes, shape_mesh

    shapes = link_shapes(model, "visual")
    out: list[Visual | None] = []
    meshes = []  # (position in out, shape, trimesh)
    collision = None
    for shape in shapes:
        if shape.kind != "mesh":
            out.append(_primitive(shape))
            continue
        try:
            meshes.append((len(out), shape, shape_mesh(shape)))
            out.append(None)  # filled below
        except (FileNotFoundError, RobotDescriptionError) as exc:
            what = "is missing" if isinstance(exc, FileNotFoundError) else f"cannot be drawn ({exc})"
            warnings.warn(f"link {shape.link!r}: visual mesh {shape.mesh_file} {what}; a stand-in is drawn", stacklevel=2)
            collision = link_shapes(model, "collision") if collision is None else collision
            out.extend(_stand_in(shape, collision))
    total = sum(len(m.faces) for _, _, m in meshes)
    for index, shape, mesh in meshes:
        share = max(MIN_MESH_FACES, int(budget * len(mesh.faces) / max(total, 1)))
        small = decimate(mesh, share)
        out[index] = Visual(shape.link, "mesh", (), np.eye(4), np.asarray(small.vertices, dtype=np.float32),
                            np.asarray(small.faces, dtype=np.int32), shape.rgba)
    return [v for v in out if v is not None]

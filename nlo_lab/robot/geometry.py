"""The shapes a URDF gives its links (``<visual>`` or ``<collision>``), as trimesh meshes in the link frame.

:func:`link_shapes` lists them (primitives, or a mesh file resolved inside the URDF's
folder tree by :mod:`~nlo_lab.robot.mesh_files`); :func:`shape_mesh` makes a
``trimesh.Trimesh`` of one, in its link's frame (origin and scale applied); :func:`decimate`
reduces a mesh to a face budget with trimesh's quadric decimation. The capsule fit of
``nlo-lab robot init``, the viewer's meshes and the self-collision check by the URDF's own
geometry (:mod:`~nlo_lab.robot.geometry_collision`) all start here.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from nlo_lab.robot.mesh_files import read_mesh, resolve_mesh

__all__ = ["ROLES", "PRIMITIVE_SECTIONS", "Shape", "link_shapes", "shape_mesh", "decimate"]

ROLES = ("visual", "collision")
PRIMITIVE_SECTIONS = 64  # cylinder sides; a sphere is an icosphere of 1280 faces (both within 0.2 % of the radius)


@dataclass(frozen=True)
class Shape:
    """One ``<visual>`` or ``<collision>`` element of a link.

    Attributes:
        link: the link's name.
        kind: ``"box"``, ``"cylinder"``, ``"sphere"`` or ``"mesh"``.
        size: box (x, y, z) lengths; cylinder (radius, length); sphere (radius,); mesh its
            scale (x, y, z) [m].
        T_link_shape: ``(4, 4)`` the element's ``<origin>`` in the link frame.
        mesh_file: the mesh file (resolved, maybe missing) for ``"mesh"``, else None.
        role: ``"visual"`` or ``"collision"``.
        rgba: the material colour when the URDF gives one, else None.
    """

    link: str
    kind: str
    size: tuple[float, ...]
    T_link_shape: np.ndarray
    mesh_file: Path | None = None
    role: str = "collision"
    rgba: tuple[float, float, float, float] | None = None


def _urdf_of(model: Any):
    """The ``yourdfpy.URDF`` of a :class:`~nlo_lab.robot.urdf.URDFModel` or a ``Robot``."""
    model = getattr(model, "model", model)  # a Robot keeps its URDFModel as .model
    return model.urdf, Path(model.path)


def _rgba(element, materials: dict) -> tuple[float, float, float, float] | None:
    material = getattr(element, "material", None)
    if material is None:
        return None
    colour = material.color if material.color is not None else materials.get(material.name)
    if colour is None or colour.rgba is None:
        return None
    rgba = tuple(float(v) for v in np.asarray(colour.rgba, dtype=np.float64).reshape(-1)[:4])
    return rgba if len(rgba) == 4 and all(np.isfinite(rgba)) else None


def link_shapes(model: Any, role: str = "collision") -> list[Shape]:
    """Every ``role`` element of every link, in file order.

    Args:
        model: a parsed :class:`~nlo_lab.robot.urdf.URDFModel` (or a ``Robot``).
        role: ``"visual"`` or ``"collision"``.

    Raises:
        RobotDescriptionError: a mesh path outside the URDF's folder tree, or not a mesh file.
    """
    urdf, path = _urdf_of(model)
    materials = {m.name: m.color for m in urdf.robot.materials if m.name is not None}
    out: list[Shape] = []
    for link in urdf.robot.links:
        for element in (link.visuals if role == "visual" else link.collisions) or []:
            geom = element.geometry
            if geom is None:
                continue
            T = np.eye(4) if element.origin is None else np.asarray(element.origin, dtype=np.float64)
            rgba = _rgba(element, materials) if role == "visual" else None
            if geom.box is not None:
                out.append(Shape(link.name, "box", tuple(float(v) for v in geom.box.size), T, None, role, rgba))
            elif geom.cylinder is not None:
                out.append(Shape(link.name, "cylinder", (float(geom.cylinder.radius), float(geom.cylinder.length)), T, None, role, rgba))
            elif geom.sphere is not None:
                out.append(Shape(link.name, "sphere", (float(geom.sphere.radius),), T, None, role, rgba))
            elif geom.mesh is not None and geom.mesh.filename:
                scale = np.ones(3) if geom.mesh.scale is None else np.broadcast_to(np.asarray(geom.mesh.scale, dtype=np.float64).reshape(-1), (3,))
                mesh_file = resolve_mesh(str(geom.mesh.filename), path)
                out.append(Shape(link.name, "mesh", tuple(float(v) for v in scale), T, mesh_file, role, rgba))
    return out


def shape_mesh(shape: Shape):
    """The shape as a ``trimesh.Trimesh`` in its link's frame [m].

    Raises:
        FileNotFoundError: a mesh file that is missing.
        RobotDescriptionError: a mesh file out of bounds or unreadable (:func:`~nlo_lab.robot.mesh_files.read_mesh`).
    """
    # lazy: trimesh loads its mesh formats on import: only where meshes are read
    import trimesh

    if shape.kind == "box":
        mesh = trimesh.creation.box(extents=shape.size)
    elif shape.kind == "cylinder":
        mesh = trimesh.creation.cylinder(radius=shape.size[0], height=shape.size[1], sections=PRIMITIVE_SECTIONS)
    elif shape.kind == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=shape.size[0])
    else:
        mesh = read_mesh(shape.mesh_file)
        mesh.apply_transform(np.diag([*shape.size, 1.0]))  # a mirroring scale also flips the faces' winding
    mesh.apply_transform(shape.T_link_shape)
    return mesh


def decimate(mesh, max_faces: int):
    """``mesh`` with at most ``max_faces`` faces (trimesh's quadric decimation; a copy when already small)."""
    if len(mesh.faces) <= max_faces:
        return mesh.copy()
    mesh = mesh.copy()
    mesh.merge_vertices()  # exported meshes often repeat each corner per triangle: a soup decimates into holes
    if len(mesh.faces) <= max_faces:
        return mesh
    small = mesh.simplify_quadric_decimation(face_count=int(max_faces))
    if len(small.faces) == 0 or len(small.faces) > max_faces:  # degenerate input: keep the convex hull instead
        small = mesh.convex_hull
    return small

"""Mesh files a URDF names: where they may lie, how large they may be, and reading them.

A URDF names a mesh as ``package://PKG/path``, as a path relative to the URDF file, or as
``file://`` / an absolute path. A URDF may come from anywhere, so the mesh it names is
only read when it lies inside **the URDF's folder tree**:

* ``package://PKG/rest``: ``rest`` under the nearest folder named ``PKG`` among the URDF's
  folder and its ancestors up to :data:`PACKAGE_LEVELS` levels up (the ROS layout
  ``PKG/urdf/robot.urdf``, ``PKG/meshes/...``); without such a folder, under the URDF's folder;
* anything else: under the URDF's own folder.

A path that leaves that root (``..``, an absolute path elsewhere, a link pointing out) is
refused with one :class:`~nlo_lab.errors.RobotDescriptionError`, as are file types other
than :data:`MESH_SUFFIXES`. A mesh is read with trimesh only after its size is checked
(:data:`MAX_MESH_BYTES`; a binary STL's triangle count from its header; a COLLADA file
parsed by :mod:`~nlo_lab.robot.safe_xml` first: no DTD, no entities), and it is refused above
:data:`MAX_MESH_FACES` faces. Real robots pass: their meshes are up to a few MB and some
tens of thousands of faces (TIAGo, Talos, PR2, Baxter in ``example-robot-data``).
"""

from __future__ import annotations

import functools
import os
import struct
from pathlib import Path
from urllib.parse import unquote, urlparse

import numpy as np

from nlo_lab.errors import RobotDescriptionError, escape
from nlo_lab.robot.safe_xml import parse_xml

__all__ = [
    "MESH_SUFFIXES",
    "MAX_MESH_BYTES",
    "MAX_MESH_FACES",
    "PACKAGE_LEVELS",
    "mesh_root",
    "resolve_mesh",
    "read_mesh",
]

MESH_SUFFIXES = (".stl", ".dae", ".obj")  # what URDFs use (and trimesh reads)
MAX_MESH_BYTES = 32 * 2**20  # per file; real robots' meshes are up to a few MB
MAX_MESH_FACES = 1_000_000  # per file; a detailed 45k-face STL is common, a million is not a robot part
PACKAGE_LEVELS = 3  # package://PKG is searched in the URDF's folder and this many ancestors


def _split(filename: str) -> tuple[str | None, str]:
    """``(package or None, path)`` of a URDF mesh filename (``package://``, ``file://`` or a path)."""
    if filename.startswith("package://"):
        pkg, _, rest = filename[len("package://"):].partition("/")
        return pkg, rest
    if filename.startswith("file://"):
        return None, unquote(urlparse(filename).path)
    if "://" in filename:
        raise RobotDescriptionError(f"mesh {escape(filename)!r}: only package://, file:// and plain paths are read")
    return None, filename


def mesh_root(filename: str, urdf_path: str | Path) -> Path:
    """The folder a mesh of ``filename`` must stay in (see the module docstring)."""
    folder = Path(urdf_path).resolve().parent
    pkg, _ = _split(filename)
    if pkg:
        for candidate in [folder, *folder.parents][: PACKAGE_LEVELS + 1]:
            if candidate.name == pkg:
                return candidate
    return folder


def resolve_mesh(filename: str, urdf_path: str | Path) -> Path:
    """The file a URDF's mesh ``filename`` stands for, inside the URDF's folder tree.

    Nothing is read: the file may not exist (the viewer then draws a stand-in).

    Raises:
        RobotDescriptionError: the path leaves the folder tree, or is not a mesh type
            trimesh reads (:data:`MESH_SUFFIXES`), naming the URDF and the mesh.
    """
    where = f"{urdf_path}: mesh {escape(filename)!r}"
    if not filename or "\x00" in filename:
        raise RobotDescriptionError(f"{where}: not a file name")
    try:
        _, rest = _split(filename)
    except RobotDescriptionError as exc:
        raise RobotDescriptionError(f"{urdf_path}: {exc}") from None
    root = mesh_root(filename, urdf_path)
    path = (root / rest) if not os.path.isabs(rest) else Path(rest)
    resolved = Path(os.path.realpath(path))  # links followed: a link may not point out either
    if resolved != root and root not in resolved.parents:
        raise RobotDescriptionError(f"{where} lies outside the URDF's folder tree {root} (refused)")
    if resolved.suffix.lower() not in MESH_SUFFIXES:
        raise RobotDescriptionError(f"{where}: not a mesh file ({', '.join(MESH_SUFFIXES)} are read)")
    return resolved


def _check_size(path: Path) -> int:
    try:
        info = path.stat()
    except FileNotFoundError:
        raise FileNotFoundError(2, "mesh file not found", str(path)) from None
    if not path.is_file():
        raise RobotDescriptionError(f"mesh {path} is not a regular file")
    if info.st_size > MAX_MESH_BYTES:
        raise RobotDescriptionError(f"mesh {path} is {info.st_size / 2**20:.1f} MiB; at most {MAX_MESH_BYTES // 2**20} MiB is read")
    if info.st_size == 0:
        raise RobotDescriptionError(f"mesh {path} is empty")
    return info.st_size


def _check_head(path: Path, size: int) -> None:
    """What the first bytes say (a binary STL's triangle count); a COLLADA file without a DTD."""
    with open(path, "rb") as f:
        head = f.read(84)
    suffix = path.suffix.lower()
    if suffix == ".stl" and len(head) >= 84:
        (count,) = struct.unpack("<I", head[80:84])
        binary = 84 + 50 * count == size  # ASCII STL starts with "solid"; so do some binary headers
        if not binary and not head.lstrip().lower().startswith(b"solid"):
            raise RobotDescriptionError(f"mesh {path}: a binary STL of {count} triangles must be {84 + 50 * count} bytes, not {size}")
        if binary and count > MAX_MESH_FACES:
            raise RobotDescriptionError(f"mesh {path} declares {count} triangles; at most {MAX_MESH_FACES} are read")
    if suffix == ".dae":  # XML: parsed once our way first (no DTD, no entities), then trimesh reads it
        parse_xml(path.read_bytes(), f"mesh {path}", huge=True)  # the size is bounded above


def read_mesh(path: str | Path):
    """Read one mesh file as a single ``trimesh.Trimesh`` (scenes concatenated), with the bounds checked.

    A file is read once while it is unchanged (same size and time); each call returns a copy.

    Raises:
        FileNotFoundError: the file is missing.
        RobotDescriptionError: too large, too many faces, a DTD in a COLLADA file, or not
            readable as a mesh (naming the file).
    """
    path = Path(path)
    size = _check_size(path)
    return _read_checked(str(path), size, path.stat().st_mtime_ns).copy()


@functools.lru_cache(maxsize=128)
def _read_checked(name: str, size: int, mtime_ns: int):
    """The mesh of file ``name`` (size and time are the cache key: a changed file is read again)."""
    # lazy: trimesh loads its mesh formats on import: only where meshes are read
    import trimesh

    path = Path(name)
    _check_head(path, size)
    try:
        mesh = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # trimesh and its loaders raise assorted types for a damaged file
        raise RobotDescriptionError(f"mesh {path} cannot be read ({type(exc).__name__}: {escape(exc)})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise RobotDescriptionError(f"mesh {path} holds no triangles")
    if len(mesh.faces) > MAX_MESH_FACES:
        raise RobotDescriptionError(f"mesh {path} has {len(mesh.faces)} faces; at most {MAX_MESH_FACES} are read")
    if not np.isfinite(mesh.vertices).all():
        raise RobotDescriptionError(f"mesh {path} has vertices that are not finite numbers")
    return mesh

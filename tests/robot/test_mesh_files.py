"""Mesh files a URDF names: confined to its folder tree, bounded in size and faces (nlo_lab.robot.mesh_files)."""

from __future__ import annotations

import os
import struct

import numpy as np
import pytest
import trimesh

from nlo_lab.errors import RobotDescriptionError
from nlo_lab.robot import mesh_files
from nlo_lab.robot.mesh_files import read_mesh, resolve_mesh


@pytest.fixture
def package(tmp_path):
    """A ROS-like package: pkg/urdf/robot.urdf and pkg/meshes/part.stl, a secret beside the package."""
    (tmp_path / "pkg" / "urdf").mkdir(parents=True)
    (tmp_path / "pkg" / "meshes").mkdir()
    trimesh.creation.box(extents=(0.1, 0.2, 0.3)).export(tmp_path / "pkg" / "meshes" / "part.stl")
    (tmp_path / "secret.stl").write_bytes(b"solid secret\nendsolid secret\n")
    urdf = tmp_path / "pkg" / "urdf" / "robot.urdf"
    urdf.write_text("<robot name='r'/>")
    return urdf


def test_package_and_relative_paths_inside_the_tree_resolve(package):
    root = package.parent.parent
    assert resolve_mesh("package://pkg/meshes/part.stl", package) == (root / "meshes" / "part.stl").resolve()
    (package.parent / "local.obj").write_text("v 0 0 0\n")
    assert resolve_mesh("local.obj", package) == (package.parent / "local.obj").resolve()
    assert resolve_mesh(f"file://{package.parent / 'local.obj'}", package) == (package.parent / "local.obj").resolve()


@pytest.mark.parametrize("name", [
    "package://pkg/../secret.stl",            # .. out of the package
    "../../secret.stl",                        # relative, out of the URDF's folder
    "package://other/../../secret.stl",        # an unknown package falls back to the URDF's folder
    "/etc/passwd.stl",                         # absolute, elsewhere
    "file:///etc/hosts.stl",
    "package://pkg/meshes/part.txt",           # not a mesh type
    "http://127.0.0.1:9/part.stl",             # not a file
])
def test_paths_leaving_the_tree_or_not_meshes_are_refused(package, name):
    with pytest.raises(RobotDescriptionError) as info:
        resolve_mesh(name, package)
    assert "\n" not in str(info.value) and str(package) in str(info.value)


def test_a_link_pointing_out_of_the_tree_is_refused(package):
    link = package.parent.parent / "meshes" / "out.stl"
    os.symlink(package.parent.parent.parent / "secret.stl", link)
    with pytest.raises(RobotDescriptionError, match="outside the URDF's folder tree"):
        resolve_mesh("package://pkg/meshes/out.stl", package)


def test_a_mesh_reads_within_its_bounds(package):
    mesh = read_mesh(package.parent.parent / "meshes" / "part.stl")
    assert len(mesh.faces) == 12 and np.allclose(mesh.extents, (0.1, 0.2, 0.3))


def test_a_binary_stl_declaring_too_many_triangles_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / "huge.stl"
    path.write_bytes(b"\0" * 80 + struct.pack("<I", 50_000_000) + b"\0" * 100)
    with pytest.raises(RobotDescriptionError, match="must be .* bytes"):
        read_mesh(path)
    count = mesh_files.MAX_MESH_FACES + 1
    path.write_bytes(b"\0" * 80 + struct.pack("<I", count))
    with open(path, "ab") as f:
        f.truncate(84 + 50 * count)  # a sparse file of the declared size
    with pytest.raises(RobotDescriptionError, match="(declares|MiB)"):
        read_mesh(path)


def test_size_and_face_bounds(tmp_path, monkeypatch):
    path = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=3).export(path)  # 1280 faces
    monkeypatch.setattr(mesh_files, "MAX_MESH_BYTES", 1000)
    with pytest.raises(RobotDescriptionError, match="MiB"):
        read_mesh(path)
    monkeypatch.setattr(mesh_files, "MAX_MESH_BYTES", 2**25)
    monkeypatch.setattr(mesh_files, "MAX_MESH_FACES", 1000)
    with pytest.raises(RobotDescriptionError, match="1280 triangles"):
        read_mesh(path)


def test_a_collada_file_with_a_dtd_is_refused(tmp_path):
    path = tmp_path / "part.dae"
    path.write_bytes(b'<?xml version="1.0"?><!DOCTYPE c [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
                     b'<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">&x;</COLLADA>')
    with pytest.raises(RobotDescriptionError, match="DTD|entity"):
        read_mesh(path)


def test_missing_empty_and_garbage_files(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_mesh(tmp_path / "none.stl")
    (tmp_path / "empty.obj").write_bytes(b"")
    with pytest.raises(RobotDescriptionError, match="empty"):
        read_mesh(tmp_path / "empty.obj")
    (tmp_path / "junk.obj").write_bytes(b"this is not a mesh\n")
    with pytest.raises(RobotDescriptionError):
        read_mesh(tmp_path / "junk.obj")


@pytest.mark.slow
def test_real_robot_meshes_pass_the_bounds(robot_data):
    """The largest meshes of robots we did not model (tens of thousands of faces, MBs) read."""
    files = sorted((p for p in robot_data.rglob("*") if p.suffix.lower() in (".stl", ".dae")), key=lambda p: -p.stat().st_size)[:4]
    assert files and files[0].stat().st_size > 1_000_000
    for path in files:
        mesh = read_mesh(path)
        assert len(mesh.faces) > 1000 and np.isfinite(mesh.vertices).all()

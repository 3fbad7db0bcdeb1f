"""Tests of nlo_lab.atomic_files and of the three writers that use it (trajectory, demonstration, viewer page)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pytest

from nlo_lab.atomic_files import atomic_path, atomic_write_bytes, current_umask
from nlo_lab.human import Demonstration, save_npz
from nlo_lab.inference import RobotTrajectory
from nlo_lab.robot import load_robot
from nlo_lab.viz import export_html


@pytest.fixture(params=[0o022, 0o027, 0o002])
def umask(request):
    old = os.umask(request.param)
    try:
        yield request.param
    finally:
        os.umask(old)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def _demo(T=4):
    arm = np.zeros((T, 2, 3, 3))
    for s, y in enumerate((0.18, -0.18)):
        arm[:, s] = [[0, y, 0], [0.05, y, -0.28], [0.3, y, -0.23]]
    rot = np.broadcast_to(np.eye(3), (T, 2, 3, 3)).copy()
    fingers = np.broadcast_to(arm[:, :, 2, None, None, :], (T, 2, 5, 2, 3)).copy()
    fingers[..., 0] += np.linspace(0.05, 0.1, 2)[None, None, None, :]
    return Demonstration(25.0, arm, np.ones((T, 2, 3), bool), rot, np.ones((T, 2), bool), fingers, np.ones((T, 2, 5), bool), name="d")


def test_current_umask_reads_without_changing(umask):
    assert current_umask() == umask
    assert current_umask() == umask


def test_every_writer_gives_the_umask_mode(tmp_path, umask):
    expected = 0o666 & ~umask
    traj = RobotTrajectory("nao", ["a", "b"], np.zeros((3, 2)), 10.0)
    written = [
        traj.save_npz(tmp_path / "t.npz"),
        traj.save_json(tmp_path / "t.json"),
        traj.save_csv(tmp_path / "t.csv"),
        save_npz(_demo(), tmp_path / "d.npz"),
        atomic_write_bytes(tmp_path / "raw.bin", b"x"),
    ]
    robot = load_robot("nao")
    written.append(export_html(tmp_path / "v.html", robot, np.zeros((2, robot.n_joints))))
    for path in written:
        assert _mode(path) == expected, f"{path.name}: mode {oct(_mode(path))}, expected {oct(expected)}"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in written)  # no temporaries left


def test_failed_write_leaves_nothing_and_keeps_the_old_file(tmp_path):
    target = tmp_path / "out.bin"
    with pytest.raises(RuntimeError, match="half way"):
        with atomic_path(target) as tmp:
            tmp.write_bytes(b"partial")
            raise RuntimeError("half way")
    assert list(tmp_path.iterdir()) == []
    atomic_write_bytes(target, b"old")
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(target) as tmp:
            tmp.write_bytes(b"new")
            raise KeyboardInterrupt
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.bin"]


def test_failed_writers_leave_nothing(tmp_path, monkeypatch):
    def boom(*a, **k):
        raise OSError("disk full")

    robot = load_robot("nao")
    monkeypatch.setattr(np, "savez", boom)
    from nlo_lab.errors import DemonstrationError

    with pytest.raises(DemonstrationError, match="disk full"):
        save_npz(_demo(), tmp_path / "d.npz")
    monkeypatch.undo()
    monkeypatch.setattr(Path, "write_text", boom)
    with pytest.raises(OSError, match="disk full"):
        export_html(tmp_path / "v.html", robot, np.zeros((2, robot.n_joints)))
    assert list(tmp_path.iterdir()) == []


def test_missing_folder_is_an_error(tmp_path):
    with pytest.raises(FileNotFoundError):
        atomic_write_bytes(tmp_path / "nope" / "x.bin", b"x")
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- output places refused before any input is read (issue 25)
def test_an_empty_output_path_is_refused():
    from nlo_lab.atomic_files import check_output_place
    from nlo_lab.errors import OutputError

    for bad in ("", None, 5):
        with pytest.raises(OutputError, match="must be a non-empty path"):
            check_output_place(bad, ("a",))


def test_a_read_only_output_folder_is_refused(tmp_path):
    """Also as root, who may write anywhere: a folder made read-only is not ours to replace."""
    from nlo_lab.atomic_files import check_output_place, output_set
    from nlo_lab.errors import OutputError

    out = tmp_path / "out"
    out.mkdir()
    (out / "a").write_text("old")
    out.chmod(0o555)
    try:
        with pytest.raises(OutputError, match=r"out is read-only \(mode 555\)"):
            check_output_place(out, ("a",))
        with pytest.raises(OutputError, match="read-only"), output_set(out, ("a",)) as tmp:
            (tmp / "a").write_text("new")
        assert (out / "a").read_text() == "old" and sorted(os.listdir(tmp_path)) == ["out"]
    finally:
        out.chmod(0o755)


def test_an_output_folder_of_another_user_is_refused(others_folder):
    from nlo_lab.atomic_files import check_output_place
    from nlo_lab.errors import OutputError

    with pytest.raises(OutputError, match=r"belongs to another user \(uid \d+\)"):
        check_output_place(others_folder, ("a",))


def test_the_writable_place_is_the_nearest_existing_folder(tmp_path):
    from nlo_lab.atomic_files import writable_place
    from nlo_lab.errors import OutputError

    assert writable_place(tmp_path / "new" / "deeper" / "out", "out") == tmp_path
    (tmp_path / "a-file").write_text("x")
    with pytest.raises(OutputError, match=f"^out lies below {tmp_path / 'a-file'}, which is not a folder$"):
        writable_place(tmp_path / "a-file" / "below", "out")
    if os.geteuid() != 0:  # root writes anywhere
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o555)
        with pytest.raises(OutputError, match=f"^out: no permission to write in {locked}$"):
            writable_place(locked / "new", "out")

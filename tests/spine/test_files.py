"""Every input is a regular file of bounded size, checked before it is opened (nlo_lab.files).

A FIFO given as a recording used to hang forever, a symlink to /dev/zero read without end, a
sparse robot spec of gigabytes was read whole. Each case here goes through the public reader
a user calls and must end, quickly, in that reader's own error class with one message naming
the file and what is wrong with it.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import targets  # tests/fuzz/targets.py: the special files and the deadline

from nlo_lab.errors import CheckpointError, DemonstrationError, NloLabError, RobotDescriptionError, SettingsError, SettingsTypeError
from nlo_lab.files import InputFileError, as_path, check_input_file, format_size, open_input, read_input_bytes
from nlo_lab.human import load_demonstration
from nlo_lab.inference import RobotTrajectory, TrajectoryError
from nlo_lab.model import load_checkpoint
from nlo_lab.paths import CHECKPOINTS_DIR, ROBOTS_DIR
from nlo_lab.robot import load_robot


def make_special(kind: str, path: Path) -> Path:
    return targets.make_special({"sparse": "sparse-64-gib"}.get(kind, kind), path)


KINDS = {
    "fifo": "a FIFO (named pipe)",
    "dev-zero": "a character device (behind a symbolic link)",
    "socket": "a socket",
    "folder": "is a folder",
    "dangling": "a symbolic link to a file that does not exist",
    "sparse": "64.0 GiB, more than",
    "empty": "the file is empty",
}


def _robot_spec_with_urdf(folder: Path, urdf_kind: str) -> Path:
    """A copy of NAO's spec whose URDF is a special file."""
    spec = json.loads((ROBOTS_DIR / "nao.json").read_text())
    spec["urdf"] = "special.urdf"
    path = folder / "nao_copy.json"
    path.write_text(json.dumps(spec))
    make_special(urdf_kind, folder / "special.urdf")
    return path


READERS = {
    ".pose recording": (".pose", load_demonstration, DemonstrationError),
    ".npz demonstration": (".npz", load_demonstration, DemonstrationError),
    ".h5 recording": (".h5", load_demonstration, DemonstrationError),
    "video": (".mp4", load_demonstration, DemonstrationError),
    "robot spec": (".json", load_robot, RobotDescriptionError),
    "checkpoint": (".pt", lambda p: load_checkpoint(p, "nao"), CheckpointError),
    "trajectory .npz": (".npz", RobotTrajectory.load, TrajectoryError),
    "trajectory .json": (".json", RobotTrajectory.load, TrajectoryError),
}


@pytest.mark.parametrize("kind", sorted(KINDS))
@pytest.mark.parametrize("reader", sorted(READERS))
def test_every_reader_refuses_what_is_not_a_bounded_regular_file(reader, kind, tmp_path):
    suffix, load, error = READERS[reader]
    path = make_special(kind, tmp_path / f"input{suffix}")
    with targets.deadline(), pytest.raises(error) as err:
        load(path)
    message = str(err.value)
    assert KINDS[kind] in message and "input" + suffix in message, message
    assert len(message.splitlines()) == 1


@pytest.mark.parametrize("kind", ["fifo", "dev-zero", "sparse"])
def test_a_urdf_that_is_not_a_bounded_regular_file(kind, tmp_path):
    spec = _robot_spec_with_urdf(tmp_path, kind)
    with targets.deadline(), pytest.raises(RobotDescriptionError, match=KINDS[kind].split(" (")[0]) as err:
        load_robot(spec)
    assert "special.urdf" in str(err.value)


def test_a_fifo_swapped_in_after_the_check_does_not_block(tmp_path, monkeypatch):
    """The check stats the path; open_input opens without blocking and checks the opened file again."""
    path = tmp_path / "x.pose"
    path.write_bytes(b"data")
    import nlo_lab.files as files

    real = files.check_input_file

    def check_then_swap(p, **kw):
        size = real(p, **kw)
        os.unlink(p)
        os.mkfifo(p)
        return size

    monkeypatch.setattr(files, "check_input_file", check_then_swap)
    with targets.deadline(), pytest.raises(InputFileError, match="FIFO"):
        read_input_bytes(path, kind=".pose", max_bytes=100)


def test_read_input_bytes_never_reads_beyond_the_limit(tmp_path, monkeypatch):
    """A file that grows after the check is cut at the limit and refused, not read to its end."""
    path = tmp_path / "g.json"
    path.write_bytes(b"x" * 10)
    import nlo_lab.files as files

    real = files.check_input_file

    def check_then_grow(p, **kw):
        size = real(p, **kw)
        with open(p, "ab") as f:
            f.write(b"y" * 1000)
        return size

    monkeypatch.setattr(files, "check_input_file", check_then_grow)
    monkeypatch.setattr(files, "_check_stat", lambda st, *a: st.st_size)  # the grown file passes the second look
    with pytest.raises(InputFileError, match="grew beyond the 100 bytes"):
        read_input_bytes(path, kind="robot spec", max_bytes=100)


def test_a_regular_file_within_the_limit_is_read(tmp_path):
    path = tmp_path / "ok.bin"
    path.write_bytes(b"abc")
    assert check_input_file(path, kind="test", max_bytes=3) == 3
    assert read_input_bytes(path, kind="test", max_bytes=3) == b"abc"
    with open_input(path, kind="test", max_bytes=3) as f:
        assert f.read() == b"abc"
    link = tmp_path / "link.bin"
    link.symlink_to(path)  # a link to a regular file is that file
    assert read_input_bytes(link, kind="test", max_bytes=3) == b"abc"
    with pytest.raises(InputFileError, match=r"3 bytes, more than the 2 bytes a test file may be \(file .*ok.bin\)"):
        check_input_file(path, kind="test", max_bytes=2)


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads every file")
def test_a_file_without_read_permission(tmp_path):
    path = tmp_path / "secret.pose"
    path.write_bytes(b"x")
    path.chmod(0)
    with pytest.raises(DemonstrationError, match="no permission to read"):
        load_demonstration(path)


def test_a_path_below_a_file(tmp_path):
    (tmp_path / "f").write_bytes(b"x")
    with pytest.raises(DemonstrationError, match="a part of the path is a file"):
        load_demonstration(tmp_path / "f" / "x.pose")


@pytest.mark.parametrize("value, error, match", [
    (5, SettingsTypeError, "must be a file path .* got int"),
    (None, SettingsTypeError, "got NoneType"),
    (b"x.pose", SettingsTypeError, "got bytes"),
    ("", SettingsError, "is empty"),
    ("a\x00b.pose", SettingsError, "NUL"),
])
def test_a_path_argument_that_is_no_path(value, error, match):
    with pytest.raises(error, match=match):
        as_path(value)
    with pytest.raises(error, match=match):
        load_demonstration(value)


def test_error_classes_are_also_the_builtin_ones():
    """An ``except ValueError`` (or TypeError, OSError, LookupError) written before nlo_lab had its own classes still works."""
    from nlo_lab.errors import OutputError, UnknownRobotError

    assert issubclass(DemonstrationError, ValueError) and issubclass(RobotDescriptionError, ValueError)
    assert issubclass(CheckpointError, ValueError) and issubclass(TrajectoryError, ValueError)
    assert issubclass(SettingsTypeError, TypeError) and issubclass(SettingsTypeError, SettingsError)
    assert issubclass(OutputError, OSError) and issubclass(UnknownRobotError, LookupError)
    for cls in (DemonstrationError, RobotDescriptionError, CheckpointError, TrajectoryError, SettingsTypeError, OutputError, InputFileError):
        assert issubclass(cls, NloLabError)
    err = DemonstrationError("NaN", path="x.npz", frame=3, field="fps")
    assert str(err) == "NaN (file x.npz, frame 3, field fps)" and (err.path, err.frame, err.field) == ("x.npz", 3, "fps")
    with pytest.raises(ValueError, match="no such file"):
        load_demonstration("/nonexistent/x.npz")
    with pytest.raises(LookupError, match="unknown robot"):
        load_robot("no_such_robot")


def test_format_size():
    assert [format_size(n) for n in (0, 1023, 1024, 1536, 5 << 30)] == ["0 bytes", "1023 bytes", "1.0 KiB", "1.5 KiB", "5.0 GiB"]


def test_a_compressed_checkpoint_record_is_refused(tmp_path):
    """torch.save never compresses; a deflated record could inflate to any size, so it is refused before torch reads it."""
    import zipfile

    src = zipfile.ZipFile(CHECKPOINTS_DIR / "nao.pt")
    bomb = tmp_path / "deflated.pt"
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as z:
        for info in src.infolist():
            z.writestr(info.filename, src.read(info.filename))
    with pytest.raises(CheckpointError, match="compressed, which torch.save never does"):
        load_checkpoint(bomb, "nao")
    shutil.copy(CHECKPOINTS_DIR / "nao.pt", tmp_path / "nao.pt")
    assert load_checkpoint(tmp_path / "nao.pt", "nao") is not None


def test_a_huge_robot_spec_is_refused_unread(tmp_path):
    spec = tmp_path / "big.json"
    spec.write_text("{" + " " * (2 << 20) + "}")
    with pytest.raises(RobotDescriptionError, match=r"2.0 MiB, more than the 1.0 MiB a robot spec file may be"):
        load_robot(spec)


def test_trajectory_npz_reads_only_its_members(tmp_path):
    """An unknown member of 4 GiB declared (a few kB on disk) is never inflated."""
    import zipfile

    traj = RobotTrajectory("nao", ("a", "b"), np.zeros((3, 2)), 10.0)
    path = traj.save_npz(tmp_path / "t.npz")
    header = np.lib.format.header_data_from_array_1_0(np.zeros(1))
    header["shape"] = (1 << 29,)  # 4 GiB of float64
    with zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED) as z, z.open("extra.npy", "w", force_zip64=True) as f:
        np.lib.format.write_array_header_1_0(f, header)
        chunk = bytes(1 << 20)
        for _ in range(64):  # 64 MiB of zeros, deflated to 64 kB; enough to show it is never read
            f.write(chunk)
    back = RobotTrajectory.load(path)
    assert back.joint_names == ("a", "b") and back.angles.shape == (3, 2)
    with zipfile.ZipFile(path, "a") as z:
        z.writestr("angles.npy", b"\x93NUMPY\x01\x00" + b"\xff\xff")  # a second angles member with a huge header
    with pytest.raises(TrajectoryError, match="angles"):
        RobotTrajectory.load(path)

"""Issue 25, items 1, 3 and 5 on the command line: every output place is checked before any input is
read, and every error line names the file and what is wrong with it.

Each case runs ``nlo-lab`` in process the way a user does and asserts exit status 2, one stderr line
holding the file's name and the reason, no traceback, nothing written; "before any input is read" is
asserted by making every reader fail loudly if it is reached.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

import numpy as np
import pytest

from nlo_lab.cli import main


def _run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _one_line(code, out, err, *needles):
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and out == "", (code, out, err)
    assert len(lines) == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


@pytest.fixture
def no_input_read(monkeypatch):
    """Every way an input or a robot is read now fails the test: the refusal must come first."""

    def reached(*args, **kwargs):
        raise AssertionError("an input was read before the output place was refused")

    import nlo_lab.cli.retarget as retarget_command
    import nlo_lab.robot

    monkeypatch.setattr(retarget_command, "_load_input", reached)
    monkeypatch.setattr(retarget_command, "_load_video", reached)
    monkeypatch.setattr(nlo_lab.robot, "load_robot", reached)


def _npz_with(path: Path, demo_npz: Path, **override) -> Path:
    with np.load(demo_npz, allow_pickle=False) as data:
        content = {k: data[k] for k in data.files}
    content.update(override)
    with open(path, "wb") as f:
        np.savez(f, **content)
    return path


# ----------------------------------------------------------------------------- output places, before any input
def test_an_empty_out_is_an_error_before_any_input(work, demo_npz, capsys, no_input_read):
    _one_line(*_run(["retarget", demo_npz, "--robot", "nao", "--out", ""], capsys), "non-empty path")
    assert sorted(os.listdir(work)) == ["demo.npz"]


def test_train_refuses_an_empty_or_unwritable_out_before_the_robot_is_read(work, capsys, no_input_read, monkeypatch):
    import nlo_lab.training

    monkeypatch.setattr(nlo_lab.training, "train_model", lambda *a, **k: pytest.fail("training started"))
    _one_line(*_run(["train", "--robot", "nao", "--out", ""], capsys), "--out", "non-empty file path")
    (work / "folder.pt").mkdir()
    _one_line(*_run(["train", "--robot", "nao", "--out", "folder.pt"], capsys), "folder.pt", "not a plain file")
    (work / "a-file").write_text("x")
    _one_line(*_run(["train", "--robot", "nao", "--out", "a-file/m.pt"], capsys), "a-file", "not a folder")


@pytest.mark.parametrize("empty", ["", "  "])
def test_lab_refuses_an_empty_dir_instead_of_using_the_default(empty, work, capsys, monkeypatch):
    import nlo_lab.lab

    monkeypatch.setenv("NLO_LAB_NOTEBOOKS", str(work / "default"))
    monkeypatch.setattr(nlo_lab.lab, "copy_notebooks", lambda folder: pytest.fail(f"notebooks copied to {folder}"))
    _one_line(*_run(["lab", "--copy-only", "--dir", empty], capsys), "--dir must be a folder path")
    assert not (work / "default").exists()


def test_save_pose_is_checked_before_the_video_is_read(work, capsys, no_input_read):
    (work / "clip.mp4").write_bytes(b"\x00" * 64)  # never opened: the refusal comes first
    _one_line(*_run(["retarget", "clip.mp4", "--robot", "nao", "--save-pose", "landmarks.txt"], capsys),
              "--save-pose", "landmarks.txt", "must end in .pose")
    _one_line(*_run(["retarget", "clip.mp4", "--robot", "nao", "--save-pose", "missing/landmarks.pose"], capsys),
              "--save-pose", "the folder missing does not exist")
    os.mkfifo(work / "fifo.pose")
    _one_line(*_run(["retarget", "clip.mp4", "--robot", "nao", "--save-pose", "fifo.pose"], capsys),
              "fifo.pose", "not a plain file")


def test_an_output_folder_of_another_user_is_refused_before_any_input(work, demo_npz, capsys, no_input_read, others_folder):
    """The issue's case: a folder someone else owns (root's mode 555 folder replaced by a non-owner)."""
    _one_line(*_run(["retarget", demo_npz, "--robot", "nao", "--out", others_folder], capsys),
              str(others_folder), "belongs to another user")


def test_a_save_pose_file_of_another_user_is_not_replaced(work, capsys, no_input_read):
    (work / "clip.mp4").write_bytes(b"\x00" * 64)
    theirs = work / "theirs.pose"
    theirs.write_bytes(b"their landmarks")
    if os.geteuid() == 0:
        os.chown(theirs, 65534, 65534)
    else:
        pytest.skip("making a file of another user needs root")
    _one_line(*_run(["retarget", "clip.mp4", "--robot", "nao", "--save-pose", theirs], capsys),
              "theirs.pose", "belongs to another user")
    assert theirs.read_bytes() == b"their landmarks"


# ----------------------------------------------------------------------------- error lines name the file
def test_a_fully_masked_arm_names_the_file(work, demo_npz, capsys):
    with np.load(demo_npz) as data:
        mask = data["arm_mask"].copy()
    mask[:, 1, 2] = False  # the right wrist is never seen: the arm is never whole
    path = _npz_with(work / "no-right-wrist.npz", demo_npz, arm_mask=mask)
    _one_line(*_run(["retarget", path, "--robot", "nao"], capsys), "no-right-wrist.npz", "right arm is never fully observed")


def test_a_nan_loss_names_the_file(work, demo_npz, capsys, nan_loss):
    line = _one_line(*_run(["retarget", demo_npz, "--robot", "nao", "--iters", "1", "--out", "out"], capsys),
                     "demo.npz", "the loss became NaN or infinite")
    assert "(file " in line and line.index("demo.npz") > line.index("(file ")
    assert not (work / "out").exists()


def test_save_pose_on_a_full_disk_names_the_pose_file(work, demo_npz, capsys, monkeypatch):
    """The pose estimation is replaced by the demonstration of ``demo.npz`` (MediaPipe is not what is tested):
    the landmarks' write meets a full disk; the line names the .pose file, nothing is left."""
    import nlo_lab.cli.retarget as retarget_command
    from nlo_lab.human import load_demonstration

    class Landmarks:
        seconds = 0.1

        def to_bytes(self):
            return b"landmarks"

    monkeypatch.setattr(retarget_command, "_load_video", lambda args, progress: (load_demonstration(demo_npz), Landmarks()))

    def full(self, data):
        with open(self, "wb") as f:  # a part lands, then the disk is full
            f.write(data[:4])
        raise OSError(errno.ENOSPC, "No space left on device", str(self))

    (work / "clip.mp4").write_bytes(b"\x00" * 64)
    monkeypatch.setattr(Path, "write_bytes", full)
    _one_line(*_run(["retarget", "clip.mp4", "--robot", "nao", "--iters", "0", "--save-pose", "landmarks.pose"], capsys),
              "landmarks.pose", "No space left on device")
    assert sorted(os.listdir(work)) == ["clip.mp4", "demo.npz"]

"""Fault injection: crafted files, hostile flags, bad output places, signals, concurrency.

Every case runs the real command line (in process, or as a child process where a
signal or a second process is involved) and asserts the exit status, exactly one
stderr line naming the problem, no traceback, and that nothing was left behind:
the folder the test works in is byte for byte as before (or holds exactly the
complete new set). Crafted files are made here, never committed as blobs.
"""

from __future__ import annotations

import errno
import io
import json
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch

from nlo_lab import cli
from nlo_lab.atomic_files import TEMP_TAG
from nlo_lab.cli import OUTPUT_FILES, main
from nlo_lab.cli import retarget as retarget_command
from nlo_lab.errors import CheckpointError, DemonstrationError, SettingsError
from nlo_lab.human import save_npz
from nlo_lab.pipeline import retarget
from nlo_lab.robot import load_robot

REPO = Path(__file__).resolve().parents[2]


# ----------------------------------------------------------------------------- helpers
def tree(folder: Path) -> list[tuple[str, int, int]]:
    """Every entry below ``folder`` with size and mtime: equal lists mean nothing changed."""
    out = []
    for root, dirs, files in os.walk(folder):
        for name in sorted(dirs + files):
            p = Path(root) / name
            st = p.lstat()
            out.append((str(p.relative_to(folder)), st.st_size if p.is_file() else -1, st.st_mtime_ns))
    return sorted(out)


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_clean_failure(code, err, *needles, status=2):
    lines = err.splitlines()
    assert code == status, (code, err)
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert lines[0].startswith("nlo-lab: "), lines[0]
    assert all(ch.isprintable() for ch in lines[0]), repr(lines[0])
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])


def fails_cleanly(capsys, workdir: Path, argv, *needles):
    """Run ``nlo-lab argv``; assert one clean error line and that ``workdir`` is unchanged."""
    before = tree(workdir)
    code, out, err = run(argv, capsys)
    assert_clean_failure(code, err, *needles)
    assert out == ""
    assert tree(workdir) == before
    return err


@pytest.fixture(scope="session")
def npz_with(make_demo):
    def build(path: Path, **override) -> Path:
        """A valid archive of a small demonstration with some entries replaced (None removes one)."""
        good = save_npz(make_demo(T=6), path.with_name("good-" + path.name))
        with np.load(good, allow_pickle=False) as data:
            content = {k: data[k] for k in data.files}
        good.unlink()
        content.update(override)
        content = {k: v for k, v in content.items() if v is not None}
        with open(path, "wb") as f:
            np.savez(f, **content)
        return path

    return build


# ----------------------------------------------------------------------------- crafted .npz
NPZ_CASES = {
    "fps is text": ({"fps": np.array("25")}, "fps"),
    "fps 1e300": ({"fps": np.array(1e300)}, "fps"),
    "fps 3e38": ({"fps": np.array(3e38)}, "fps"),
    "fps 1e-30": ({"fps": np.array(1e-30)}, "fps"),
    "fps complex": ({"fps": np.array(25 + 1j)}, "fps"),
    "fps True": ({"fps": np.array(True)}, "fps"),
    "fps NaN": ({"fps": np.array(np.nan)}, "fps"),
    "arm_positions text": ({"arm_positions": np.array("abc")}, "arm_positions"),
    "arm_positions complex": ({"arm_positions": np.ones((6, 2, 3, 3), complex)}, "arm_positions"),
    "format_version text": ({"format_version": np.array("abc")}, "format_version"),
    "format_version list": ({"format_version": np.array([1, 1])}, "format_version"),
    "meta nested 100000 deep": ({"meta_json": np.array('{"a": ' + "[" * 100_000 + "]" * 100_000 + "}")}, "meta_json"),
    "meta nested 100 deep": ({"meta_json": np.array('{"a": ' + "[" * 100 + "]" * 100 + "}")}, "meta_json"),
    "meta a list": ({"meta_json": np.array("[1]")}, "meta_json"),
    "name a number": ({"name": np.array(3.0)}, "name"),
    "wrist mask text": ({"wrist_mask": np.full((6, 2), "x")}, "wrist_mask"),
    "missing fps": ({"fps": None}, "fps"),
}


@pytest.mark.parametrize("case", sorted(NPZ_CASES))
def test_crafted_npz(case, work, capsys, npz_with):
    override, needle = NPZ_CASES[case]
    path = npz_with(work / "crafted.npz", **override)
    fails_cleanly(capsys, work, ["retarget", path, "--robot", "yumi", "--out", "out"], "crafted.npz", needle)


def test_npy_renamed_to_npz(work, capsys):
    np.save(work / "x.npy", np.zeros((6, 2, 3, 3)))
    os.rename(work / "x.npy", work / "x.npz")
    fails_cleanly(capsys, work, ["retarget", "x.npz", "--robot", "yumi"], "x.npz", "not a readable .npz")


def test_pickle_in_npz_is_refused_and_never_runs(work, capsys, npz_with):
    marker = work / "ran"

    class Evil:
        def __reduce__(self):
            return (os.mkdir, (str(marker),))

    path = npz_with(work / "evil.npz", name=np.array([Evil()], dtype=object))
    fails_cleanly(capsys, work, ["retarget", path, "--robot", "yumi"], "evil.npz", "pickles")
    assert not marker.exists()


def _raw_npy_member(zf: zipfile.ZipFile, name: str, shape, payload: bytes = b"") -> None:
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": shape})
    zf.writestr(name + ".npy", header.getvalue() + payload)


def test_npz_declaring_a_huge_array_is_refused_before_reading(work, capsys, npz_with):
    path = npz_with(work / "huge.npz", arm_positions=None)
    with zipfile.ZipFile(path, "a") as zf:  # 10^9 frames declared, none stored
        _raw_npy_member(zf, "arm_positions", (10**9, 2, 3, 3))
    assert path.stat().st_size < 100_000
    fails_cleanly(capsys, work, ["retarget", path, "--robot", "yumi"], "huge.npz", "arm_positions", "declares")


def test_unknown_npz_members_are_skipped_unread(work, npz_with):
    path = npz_with(work / "extra.npz")
    with zipfile.ZipFile(path, "a") as zf:
        _raw_npy_member(zf, "unused", (2 * 10**9 // 8,))  # "2 GB", never stored: reading it would fail
        zf.writestr("garbage.npy", b"not an array at all")
    from nlo_lab.human import load_demonstration

    assert len(load_demonstration(path)) == 6


# ----------------------------------------------------------------------------- crafted .h5
def test_h5_dangling_link_at_the_root(work, capsys, write_authors_h5):
    write_authors_h5(work / "d.h5", groups=("a",))
    with h5py.File(work / "d.h5", "a") as f:
        f["0_first"] = h5py.SoftLink("/nowhere")
        f["a"]["l_up_pos_link"] = h5py.SoftLink("/nowhere")
        del f["a"]["l_fr_pos"]
        f["a"]["l_fr_pos"] = h5py.SoftLink("/nowhere")
    fails_cleanly(capsys, work, ["retarget", "d.h5", "--robot", "yumi"], "d.h5", "a/l_fr_pos", "leads nowhere")


def test_h5_external_link_at_the_root(work, capsys, write_authors_h5):
    write_authors_h5(work / "e.h5", groups=("b",))
    with h5py.File(work / "e.h5", "a") as f:
        f["a"] = h5py.ExternalLink("/etc/passwd", "/x")
        del f["b"]["r_hd_pos"]
        f["b"]["r_hd_pos"] = h5py.ExternalLink("other.h5", "/r_hd_pos")
    fails_cleanly(capsys, work, ["retarget", "e.h5", "--robot", "yumi"], "e.h5", "b/r_hd_pos", "external")


@pytest.mark.parametrize("fps", [1e300, 3e38, 1e-30, -5.0, 0.0])
def test_h5_fps_out_of_range(fps, work, capsys, write_authors_h5):
    write_authors_h5(work / "f.h5", groups=("a",), fps=fps)
    fails_cleanly(capsys, work, ["retarget", "f.h5", "--robot", "yumi"], "f.h5", "fps", "[1, 1000]")


def test_h5_complex_dataset_is_refused(work, capsys, write_authors_h5):
    write_authors_h5(work / "c.h5", groups=("a",))
    with h5py.File(work / "c.h5", "a") as f:
        value = f["a"]["l_hd_pos"][()] * (1 + 1j)
        del f["a"]["l_hd_pos"]
        f["a"]["l_hd_pos"] = value
    fails_cleanly(capsys, work, ["retarget", "c.h5", "--robot", "yumi"], "c.h5", "a/l_hd_pos", "complex")


def test_h5_declaring_500m_rows_is_refused_before_reading(work, capsys, write_authors_h5):
    write_authors_h5(work / "big.h5", groups=("a",))
    with h5py.File(work / "big.h5", "a") as f:
        del f["a"]["l_up_pos"]
        f["a"].create_dataset("l_up_pos", shape=(500_000_000, 3), dtype="f8", chunks=(1024, 3))  # nothing stored
    assert (work / "big.h5").stat().st_size < 200_000
    fails_cleanly(capsys, work, ["retarget", "big.h5", "--robot", "yumi"], "big.h5", "a/l_up_pos", "500000000 frames")


def test_h5_group_names_are_escaped(work, capsys, write_authors_h5):
    evil = "a\n\x1b[31mnlo-lab: fake line\x07"
    write_authors_h5(work / "n.h5", groups=(evil,))
    with h5py.File(work / "n.h5", "a") as f:
        del f[evil]["l_up_pos"]
    err = fails_cleanly(capsys, work, ["retarget", "n.h5", "--robot", "yumi"], "n.h5", "\\n\\x1b[31mnlo-lab: fake line\\x07/l_up_pos")
    assert "\x1b" not in err and "\x07" not in err


# ----------------------------------------------------------------------------- crafted .pose
def test_pose_with_all_world_landmarks_at_zero(work, capsys, pose_files):
    overrides = {(t, 8 + 21 + 21 + p): 0.0 for t in range(40) for p in range(8)}  # the world component
    pose_files.write(work / "z.pose", data_overrides=overrides)
    fails_cleanly(capsys, work, ["retarget", "z.pose", "--robot", "yumi"], "z.pose", "POSE_WORLD_LANDMARKS")


def test_pose_point_names_and_file_names_are_escaped(work, capsys, pose_files):
    name = "evil\n\x1b]0;title\x07.pose"
    pose_files.write(work / name, data_overrides={(3, 0): np.nan})  # NaN in an observed landmark names the point
    err = fails_cleanly(capsys, work, ["retarget", name, "--robot", "yumi"], "evil\\n\\x1b]0;title\\x07.pose")
    assert "\x1b" not in err


def _body_counts_offset(path: Path) -> int:
    """Where a v0.2 file's body counts (fps float32, frames uint32, people uint16) start."""
    from pose_format.pose_header import PoseHeader
    from pose_format.utils.reader import BufferReader

    reader = BufferReader(path.read_bytes())
    PoseHeader.read(reader)
    return reader.read_offset


@pytest.fixture(scope="session")
def crafted_pose(pose_files):
    def build(work: Path, frames: int | None = None, people: int | None = None, extra: bytes = b"") -> Path:
        """A valid small .pose whose body counts are then overwritten (the data stays a few kB)."""
        import struct

        path = work / "huge.pose"
        pose_files.write(path, T=10)
        data = bytearray(path.read_bytes())
        at = _body_counts_offset(path)
        _fps, old_frames, old_people = struct.unpack_from("<fIH", data, at)
        struct.pack_into("<fIH", data, at, _fps, old_frames if frames is None else frames, old_people if people is None else people)
        path.write_bytes(bytes(data) + extra)
        return path

    return build


@pytest.mark.parametrize("frames, people, needle", [
    (4_000_000_000, None, "4000000000 frames"),  # more than MAX_FRAMES: refused on the count alone
    (400_000, None, "400000 frames x 1 people"),  # within MAX_FRAMES, but the file holds 10 frames
    (None, 65_535, "65535 people"),
    (None, 2, "10 frames x 2 people"),
])
def test_pose_declaring_a_huge_body_is_refused_before_reading(frames, people, needle, work, capsys, monkeypatch, crafted_pose):
    import pose_format

    path = crafted_pose(work, frames, people)
    assert path.stat().st_size < 20_000
    monkeypatch.setattr(pose_format.Pose, "read", lambda *a, **k: pytest.fail("the body was read"))
    fails_cleanly(capsys, work, ["retarget", path.name, "--robot", "yumi"], "huge.pose", needle)


def test_pose_with_bytes_after_its_body_is_refused(work, capsys, crafted_pose):
    path = crafted_pose(work, extra=b"\0" * 64)
    fails_cleanly(capsys, work, ["retarget", path.name, "--robot", "yumi"], "huge.pose", "file holds")


def test_pose_size_check_passes_a_valid_file(work, crafted_pose):
    from nlo_lab.human import load_demonstration

    assert len(load_demonstration(crafted_pose(work))) == 10  # the counts rewritten unchanged


def test_truncated_pose(work, capsys, pose_files):
    pose_files.write(work / "t.pose")
    data = (work / "t.pose").read_bytes()
    (work / "t.pose").write_bytes(data[: len(data) // 3])
    fails_cleanly(capsys, work, ["retarget", "t.pose", "--robot", "yumi"], "t.pose")


# ----------------------------------------------------------------------------- robot specs, checkpoints
def _spec(work: Path, **change) -> Path:
    spec = json.loads((REPO / "assets/robots/yumi.json").read_text())
    spec.update(change)
    spec["urdf"] = str((REPO / "assets/robots" / spec["urdf"]).resolve())
    path = work / "robot.json"
    path.write_text(json.dumps(spec))
    return path


def test_binary_robot_spec(work, capsys):
    (work / "robot.json").write_bytes(bytes(range(256)) * 4)
    fails_cleanly(capsys, work, ["retarget", "demo:introduction_06", "--robot", "robot.json"], "robot.json", "not a text file")


@pytest.mark.parametrize("margin", ["abc", [1, 2], {"default": "x"}, True])
def test_robot_spec_with_a_bad_margin(margin, work, capsys):
    _spec(work, collision_margin=margin)
    fails_cleanly(capsys, work, ["retarget", "demo:introduction_06", "--robot", "robot.json"], "robot.json", "collision_margin")


def test_checkpoint_with_numeric_joint_names(tmp_path):
    from nlo_lab.model import checkpoint_path, load_checkpoint

    ckpt = torch.load(checkpoint_path("nao"), map_location="cpu", weights_only=True)
    ckpt["joint_names"] = 7
    torch.save(ckpt, tmp_path / "bad.pt")
    with pytest.raises(CheckpointError, match="bad.pt"):
        load_checkpoint(tmp_path / "bad.pt", "nao")


# ----------------------------------------------------------------------------- hostile flags
FLAG_CASES = {
    "seed with 30 digits": (["--seed", "1" * 30], "--seed"),
    "negative seed": (["--seed", "-1"], "--seed"),
    "iters not a number": (["--iters", "1e9"], "--iters"),
    "negative iters": (["--iters", "-3"], "--iters"),
    "iters 10**12": (["--iters", str(10**12)], "--iters"),
    "iters just past the range": (["--iters", str(cli.ITERS_RANGE[1] + 1)], "--iters"),
    "iters with 100000 digits": (["--iters", "9" * 100_000], "--iters"),
    "threads 0": (["--threads", "0"], "--threads"),
    "threads 10**6": (["--threads", str(10**6)], "--threads"),
    "weights 1e39": (["--weights", "ee=1e39"], "weight ee"),
    "weights infinite": (["--weights", "collision=inf"], "collision"),
    "weights past the range": (["--weights", f"smooth={cli.WEIGHT_RANGE[1] * 2:g}"], "smooth"),
    "unknown init": (["--init", "bogus"], "--init"),
    "weights garbage": (["--weights", "ee=,,=3"], "weight ee"),
    "weights unknown term": (["--weights", "nope=1"], "nope"),
    "weights negative": (["--weights", "ee=-1"], "ee"),
    "weights NaN": (["--weights", "ee=nan"], "ee"),
    "hand-search unknown finger": (["--hand-search", "ring,toe"], "toe"),
    "hand-search empty": (["--hand-search", ","], "--hand-search"),
    "hand-search a finger twice": (["--hand-search", "ring,middle,ring"], "ring named more than once"),
    "unknown robot": (["--robot", "r2d2"], "r2d2"),
    "robot name with escapes": (["--robot", "x\x1b[2J\ny"], "x\\x1b[2J\\ny"),
}


@pytest.mark.parametrize("case", sorted(FLAG_CASES))
def test_hostile_flags(case, work, capsys):
    extra, needle = FLAG_CASES[case]
    argv = ["retarget", "demo:introduction_06", "--robot", "yumi", "--out", "out"] + extra
    fails_cleanly(capsys, work, argv, needle)


def test_port_out_of_range(work, capsys):
    fails_cleanly(capsys, work, ["lab", "--port", "99999"], "--port")


@pytest.mark.parametrize("argv, needle", [
    (["train", "--robot", "nao", "--epochs", "0"], "--epochs"),
    (["train", "--robot", "nao", "--epochs", str(10**12)], "--epochs"),
    (["evaluate", "--robot", "nao", "--limit", "0"], "--limit"),
    (["evaluate", "--robot", "nao", "--limit", "-5"], "--limit"),
    (["lab", "--port", "0"], "--port"),
])
def test_numeric_flags_of_the_other_commands_are_bounded(argv, needle, work, capsys):
    err = fails_cleanly(capsys, work, argv, needle)
    assert "in [" in err  # the range is stated


def test_flag_ranges_are_stated_in_help():
    helps = {a.dest: a.help for a in cli.build_parser()._subparsers._group_actions[0].choices["retarget"]._actions}
    assert f"{cli.ITERS_RANGE[0]}..{cli.ITERS_RANGE[1]}" in helps["iters"]
    assert f"{cli.WEIGHT_RANGE[1]:g}" in helps["weights"]


def test_the_largest_weights_in_range_still_give_a_finite_result(work, demo_npz, capsys):
    top = cli.WEIGHT_RANGE[1]
    weights = ",".join(f"{k}={top:g}" for k in ("ee", "ori", "elbow", "finger", "collision", "latent", "smooth"))
    code, out, err = run(["retarget", demo_npz, "--robot", "nao", "--iters", "2", "--weights", weights, "--json"], capsys)
    assert code == 0, err
    assert json.loads(out)["frames"] == 12


def test_weights_that_would_make_the_loss_nan_are_refused():
    """LossWeights(ee=1e39) made the loss NaN (issue 16); the weights now share the command line's range.
    A NaN loss that still happens is an error naming the file (tests/spine/test_errors.py)."""
    from nlo_lab.objective import LossWeights

    with pytest.raises(SettingsError, match=r"loss weight ee must be in \[0, 1e\+06\], got 1e\+39"):
        LossWeights(ee=1e39)


def test_retarget_rechecks_the_demonstration(make_demo):
    robot = load_robot("nao")
    demo = make_demo(T=5)
    demo.wrist_rotations[2, 0] = np.nan  # after construction
    with pytest.raises(DemonstrationError, match="frame 2"):
        retarget(demo, robot)
    demo = make_demo(T=5)
    demo.wrist_rotations[3, 1] *= 2.0  # not a rotation any more
    with pytest.raises(DemonstrationError, match="not a rotation"):
        retarget(demo, robot)
    with pytest.raises(SettingsError, match="chunk_frames"):
        retarget(make_demo(T=5), robot, chunk_frames=0)


# ----------------------------------------------------------------------------- output places
def test_out_is_an_existing_file(work, demo_npz, capsys):
    (work / "file").write_text("keep me")
    fails_cleanly(capsys, work, ["retarget", demo_npz, "--robot", "yumi", "--out", "file"], "file", "not a folder")


def test_out_is_the_input_file(work, demo_npz, capsys):
    fails_cleanly(capsys, work, ["retarget", demo_npz, "--robot", "yumi", "--out", demo_npz], "demo.npz", "not a folder")


def test_out_is_dev_null(work, demo_npz, capsys):
    fails_cleanly(capsys, work, ["retarget", demo_npz, "--robot", "yumi", "--out", "/dev/null"], "/dev/null")


def test_out_below_a_file(work, demo_npz, capsys):
    (work / "file").write_text("keep me")
    fails_cleanly(capsys, work, ["retarget", demo_npz, "--robot", "yumi", "--out", "file/sub/out"], "not a folder")


def test_out_is_the_current_folder(work, demo_npz, capsys):
    fails_cleanly(capsys, work, ["retarget", demo_npz, "--robot", "yumi", "--out", "."], "current folder")


@pytest.mark.parametrize("blocker", ["trajectory.csv", "viewer.html", "notes"])
def test_out_with_a_blocking_folder_is_refused_before_work(blocker, work, demo_npz, capsys, monkeypatch):
    out = work / "out"
    out.mkdir()
    (out / "viewer.html").write_text("old") if blocker != "viewer.html" else None
    (out / blocker).mkdir()
    monkeypatch.setattr(retarget_command, "_load_input", lambda text: pytest.fail("work started"))
    fails_cleanly(capsys, work, ["retarget", demo_npz, "--robot", "yumi", "--out", out], blocker)


def test_read_only_place_is_refused_before_work(work, demo_npz, capsys, monkeypatch):
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if Path(p) == work else real(p, mode, **kw))
    fails_cleanly(capsys, work, ["retarget", demo_npz, "--robot", "yumi", "--out", "out"], "no permission", str(work))


def test_permission_error_while_writing(work, demo_npz, capsys, monkeypatch):
    import nlo_lab.inference.trajectory as trajectory

    def denied(self, path):
        raise PermissionError(errno.EACCES, "Permission denied", str(path))

    monkeypatch.setattr(trajectory.RobotTrajectory, "save_csv", denied)
    fails_cleanly(capsys, work, ["retarget", demo_npz, "--robot", "nao", "--iters", "0", "--out", "out"],
                  "Permission denied", "trajectory.csv")


@pytest.mark.parametrize("old_set", [False, True])
def test_full_disk_while_writing_leaves_the_old_set(old_set, work, demo_npz, capsys, monkeypatch):
    import nlo_lab.viz as viz

    out = work / "out"
    if old_set:
        out.mkdir()
        for name in OUTPUT_FILES:
            (out / name).write_text(f"old {name}")
        (out / "notes.txt").write_text("the user's own file")

    def full(path, *args, **kwargs):
        Path(path).write_bytes(b"partial")
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(viz, "export_html", full)
    fails_cleanly(capsys, work, ["retarget", demo_npz, "--robot", "nao", "--iters", "0", "--out", out],
                  "No space left on device", "viewer.html")


def test_memory_error_is_one_line(work, demo_npz, capsys, monkeypatch):
    def oom(*args, **kwargs):
        raise MemoryError()

    monkeypatch.setattr("nlo_lab.pipeline.Retargeter.__call__", oom)
    fails_cleanly(capsys, work, ["retarget", demo_npz, "--robot", "nao", "--out", "out"], "out of memory")


def test_a_bug_still_gives_a_traceback(work, demo_npz, monkeypatch):
    def bug(*args, **kwargs):
        raise ZeroDivisionError("our bug")

    monkeypatch.setattr("nlo_lab.pipeline.Retargeter.__call__", bug)
    with pytest.raises(ZeroDivisionError):  # exit 1 with a traceback, from the interpreter
        main(["retarget", str(demo_npz), "--robot", "nao"])


def test_new_set_replaces_old_and_keeps_other_files(work, demo_npz, capsys):
    out = work / "out"
    out.mkdir()
    for name in OUTPUT_FILES:
        (out / name).write_text("old")
    (out / "notes.txt").write_text("the user's own file")
    code, _, err = run(["retarget", demo_npz, "--robot", "nao", "--iters", "0", "--out", out, "--quiet"], capsys)
    assert code == 0, err
    assert sorted(os.listdir(out)) == sorted(OUTPUT_FILES + ("notes.txt",))
    assert all((out / n).read_bytes() != b"old" for n in OUTPUT_FILES)
    assert (out / "notes.txt").read_text() == "the user's own file"
    assert [p.name for p in work.iterdir() if TEMP_TAG in p.name] == []


def test_stale_temp_folder_of_a_killed_run_is_cleaned(work, demo_npz, capsys):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = work / f".out{TEMP_TAG}{dead.pid}-0123abcd"
    stale.mkdir()
    (stale / "trajectory.npz").write_text("half")
    alive = work / f".out{TEMP_TAG}{os.getpid()}-4567abcd"  # a live writer's (ours): left alone
    alive.mkdir()
    code, _, err = run(["retarget", demo_npz, "--robot", "nao", "--iters", "0", "--out", "out"], capsys)
    assert code == 0, err
    assert not stale.exists() and alive.exists()


# ----------------------------------------------------------------------------- warnings
def test_warnings_are_one_line_each_and_quiet_silences_them(work, demo_npz, capsys, monkeypatch):
    import warnings

    from nlo_lab.pipeline import Retargeter

    real = Retargeter.__call__

    def noisy(*args, **kwargs):
        warnings.warn("first line\nsecond line", UserWarning, stacklevel=1)
        return real(*args, **kwargs)

    monkeypatch.setattr(Retargeter, "__call__", noisy)
    code, _, err = run(["retarget", demo_npz, "--robot", "nao", "--iters", "0", "--json"], capsys)
    assert code == 0
    assert err.splitlines() == ["nlo-lab: warning: first line\\nsecond line"]
    code, _, err = run(["retarget", demo_npz, "--robot", "nao", "--iters", "0", "--json", "--quiet"], capsys)
    assert code == 0 and err == ""


# ----------------------------------------------------------------------------- signals and concurrency (child processes)
_CHILD = """
import os, signal, sys, time
from pathlib import Path
import nlo_lab.viz as viz
from nlo_lab import cli

mode = sys.argv[1]
real = viz.export_html

def export(path, *args, **kwargs):
    real(path, *args, **kwargs)  # the temporary folder exists and holds files
    Path(path).with_name("ready").touch() if mode == "wait" else None
    if mode.startswith("self-"):
        os.kill(os.getpid(), getattr(signal, mode[5:]))
    elif mode == "swallow-SIGINT":  # as a library's `except BaseException: pass` around an import does
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1)
        except BaseException:
            pass
    elif mode == "wait":
        time.sleep(60)

viz.export_html = export
sys.exit(cli.main(sys.argv[2:]))
"""


def _child(mode: str, argv, cwd: Path, **kw) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.Popen([sys.executable, "-c", _CHILD, mode] + [str(a) for a in argv], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def _temp_folders(folder: Path) -> list[Path]:
    return [p for p in folder.iterdir() if TEMP_TAG in p.name]


@pytest.mark.slow
@pytest.mark.parametrize("sig", ["SIGTERM", "SIGINT", "SIGHUP", "swallowed SIGINT"])
def test_signal_while_writing_removes_the_temp_folder(sig, work, demo_npz):
    mode = "swallow-SIGINT" if sig.startswith("swallowed") else f"self-{sig}"
    sig = sig.split()[-1]
    proc = _child(mode, ["retarget", demo_npz, "--robot", "nao", "--iters", "0", "--out", "out"], work)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 128 + getattr(signal, sig), err
    assert_clean_failure(proc.returncode, err, sig, status=128 + getattr(signal, sig))
    assert not (work / "out").exists() and _temp_folders(work) == []


@pytest.mark.slow
@pytest.mark.parametrize("sig", ["SIGTERM", "SIGKILL"])
def test_signal_from_outside_at_the_moment_the_temp_folder_exists(sig, work, demo_npz):
    out = work / "out"
    out.mkdir()
    for name in OUTPUT_FILES:
        (out / name).write_text("old")
    before = tree(out)
    proc = _child("wait", ["retarget", demo_npz, "--robot", "nao", "--iters", "0", "--out", out], work)
    deadline = time.monotonic() + 300
    while not any((t / "ready").exists() for t in _temp_folders(work)):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.05)
    proc.send_signal(getattr(signal, sig))
    _, err = proc.communicate(timeout=60)
    assert tree(out) == before  # the old set, untouched
    if sig == "SIGKILL":
        assert proc.returncode == -signal.SIGKILL
        assert len(_temp_folders(work)) == 1  # nothing can clean up after SIGKILL ...
        proc = _child("none", ["retarget", demo_npz, "--robot", "nao", "--iters", "0", "--out", out], work)
        _, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, err  # ... but the next run into the same place does
    else:
        assert_clean_failure(proc.returncode, err, "SIGTERM", status=128 + signal.SIGTERM)
    assert _temp_folders(work) == []


@pytest.mark.slow
def test_two_runs_into_one_place_each_leave_a_whole_set(work, demo_npz):
    out = work / "out"
    procs = [_child("none", ["retarget", demo_npz, "--robot", "nao", "--iters", str(i), "--out", out], work) for i in (0, 3)]
    for p in procs:
        _, err = p.communicate(timeout=300)
        assert p.returncode == 0, err
    assert sorted(os.listdir(out)) == sorted(OUTPUT_FILES)
    with np.load(out / "trajectory.npz") as data:
        angles = data["angles"]
    csv = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(csv[:, -angles.shape[1]:], angles, atol=1e-6)  # npz and csv from the same run
    assert _temp_folders(work) == []


# ----------------------------------------------------------------------------- the swap without RENAME_EXCHANGE
def _old_set(out: Path) -> None:
    out.mkdir()
    for name in OUTPUT_FILES:
        (out / name).write_text(f"old {name}")
    (out / "notes.txt").write_text("the user's own file")


def test_swap_without_an_atomic_exchange(tmp_path, monkeypatch):
    from nlo_lab import atomic_files

    monkeypatch.setattr(atomic_files, "_exchange", lambda a, b: False)  # an old kernel or a file system without it
    out = tmp_path / "out"
    _old_set(out)
    with atomic_files.output_set(out, OUTPUT_FILES) as tmp:
        for name in OUTPUT_FILES:
            (tmp / name).write_text(f"new {name}")
    assert {p.name: p.read_text() for p in out.iterdir()} == {**{n: f"new {n}" for n in OUTPUT_FILES}, "notes.txt": "the user's own file"}
    assert os.listdir(tmp_path) == ["out"]


def test_failed_swap_puts_the_old_set_back(tmp_path, monkeypatch):
    from nlo_lab import atomic_files

    monkeypatch.setattr(atomic_files, "_exchange", lambda a, b: False)
    out = tmp_path / "out"
    _old_set(out)
    before = tree(tmp_path)
    real, calls, new = os.rename, [], []

    def rename(a, b):
        if new and Path(a) == new[0] and Path(b) == out:
            calls.append(a)
            if len(calls) == 1:  # what the kernel says for a folder onto a non-empty one
                raise OSError(errno.ENOTEMPTY, "Directory not empty", str(b))
            raise OSError(errno.EIO, "Input/output error", str(b))  # the new set cannot move in
        return real(a, b)

    monkeypatch.setattr(os, "rename", rename)
    with pytest.raises(OSError, match="Input/output"):
        with atomic_files.output_set(out, OUTPUT_FILES) as tmp:
            new.append(tmp)
            for name in OUTPUT_FILES:
                (tmp / name).write_text("new")
    assert len(calls) == 2  # the fallback ran: old set aside, new set refused, old set back
    assert [(p, s) for p, s, _ in tree(tmp_path)] == [(p, s) for p, s, _ in before]  # old set back, no temp folder


def test_output_set_lacking_a_file_is_a_bug_and_leaves_nothing(tmp_path):
    from nlo_lab import atomic_files

    with pytest.raises(RuntimeError, match="lacks"):
        with atomic_files.output_set(tmp_path / "out", OUTPUT_FILES) as tmp:
            (tmp / "trajectory.npz").write_text("only one")
    assert os.listdir(tmp_path) == []


def test_read_only_file_system_names_the_place(work, demo_npz, capsys, monkeypatch):
    from nlo_lab import atomic_files

    real = os.mkdir

    def read_only(path, *args, **kwargs):
        if TEMP_TAG in str(path):
            raise OSError(errno.EROFS, "Read-only file system", str(path))
        return real(path, *args, **kwargs)

    monkeypatch.setattr(atomic_files.os, "mkdir", read_only)
    err = fails_cleanly(capsys, work, ["retarget", demo_npz, "--robot", "nao", "--iters", "0", "--out", "out"],
                        "Read-only file system", f"cannot write in {work}")
    assert TEMP_TAG not in err

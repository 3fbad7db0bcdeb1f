"""The command line contract (docs/DESIGN.md, "Command line"): JSON keys, exit codes, files."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from nlo_lab.cli import main

SUMMARY_KEYS = {
    "robot", "frames", "fps", "seconds", "iterations", "frechet_m", "frechet_wrist_m",
    "frechet_elbow_m", "self_collision_frames", "limit_violations",
}


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_bad_flag_is_one_line_exit_2(capsys, assert_one_line_error):
    code, _, err = run(["retarget", "demo:x", "--robot", "nao", "--bogus"], capsys)
    assert_one_line_error(code, err, "--bogus")


def test_bad_iters_is_one_line_exit_2(capsys, assert_one_line_error):
    code, _, err = run(["retarget", "demo:x", "--robot", "nao", "--iters", "many"], capsys)
    assert_one_line_error(code, err, "--iters")


def test_unknown_robot_exit_2(capsys, tmp_path, assert_one_line_error):
    code, _, err = run(["retarget", "demo:x", "--robot", "marvin", "--out", str(tmp_path / "o")], capsys)
    assert_one_line_error(code, err, "marvin")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("flags, needle", [(["--handshape"], "--handshape"), (["--hand-search", "ring"], "--hand-search"),
                                          (["--handshape", "--hand-search", "ring"], "--hand-search")])
def test_a_hand_search_for_a_robot_without_fingers_exit_2(capsys, tmp_path, assert_one_line_error, flags, needle):
    code, _, err = run(["retarget", "demo:introduction_06", "--robot", "pepper", *flags, "--out", str(tmp_path / "o")], capsys)
    assert_one_line_error(code, err, needle, "pepper has no finger joints")
    assert not (tmp_path / "o").exists()


def test_a_hand_slowdown_for_a_robot_without_hands_exit_2(capsys, tmp_path, assert_one_line_error):
    code, _, err = run(["retarget", "demo:introduction_06", "--robot", "nao", "--hand-slowdown", "2", "--out", str(tmp_path / "o")], capsys)
    assert_one_line_error(code, err, "--hand-slowdown", "nao has no hand joints")
    assert not (tmp_path / "o").exists()
    code, _, err = run(["retarget", "demo:introduction_06", "--robot", "nao", "--hand-slowdown", "1", "--iters", "0", "--json",
                        "--quiet"], capsys)
    assert code == 0, err  # 1: the default, nothing asked of the hands


def test_bad_weights_exit_2(capsys, assert_one_line_error):
    code, _, err = run(["retarget", "demo:x", "--robot", "nao", "--weights", "ee=banana"], capsys)
    assert_one_line_error(code, err, "ee")


def test_missing_file_exit_2(capsys, tmp_path, assert_one_line_error):
    missing = tmp_path / "nothing.pose"
    code, _, err = run(["retarget", str(missing), "--robot", "nao", "--out", str(tmp_path / "o")], capsys)
    assert_one_line_error(code, err, "nothing.pose")
    assert not (tmp_path / "o").exists()


def test_corrupt_file_exit_2_nothing_written(capsys, tmp_path, assert_one_line_error):
    bad = tmp_path / "broken.pose"
    bad.write_bytes(b"\x00\x01 this is not a pose file")
    out_dir = tmp_path / "o"
    code, _, err = run(["retarget", str(bad), "--robot", "nao", "--out", str(out_dir)], capsys)
    assert_one_line_error(code, err, "broken.pose")
    assert not out_dir.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["broken.pose"]


def test_nan_in_npz_names_field_exit_2(capsys, tmp_path, assert_one_line_error):
    from nlo_lab.corpus import sign_corpus
    from nlo_lab.human import save_npz

    demo = sign_corpus("test")[0].slice(0, 10)
    path = tmp_path / "clip.npz"
    save_npz(demo, path)
    data = dict(np.load(path, allow_pickle=False))
    data["arm_positions"] = data["arm_positions"].copy()
    data["arm_positions"][4, 1, 2, 0] = np.nan
    np.savez(path, **data)
    code, _, err = run(["retarget", str(path), "--robot", "nao"], capsys)
    assert_one_line_error(code, err, "clip.npz", "frame 4")


def test_unknown_demo_clip_exit_2(capsys, assert_one_line_error):
    code, _, err = run(["retarget", "demo:no_such_clip", "--robot", "nao"], capsys)
    assert_one_line_error(code, err, "no_such_clip")


def test_retarget_json_and_files(capsys, tmp_path):
    from nlo_lab.corpus import corpus_names

    name = corpus_names("test")[0]
    out_dir = tmp_path / "out"
    code, out, err = run(["retarget", f"demo:{name}", "--robot", "nao", "--iters", "5", "--out", str(out_dir), "--json"], capsys)
    assert code == 0, err
    summary = json.loads(out.strip().splitlines()[-1])
    assert SUMMARY_KEYS <= summary.keys()
    assert summary["robot"] == "nao"
    assert summary["iterations"] <= 5
    assert summary["limit_violations"] == 0
    assert summary["frechet_m"] == pytest.approx((summary["frechet_wrist_m"] + summary["frechet_elbow_m"]) / 2, rel=1e-6)
    assert sorted(p.name for p in out_dir.iterdir()) == ["trajectory.csv", "trajectory.npz", "viewer.html"]
    traj = np.load(out_dir / "trajectory.npz")
    assert traj["angles"].shape == (summary["frames"], 10)
    header = (out_dir / "trajectory.csv").read_text().splitlines()[0]
    assert "LShoulderPitch" in header
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary folder left


@pytest.mark.slow
def test_viewer_plays_on_the_trajectory_time_base(capsys, tmp_path):
    """viewer.html shows the motion as the robot would play it: its keys sit at trajectory.npz's `time`."""
    import base64
    import re

    import umsgpack

    out_dir = tmp_path / "out"
    code, out, err = run(["retarget", "demo:introduction_06", "--robot", "yumi", "--iters", "3", "--out", str(out_dir),
                          "--json"], capsys)
    assert code == 0, err
    summary = json.loads(out)
    assert summary["slowdown"] > 1.05, "the clip must be retimed for this test to mean anything"
    with np.load(out_dir / "trajectory.npz") as traj:
        times = traj["time"]
    page = (out_dir / "viewer.html").read_text(encoding="utf-8")
    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", page)]
    clips = [a["clip"] for c in cmds if c["type"] == "set_animation" for a in c["animations"]]
    assert clips
    for clip in clips:  # robot and human: float32 keys, so a relative tolerance
        for track in clip["tracks"]:
            seconds = np.array([k["time"] for k in track["keys"]]) / clip["fps"]
            np.testing.assert_allclose(seconds, times, rtol=1e-6, atol=1e-6)


def test_console_script_runs_as_module():
    proc = subprocess.run([sys.executable, "-m", "nlo_lab.cli", "retarget", "x", "--robot"], capture_output=True, text=True)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


class _Terminal:
    """A stderr that says it is a terminal and keeps what is written."""

    def __init__(self):
        self.text = ""

    def isatty(self):
        return True

    def write(self, s):
        self.text += s
        return len(s)

    def flush(self):
        pass


@pytest.mark.parametrize("quiet", [False, True])
def test_retarget_progress_bar_on_a_terminal_unless_quiet(monkeypatch, capsys, quiet):
    from nlo_lab.corpus import corpus_names

    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    argv = ["retarget", f"demo:{corpus_names('test')[0]}", "--robot", "nao", "--iters", "3", "--json"] + (["--quiet"] if quiet else [])
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out.strip())["robot"] == "nao"  # stdout stays pure JSON
    if quiet:
        assert term.text == ""
    else:
        assert "retarget" in term.text and "to nao" in term.text and "it" in term.text, term.text


def test_retarget_progress_bar_leaves_the_result_unchanged(capsys):
    from nlo_lab.corpus import corpus_clip, corpus_names
    from nlo_lab.inference import OptimizeSettings
    from nlo_lab.pipeline import retarget
    from nlo_lab.robot import load_robot

    robot, demo = load_robot("nao"), corpus_clip(corpus_names("test")[1])
    settings = OptimizeSettings(iterations=4, patience=10)
    quiet = retarget(demo, robot, settings=settings)
    shown = retarget(demo, robot, settings=settings, progress=True)
    err = capsys.readouterr().err
    assert f"retarget {len(demo)} frames to nao" in err
    assert shown.optimization.iterations == quiet.optimization.iterations == 4
    assert np.array_equal(shown.trajectory.angles, quiet.trajectory.angles)


def test_the_command_line_is_the_only_argument_parser():
    """train and evaluate have no parsers of their own: one set of flags, one error path."""
    import ast
    from pathlib import Path

    import nlo_lab

    users = []
    for path in Path(nlo_lab.__file__).parent.rglob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        if any(isinstance(n, ast.Attribute) and n.attr == "ArgumentParser" for n in ast.walk(tree)):
            users.append(path.relative_to(Path(nlo_lab.__file__).parent).as_posix())
    assert users and all(u.startswith("cli/") for u in users), users  # the command line's package, nowhere else


@pytest.mark.slow
def test_a_bad_flag_or_help_does_not_wait_for_torch():
    """The flags' choices come from modules that import torch; they are read only when needed."""
    code = (
        "import sys, contextlib, io\n"
        "from nlo_lab.cli import build_parser, main\n"
        "assert main(['retarget', 'demo:x', '--robot', 'nao', '--iters', 'many']) == 2\n"
        "assert main(['train', '--robot', 'nao', '--epochs', '0']) == 2\n"
        "print('torch' in sys.modules)\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        "    try:\n"
        "        build_parser().parse_args(['retarget', '--help'])\n"
        "    except SystemExit:\n"
        "        pass\n"
        "print('encoder, random, train-stats, zeros' in ' '.join(out.getvalue().split()))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.stdout.split() == ["False", "True"], r.stdout + r.stderr


def test_the_summary_scores_the_hands_of_what_it_wrote(capsys, tmp_path):
    """On YuMi the JSON's hand keys are the handshape measures of the written trajectory against the recording."""
    from nlo_lab.human import load_demonstration
    from nlo_lab.metrics import HAND_KEYS, hand_summary
    from nlo_lab.paths import RECORDINGS_DIR
    from nlo_lab.robot import load_robot

    pose = RECORDINGS_DIR / "holistic_both_hands_47f.pose"
    code, out, err = run(["retarget", str(pose), "--robot", "yumi", "--out", str(tmp_path / "o"), "--json"], capsys)
    assert code == 0, err
    summary = json.loads(out.strip().splitlines()[-1])
    angles = np.load(tmp_path / "o" / "trajectory.npz")["angles"]
    expected = hand_summary(load_robot("yumi"), angles, load_demonstration(pose))
    assert expected["hand_frames"] > 0 and {k: summary[k] for k in HAND_KEYS} == pytest.approx(expected)


def test_the_printed_summary_has_no_hand_lines_without_hands(capsys):
    from nlo_lab.corpus import corpus_names

    code, out, err = run(["retarget", f"demo:{corpus_names('test')[0]}", "--robot", "nao", "--iters", "2"], capsys)
    assert code == 0, err
    assert "frechet_m" in out and "wrist_tip_deg" not in out and "hand_frames" not in out
    code, out, err = run(["retarget", f"demo:{corpus_names('test')[0]}", "--robot", "nao", "--iters", "2", "--json"], capsys)
    assert json.loads(out.strip().splitlines()[-1])["hand_frames"] is None  # the JSON keeps its keys: null

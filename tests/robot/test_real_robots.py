"""Robots we did not model, from the example-robot-data wheel (the test extra): init, check, a short train, a retarget.

The command line as a user runs it: ``nlo-lab robot init URDF --srdf SRDF --out SPEC.json``,
``nlo-lab robot check SPEC.json``, ``nlo-lab train --robot SPEC.json --out CKPT.pt`` (15 s) and
``nlo-lab retarget RECORDING --robot SPEC.json --checkpoint CKPT.pt --out DIR --json``.
Romeo's hands have four fingers (three and a thumb, all following one hand joint); the tips are
given (their names carry no finger names). ``benchmarks/robots.py`` measures the targets on
fully trained checkpoints.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from nlo_lab.paths import RECORDINGS_DIR

ROBOTS = {
    "baxter": ("baxter_description/urdf/baxter.urdf", "baxter_description/srdf/baxter_manipulation.srdf", []),
    "talos": ("talos_data/robots/talos_reduced.urdf", "talos_data/srdf/talos.srdf", []),
    "romeo": ("romeo_description/urdf/romeo.urdf", "romeo_description/srdf/romeo.srdf", [
        "--left-hand", "thumb=LThumb3Link,index=LFinger13Link,middle=LFinger23Link,ring=LFinger33Link",
        "--right-hand", "thumb=RThumb3Link,index=RFinger13Link,middle=RFinger23Link,ring=RFinger33Link"]),
}
RECORDING = RECORDINGS_DIR / "holistic_both_hands_47f.pose"


def nlo_lab(*args, cwd):
    """Run the command line in a fresh process (as a user does); returns (code, stdout, stderr)."""
    proc = subprocess.run([sys.executable, "-m", "nlo_lab.cli", *map(str, args)], capture_output=True, text=True, cwd=cwd, timeout=900)
    return proc.returncode, proc.stdout, proc.stderr


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_a_real_robot_from_urdf_to_a_retargeted_recording(name, robot_data, tmp_path):
    urdf, srdf, flags = ROBOTS[name]
    spec, ckpt, out = tmp_path / f"{name}.json", tmp_path / f"{name}.pt", tmp_path / "out"
    code, stdout, stderr = nlo_lab("robot", "init", robot_data / urdf, "--srdf", robot_data / srdf, "--out", spec, *flags, cwd=tmp_path)
    assert code == 0, stderr
    assert "wrote" in stdout and "Traceback" not in stderr
    data = json.loads(spec.read_text())
    assert len(data["actuated_joints"]) >= 14
    assert data["srdf"].endswith(".srdf") and data["capsules"] and data["collision_pairs"]
    if name == "romeo":
        assert sorted(data["arms"]["left"]["fingers"]) == ["index", "middle", "ring", "thumb"]
        assert "LHand" in data["actuated_joints"]  # the fingers' joints follow it (mimic): it is actuated for them
    code, stdout, stderr = nlo_lab("robot", "check", spec, cwd=tmp_path)
    assert code == 0, stderr
    assert "left  arm: 7 joints" in stdout and "right arm: 7 joints" in stdout
    if name == "romeo":  # every finger follows LHand: none has a joint of its own, the finger search has nothing to move
        assert stdout.count("no joint of its own, the finger search cannot move: thumb, index, middle, ring") == 2, stdout
    code, stdout, stderr = nlo_lab("train", "--robot", spec, "--out", ckpt, "--max-seconds", 15, "--quiet", cwd=tmp_path)
    assert code == 0, stderr
    assert ckpt.is_file()
    code, stdout, stderr = nlo_lab("retarget", RECORDING, "--robot", spec, "--checkpoint", ckpt, "--out", out, "--json", "--iters", 30,
                                   cwd=tmp_path)
    assert code == 0, stderr
    summary = json.loads(stdout.strip().splitlines()[-1])
    assert summary["frames"] == 47 and summary["limit_violations"] == 0 and summary["velocity_violations"] == 0
    with np.load(out / "trajectory.npz") as traj:
        assert traj["angles"].shape == (47, len(data["actuated_joints"]))  # one trajectory frame per recording frame
        assert traj["time"].shape == (47,) and bool(np.all(np.diff(traj["time"]) > 0))
    assert (out / "viewer.html").stat().st_size > 100_000  # the robot as it looks: its meshes, decimated


def test_without_its_checkpoint_a_drafted_robot_says_how_to_train_one(robot_data, tmp_path):
    spec = tmp_path / "icub.json"
    code, _, stderr = nlo_lab("robot", "init", robot_data / "icub_description/robots/icub.urdf", "--out", spec, cwd=tmp_path)
    assert code == 0, stderr
    code, _, stderr = nlo_lab("retarget", RECORDING, "--robot", spec, cwd=tmp_path)
    assert code == 2 and len(stderr.strip().splitlines()) == 1
    assert f"nlo-lab train --robot {spec}" in stderr and "--checkpoint" in stderr


@pytest.mark.slow
def test_a_drafted_romeo_trained_with_the_default_starts_points_its_arms_where_the_signer_does(robot_data, tmp_path):
    """Issue 28's direction target (at most 0.6 of the robot at rest) on the recording where single starts
    missed: from a straight elbow, 3 of 5 seeds trained into a basin where Romeo's elbows swing out (ratio
    0.8-1.0). The default candidate starts (TrainSettings.starts) go on with the lowest validation objective."""
    from nlo_lab.evaluation.directions import direction_error
    from nlo_lab.human import load_demonstration
    from nlo_lab.robot import load_robot

    urdf, srdf, flags = ROBOTS["romeo"]
    spec, ckpt, out = tmp_path / "romeo.json", tmp_path / "romeo.pt", tmp_path / "out"
    code, _, stderr = nlo_lab("robot", "init", robot_data / urdf, "--srdf", robot_data / srdf, "--out", spec, *flags, cwd=tmp_path)
    assert code == 0, stderr
    code, stdout, stderr = nlo_lab("train", "--robot", spec, "--out", ckpt, "--max-steps", 1500, "--max-seconds", 900, "--quiet", cwd=tmp_path)
    assert code == 0, stderr
    assert "(the best of 3 starts: seed " in stdout
    code, _, stderr = nlo_lab("retarget", RECORDING, "--robot", spec, "--checkpoint", ckpt, "--out", out, "--json", cwd=tmp_path)
    assert code == 0, stderr
    with np.load(out / "trajectory.npz") as traj:
        angles = traj["angles"]
    error = direction_error(load_robot(spec), load_demonstration(RECORDING), angles)
    assert error["ratio"] <= 0.6, error

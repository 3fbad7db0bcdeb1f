"""Tests of nlo_lab.inference.RobotTrajectory: validation and file round trips."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from nlo_lab.errors import NloLabError
from nlo_lab.inference import RobotTrajectory, TrajectoryError


@pytest.fixture
def traj():
    rng = np.random.default_rng(0)
    return RobotTrajectory(robot="nao", joint_names=["a", "b", "c"], angles=rng.uniform(-2, 2, size=(17, 3)), fps=30.0)


@pytest.mark.parametrize("suffix", [".npz", ".json"])
def test_round_trip_exact(tmp_path, traj, suffix):
    path = tmp_path / f"t{suffix}"
    getattr(traj, "save_npz" if suffix == ".npz" else "save_json")(path)
    back = RobotTrajectory.load(path)
    assert back == traj
    assert back.angles.dtype == np.float64
    np.testing.assert_array_equal(back.angles, traj.angles)  # bit-exact
    assert back.joint_names == ("a", "b", "c") and back.robot == "nao" and back.fps == 30.0
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary left behind


def test_csv_header_and_values(tmp_path, traj):
    path = traj.save_csv(tmp_path / "t.csv")
    rows = list(csv.reader(path.open()))
    assert rows[0] == ["time_s", "a", "b", "c"]
    assert len(rows) == 1 + len(traj)
    data = np.array(rows[1:], dtype=np.float64)
    np.testing.assert_allclose(data[:, 0], np.arange(17) / 30.0, rtol=0, atol=0)
    np.testing.assert_array_equal(data[:, 1:], traj.angles)


def test_frozen_and_read_only(traj):
    with pytest.raises(AttributeError):
        traj.fps = 10  # type: ignore[misc]
    with pytest.raises(ValueError):
        traj.angles[0, 0] = 1.0


def test_input_is_copied():
    a = np.zeros((2, 1))
    t = RobotTrajectory("x", ["j"], a, 10)
    a[0, 0] = 5.0
    assert t.angles[0, 0] == 0.0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(angles=np.zeros((5, 2))), r"\(T, 3\)"),
        (dict(angles=np.zeros((0, 3))), "no frames"),
        (dict(angles=np.array([[0.0, np.nan, 0.0]])), "frame 0, joint 'b'"),
        (dict(fps=0), "fps"),
        (dict(fps=-3.0), "fps"),
        (dict(fps="fast"), "fps"),
        (dict(joint_names=["a", "a", "c"]), "duplicates"),
        (dict(robot=""), "robot"),
    ],
)
def test_bad_input_raises(kwargs, match):
    args = dict(robot="nao", joint_names=["a", "b", "c"], angles=np.zeros((4, 3)), fps=25.0)
    args.update(kwargs)
    with pytest.raises(TrajectoryError, match=match):
        RobotTrajectory(**args)
    assert issubclass(TrajectoryError, NloLabError)


def test_load_bad_files(tmp_path, traj):
    with pytest.raises(TrajectoryError, match="no such file"):
        RobotTrajectory.load(tmp_path / "missing.npz")
    with pytest.raises(TrajectoryError, match="unsupported"):
        RobotTrajectory.load(tmp_path / "t.csv")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(TrajectoryError, match="bad.json"):
        RobotTrajectory.load(bad)
    wrong = tmp_path / "wrong.json"
    d = traj.to_dict()
    d["angles"] = d["angles"][:3] + [[1.0, 2.0]]
    wrong.write_text(json.dumps(d))
    with pytest.raises(TrajectoryError, match="wrong.json"):
        RobotTrajectory.load(wrong)
    trunc = tmp_path / "trunc.npz"
    traj.save_npz(trunc)
    trunc.write_bytes(trunc.read_bytes()[:50])
    with pytest.raises(TrajectoryError, match="trunc.npz"):
        RobotTrajectory.load(trunc)


def test_failed_write_leaves_old_file_intact(tmp_path, traj, monkeypatch):
    path = tmp_path / "t.json"
    traj.save_json(path)
    before = path.read_bytes()

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr("nlo_lab.inference.trajectory.os.replace", boom)
    other = RobotTrajectory("nao", ["a", "b", "c"], np.ones((2, 3)), 10.0)
    with pytest.raises(OSError, match="disk full"):
        other.save_json(path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.json"]


def test_missing_folder(tmp_path, traj):
    with pytest.raises(TrajectoryError, match="does not exist"):
        traj.save_npz(tmp_path / "nope" / "t.npz")

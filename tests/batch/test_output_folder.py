"""The output folder that `retarget --out` and `batch` write: the set swapped in whole, older extra files dropped."""

from __future__ import annotations

import json
import math
import os

import pytest

from nlo_lab.batch import SUMMARY_FILE, read_summary, write_output_folder
from nlo_lab.human import load_demonstration
from nlo_lab.inference import OptimizeSettings
from nlo_lab.paths import RECORDINGS_DIR
from nlo_lab.pipeline import RetargetConfig
from nlo_lab.robot import load_robot


@pytest.fixture(scope="module")
def made():
    robot = load_robot("nao")
    demo = load_demonstration(RECORDINGS_DIR / "holistic_both_hands_47f.pose")
    return RetargetConfig(robot, OptimizeSettings(iterations=1)).build()(demo), demo, robot


def test_the_viewer_and_the_summary_come_and_go_with_the_set(tmp_path, made):
    result, demo, robot = made
    out = tmp_path / "x"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    write_output_folder(out, result, demo, robot, viewer=True, summary={**result.summary, "final_loss": math.nan})
    assert sorted(os.listdir(out)) == ["notes.txt", SUMMARY_FILE, "trajectory.csv", "trajectory.npz", "viewer.html"]
    assert json.loads((out / SUMMARY_FILE).read_text())["final_loss"] is None  # not finite: null, valid JSON
    assert read_summary(out)["frames"] == 47
    write_output_folder(out, result, demo, robot, viewer=False)  # retarget --out keeps the folder's other files
    assert sorted(os.listdir(out)) == ["notes.txt", SUMMARY_FILE, "trajectory.csv", "trajectory.npz", "viewer.html"]
    write_output_folder(out, result, demo, robot, viewer=False, stale=("viewer.html", SUMMARY_FILE))  # batch's: they go
    assert sorted(os.listdir(out)) == ["notes.txt", "trajectory.csv", "trajectory.npz"]
    assert read_summary(out) is None and (out / "notes.txt").read_text() == "mine"


def test_a_failure_before_the_swap_changes_nothing(tmp_path, made):
    result, demo, robot = made
    out = tmp_path / "x"
    write_output_folder(out, result, demo, robot, viewer=False, summary=result.summary)
    before = {name: (out / name).read_bytes() for name in os.listdir(out)}

    def stop():
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_output_folder(out, result, demo, robot, viewer=True, summary={**result.summary, "frames": 1}, before_swap=stop)
    assert {name: (out / name).read_bytes() for name in os.listdir(out)} == before
    assert [p.name for p in tmp_path.iterdir()] == ["x"]  # no temporary folder left

"""``nlo-lab robot check``'s account of a hand: which fingers have a joint of their own (what the finger search moves)."""

from __future__ import annotations

import json
from pathlib import Path

from nlo_lab.robot import check_spec, load_robot, spec_summary

ASSETS = Path(__file__).resolve().parents[2] / "assets" / "robots"


def yumi_spec(tmp_path, edit) -> Path:
    """YuMi's spec with ``edit(arm)`` applied to each arm's dict, written to ``tmp_path``."""
    spec = json.loads((ASSETS / "yumi.json").read_text())
    spec["urdf"] = str(ASSETS / "yumi.urdf")
    for arm in spec["arms"].values():
        edit(arm)
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(spec))
    return path


def test_every_yumi_finger_has_a_joint_of_its_own():
    report = check_spec("yumi")
    assert report.own_fingers == {side: ["thumb", "index", "middle", "ring", "pinky"] for side in ("left", "right")}
    lines = spec_summary(report)
    assert sum("fingers thumb, index, middle, ring, pinky (each with a joint of its own)" in line for line in lines) == 2


def test_fingers_that_share_their_joints_are_named_as_the_search_cannot_move_them(tmp_path):
    def couple(arm):  # the ring finger named at the pinky's tip: the two share every joint above it
        arm["fingers"]["ring"] = arm["fingers"]["pinky"]

    report = check_spec(yumi_spec(tmp_path, couple))
    assert report.own_fingers["left"] == ["thumb", "index", "middle"]
    line = next(line for line in spec_summary(report) if line.lstrip().startswith("left"))
    assert line.endswith("fingers thumb, index, middle, ring, pinky (a joint of its own: thumb, index, middle; "
                         "no joint of its own, the finger search cannot move: ring, pinky)"), line
    robot = load_robot(yumi_spec(tmp_path, couple))
    assert robot.finger_joints("left", "ring") == [] and robot.finger_joints("left", "pinky") == []
    assert [robot.joint_names[j] for j in robot.finger_joints("left", "middle")] == ["yumi_hand_l_middle_proximal_joint"]

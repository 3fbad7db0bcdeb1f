"""Our bundled robots drafted from their URDFs alone come out close to their hand-written specs.

Tolerances (the draft derives what the hand-written specs state):
- actuated joints: the same, in the same order; role links (shoulder, elbow, wrist): the same;
- fingers: the same five, each tip the same link, each base within 2 cm of the hand-written one
  (YuMi's thumb: the draft takes the child of the thumb's first joint, the spec its second);
- wrist alignment: within 1 degree (YuMi's two arms differ by 3.4 mrad in the published joint 1);
- the robot frame: shoulders and arm lengths within 1 mm of the bundled robot's;
- velocity limits: equal where the URDF states one; the capsules hold the collision geometry.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from nlo_lab.paths import ROBOTS_DIR
from nlo_lab.robot import load_robot
from nlo_lab.robot.spec_draft import draft_spec


def angle_between(ra, rb) -> float:
    from nlo_lab.rotations import rpy_to_matrix

    R = rpy_to_matrix(ra).T @ rpy_to_matrix(rb)
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))))


@pytest.mark.parametrize("name", ["nao", "pepper", pytest.param("yumi", marks=pytest.mark.slow)])
def test_bundled_robot_drafted_from_its_urdf_matches_its_spec(name, tmp_path):
    bundled = load_robot(name)
    draft = draft_spec(ROBOTS_DIR / f"{name}.urdf", tmp_path / f"{name}.json", samples=200)
    drafted = draft.robot
    assert drafted.joint_names == bundled.joint_names
    for side in ("left", "right"):
        a, b = drafted.arm(side), bundled.arm(side)
        assert (a.shoulder, a.elbow, a.wrist) == (b.shoulder, b.elbow, b.wrist)
        assert sorted(a.fingers) == sorted(b.fingers)
        with torch.no_grad():
            pa = drafted.forward_kinematics(drafted.reference_q[None].double())
            pb = bundled.forward_kinematics(bundled.reference_q[None].double())
        for finger, (base, tip) in b.fingers.items():
            assert a.fingers[finger][1] == tip
            assert float((pa[a.fingers[finger][0]][0, :3, 3] - pb[base][0, :3, 3]).norm()) < 0.02, (side, finger)
        assert angle_between(a.wrist_alignment_rpy, b.wrist_alignment_rpy) < 1.0, side
        torch.testing.assert_close(drafted.shoulder_position(side).double(), bundled.shoulder_position(side).double(), atol=1e-3, rtol=0)
        np.testing.assert_allclose(drafted.zero_pose_lengths(side), bundled.zero_pose_lengths(side), atol=1e-3)
    urdf_speeds = {j.name: j.velocity for j in bundled.model.joints if j.velocity is not None}
    for joint, speed in draft.spec["velocity_limits"].items():
        if joint in urdf_speeds:
            assert speed == pytest.approx(dict(bundled.spec.velocity_limits)[joint]), joint
    assert draft.warnings == [] or all("no velocity limit" in w for w in draft.warnings)

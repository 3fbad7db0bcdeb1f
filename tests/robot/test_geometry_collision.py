"""The self-collision check by the URDF's own geometry (nlo_lab.robot.geometry_collision)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from nlo_lab.robot import load_robot
from nlo_lab.robot.geometry_collision import DEPTH_TOLERANCE, GeometryCollision, overlap_depth, polytope


def moved(x: float = 0.0, y: float = 0.0, z: float = 0.0, yaw: float = 0.0) -> np.ndarray:
    T = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = (x, y, z)
    return T


@pytest.mark.parametrize("gap", [-0.03, -0.01, -0.002, 0.0, 0.004, 0.2])
def test_two_boxes_pressed_together_overlap_by_the_slab_they_share(gap):
    box = polytope("a", trimesh.creation.box(extents=(0.1, 0.1, 0.1)))
    depth = overlap_depth(box, moved(), box, moved(x=0.1 + gap))
    assert depth == pytest.approx(max(0.0, -gap), abs=1e-7)


def test_two_spheres_overlap_by_their_lens_thickness():
    ball = polytope("a", trimesh.creation.icosphere(subdivisions=3, radius=0.05))
    depth = overlap_depth(ball, moved(), ball, moved(y=0.09))
    assert depth == pytest.approx(0.01, abs=5e-4)  # tessellated within 0.2 % of the radius


def test_crossed_bars_with_no_corner_inside_the_other_still_overlap():
    """A plus sign: no vertex of either bar lies inside the other; the linear programme still finds it."""
    bar = polytope("a", trimesh.creation.box(extents=(0.4, 0.02, 0.02)))
    assert overlap_depth(bar, moved(), bar, moved(yaw=np.pi / 2)) == pytest.approx(0.02, abs=1e-7)
    assert overlap_depth(bar, moved(), bar, moved(z=0.021, yaw=np.pi / 2)) == 0.0


def two_link_arm(tmp_path, length: float = 0.15, elbow=(-3.0, 3.0)):
    """A base and a two-joint arm whose far link can fold back onto the base."""
    urdf = tmp_path / "fold.urdf"
    urdf.write_text(f"""<robot name="fold">
  <link name="base"><collision><origin xyz="0 0 -0.1"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  <link name="upper"><collision><origin xyz="{length / 2} 0 0"/><geometry><box size="{length} 0.04 0.04"/></geometry></collision></link>
  <link name="fore"><collision><origin xyz="{length / 2} 0 0"/><geometry><box size="{length} 0.04 0.04"/></geometry></collision></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.05"/>
    <axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" velocity="1" effort="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="{length} 0 0"/>
    <axis xyz="0 1 0"/><limit lower="{elbow[0]}" upper="{elbow[1]}" velocity="1" effort="1"/></joint>
</robot>""")
    spec = tmp_path / "fold.json"
    spec.write_text(json.dumps({
        "name": "fold", "urdf": "fold.urdf", "base_link": "base", "actuated_joints": ["shoulder", "elbow"],
        "arms": {side: {"shoulder": "upper", "elbow": "fore", "wrist": "fore"} for side in ("left", "right")},
    }))
    return load_robot(spec)


def test_a_folded_arm_hits_its_base_and_the_check_says_how_deep(tmp_path):
    robot = two_link_arm(tmp_path)
    check = GeometryCollision(robot)
    pairs = {(check.pieces[i].link, check.pieces[j].link) for i, j in check.pairs}
    assert pairs == {("base", "fore")}  # upper hangs from base, fore from upper: only base/fore is checked
    # straight out: clear; elbow folded by 2 rad with the shoulder level: the forearm's tip comes
    # back to x = 0.15 (1 + cos 2) = 0.088 and down to z = 0.05 - 0.15 sin 2 = -0.086, inside the
    # base box (|x| <= 0.1, z <= 0); the overlap is at most the bar's 0.04 m thickness
    report = check.report(np.array([[0.0, 0.0], [0.0, 2.0]]))
    assert report["frames"] == 1 and report["worst"] == ("base", "fore", 1)
    assert 0.01 < report["max_depth_m"] <= 0.04 + 1e-9
    assert check.depths(np.array([[0.0, 0.0]]))[0, 0] == 0.0


def test_pairs_touching_at_rest_are_not_checked(tmp_path):
    """An elbow whose limits start folded (zero clamps to 2 rad): the forearm rests in the base."""
    robot = two_link_arm(tmp_path, elbow=(2.0, 3.0))
    check = GeometryCollision(robot)
    assert check.rest_contacts == [("base", "fore")]
    assert len(check.pairs) == 0 and check.report(robot.neutral_q.numpy()[None])["frames"] == 0


@pytest.mark.parametrize("name", ["yumi", "nao", "pepper"])
def test_bundled_robots_are_clear_at_their_neutral_pose_and_pairs_are_not_adjacent(name):
    robot = load_robot(name)
    check = GeometryCollision(robot)
    assert check.skipped == []
    assert check.report(robot.neutral_q.numpy()[None])["frames"] == 0
    parent = {j.child: j.parent for j in robot.model.joints}
    for i, j in check.pairs:
        a, b = check.pieces[i].link, check.pieces[j].link
        assert parent.get(a) != b and parent.get(b) != a


def test_nao_wrist_driven_into_its_legs_is_found():
    """The collision the hand-written capsules left out (issue 28): NAO's hand against its thigh."""
    robot = load_robot("nao")
    q = robot.neutral_q.numpy().copy()
    names = robot.joint_names
    q[names.index("LShoulderPitch")] = 1.5  # arm down
    q[names.index("LShoulderRoll")] = -0.3  # inwards, over the thigh
    q[names.index("LElbowRoll")] = -0.05
    check = GeometryCollision(robot)
    report = check.report(q[None])
    d = check.depths(q[None])[0]
    hit = {(check.pieces[i].link, check.pieces[j].link) for (i, j), v in zip(check.pairs, d, strict=True) if v > DEPTH_TOLERANCE}
    assert report["frames"] == 1 and any("legs" in p for p in hit), hit
    # and the fitted capsules see it too
    assert float(robot.capsule_distances(robot.forward_kinematics(__import__("torch").as_tensor(q)[None])).min()) < 0

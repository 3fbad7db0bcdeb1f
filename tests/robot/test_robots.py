"""Robot descriptions and the loader: joint tables, frames, graph, and bad input."""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable

import numpy as np
import pytest
import torch

from nlo_lab.errors import NloLabError, RobotDescriptionError, UnknownRobotError
from nlo_lab.graph import NODE_ARM, NODE_HAND
from nlo_lab.paths import ROBOTS_DIR
from nlo_lab.robot import Robot, known_robots, load_robot
from nlo_lab.robot.geometry import link_shapes, shape_mesh

ROBOTS = ["yumi", "nao", "pepper"]


# --------------------------------------------------------------- joint tables (docs/ROBOT_FACTS.md)
YUMI_ARM = {  # joint: (lower, upper) [rad], same for both arms
    1: (-2.94088, 2.94088),
    2: (-2.50455, 0.75922),
    7: (-2.94088, 2.94088),
    3: (-2.15548, 1.39626),
    4: (-5.06145, 5.06145),
    5: (-1.53589, 2.40855),
    6: (-3.99680, 3.99680),
}
INSPIRE = {  # actuated hand joints per hand: name fragment -> (lower, upper)
    "thumb_proximal_yaw": (0.0, 1.308),
    "thumb_proximal_pitch": (0.0, 0.6),
    "index_proximal": (0.0, 1.47),
    "middle_proximal": (0.0, 1.47),
    "ring_proximal": (0.0, 1.47),
    "pinky_proximal": (0.0, 1.47),
}
P = 2.08567
NAO = {
    "LShoulderPitch": (-P, P), "LShoulderRoll": (-0.314159, 1.32645), "LElbowYaw": (-P, P),
    "LElbowRoll": (-1.54462, -0.0349066), "LWristYaw": (-1.82387, 1.82387),
    "RShoulderPitch": (-P, P), "RShoulderRoll": (-1.32645, 0.314159), "RElbowYaw": (-P, P),
    "RElbowRoll": (0.0349066, 1.54462), "RWristYaw": (-1.82387, 1.82387),
}  # fmt: skip
PEPPER = {
    "LShoulderPitch": (-P, P), "LShoulderRoll": (0.00872665, 1.56207), "LElbowYaw": (-P, P),
    "LElbowRoll": (-1.56207, -0.00872665), "LWristYaw": (-1.82387, 1.82387),
    "RShoulderPitch": (-P, P), "RShoulderRoll": (-1.56207, -0.00872665), "RElbowYaw": (-P, P),
    "RElbowRoll": (0.00872665, 1.56207), "RWristYaw": (-1.82387, 1.82387),
}  # fmt: skip


def expected_limits(name: str, robot64: Callable[[str], Robot]) -> dict[str, tuple[float, float]]:
    if name == "nao":
        return NAO
    if name == "pepper":
        return PEPPER
    out = {f"yumi_joint_{k}_{s}": lim for s in "lr" for k, lim in YUMI_ARM.items()}
    robot = robot64("yumi")
    for s in "lr":
        for frag, lim in INSPIRE.items():
            hits = [n for n in robot.joint_names if f"_{s}_" in n and frag in n and n not in out]
            assert len(hits) == 1, f"expected one actuated {s} hand joint named like {frag!r}, got {hits}"
            out[hits[0]] = lim
    return out


@pytest.mark.parametrize("name", ROBOTS)
def test_joint_counts_and_limits_match_robot_facts(name, robot64):
    robot = robot64(name)
    expected = expected_limits(name, robot64)
    assert robot.n_joints == {"yumi": 26, "nao": 10, "pepper": 10}[name]
    assert sorted(robot.joint_names) == sorted(expected)
    for i, joint in enumerate(robot.joint_names):
        lo, hi = expected[joint]
        # the facts are given to 5-6 significant digits
        assert float(robot.lower_limits[i]) == pytest.approx(lo, abs=1e-5), joint
        assert float(robot.upper_limits[i]) == pytest.approx(hi, abs=1e-5), joint


def test_known_robots_are_bundled():
    assert set(ROBOTS) <= set(known_robots())


# --------------------------------------------------------------- frames
@pytest.mark.parametrize("name", ROBOTS)
def test_origin_is_midpoint_of_shoulders_left_arm_at_plus_y(name, robot64):
    robot = robot64(name)
    left, right = robot.shoulder_position("left"), robot.shoulder_position("right")
    # 1e-4 m: the published rpy (1.5708 for pi/2, 4-digit YuMi base angles) leave ~4e-5 m residue
    torch.testing.assert_close(left + right, torch.zeros(3, dtype=torch.float64), atol=1e-4, rtol=0)
    assert abs(float(left[0])) < 1e-4 and abs(float(left[2])) < 1e-4
    assert float(left[1]) > 0.05 and float(right[1]) < -0.05
    # shoulder_position agrees with FK at the reference pose
    poses = robot.forward_kinematics(robot.reference_q[None])
    torch.testing.assert_close(poses[robot.arm("left").shoulder][0, :3, 3], left)


# Published segment lengths, measured at q = 0 between the named links along the
# arm's long axis (an axis of the first link's frame). The published figures are
# the sums of the offsets along the arm; the lateral offsets (NAO/Pepper elbow
# 15 mm, YuMi joint offsets) are not part of them, hence the projection.
PUBLISHED = {
    "yumi": [("yumi_link_2_l", "yumi_link_4_l", 1, 0.17283 + 0.07873), ("yumi_link_4_l", "yumi_link_6_l", 1, 0.265),
             ("yumi_link_2_r", "yumi_link_4_r", 1, 0.2516), ("yumi_link_4_r", "yumi_link_6_r", 1, 0.265)],
    "nao": [("LShoulder", "LElbow", 0, 0.105), ("RShoulder", "RElbow", 0, 0.105)],
    "pepper": [("LShoulder", "LElbow", 0, 0.1812), ("RShoulder", "RElbow", 0, 0.1812)],
}  # fmt: skip


@pytest.mark.parametrize("name", ROBOTS)
def test_zero_pose_reproduces_published_lengths(name, robot64):
    robot = robot64(name)
    q0 = torch.zeros(1, robot.n_joints, dtype=torch.float64)
    poses = robot.forward_kinematics(q0)
    for a, b, axis, length in PUBLISHED[name]:
        Ta, Tb = poses[a][0], poses[b][0]
        along = float(Ta[:3, axis] @ (Tb[:3, 3] - Ta[:3, 3]))
        # 1e-4 m: the facts round to 0.1 mm (0.2516 vs 0.17283 + 0.07873 = 0.25156)
        assert along == pytest.approx(length, abs=1e-4), (a, b)
    # the upper-arm segment runs between the spec's shoulder and elbow role links
    arm = robot.arm("left")
    assert (arm.shoulder, arm.elbow) == PUBLISHED[name][0][:2]


@pytest.mark.parametrize("name", ROBOTS)
def test_zero_pose_lengths_are_role_link_distances(name, robot64):
    robot = robot64(name)
    poses = robot.forward_kinematics(robot.reference_q[None])
    for side in ("left", "right"):
        arm = robot.arm(side)
        p = {k: poses[k][0, :3, 3] for k in (arm.shoulder, arm.elbow, arm.wrist)}
        up, fore = robot.zero_pose_lengths(side)
        assert up == pytest.approx(float((p[arm.elbow] - p[arm.shoulder]).norm()), abs=1e-12)
        assert fore == pytest.approx(float((p[arm.wrist] - p[arm.elbow]).norm()), abs=1e-12)
        assert 0.05 < up < 0.4 and 0.04 < fore < 0.4


@pytest.mark.parametrize("name", ROBOTS)
def test_wrist_alignment_is_mirror_symmetric_and_points_along_the_hand(name, robot64):
    """Human wrist frame (x along the hand, y pinky->index, z = x cross y) on both sides.

    Mirroring the robot (y -> -y) maps the right hand frame's x and y onto the
    left's, and z onto minus the left's (z = x cross y flips under a mirror).
    """
    robot = robot64(name)
    poses = robot.forward_kinematics(robot.reference_q[None])
    M = torch.diag(torch.tensor([1.0, -1.0, 1.0], dtype=torch.float64))
    frames = {}
    for side in ("left", "right"):
        arm = robot.arm(side)
        R = poses[arm.wrist][0, :3, :3] @ robot.wrist_alignment(side)
        torch.testing.assert_close(R.T @ R, torch.eye(3, dtype=torch.float64), atol=1e-9, rtol=0)
        assert float(torch.linalg.det(R)) == pytest.approx(1.0, abs=1e-9)
        frames[side] = R
        # x along the hand: towards the middle finger base, or towards the hand's collision geometry
        wrist = poses[arm.wrist][0, :3, 3]
        if arm.fingers:
            to_middle = poses[arm.fingers["middle"][0]][0, :3, 3] - wrist
            pinky_to_index = poses[arm.fingers["index"][0]][0, :3, 3] - poses[arm.fingers["pinky"][0]][0, :3, 3]
            assert float(R[:, 1] @ pinky_to_index / pinky_to_index.norm()) > 0.9
        else:
            boxes = [shape_mesh(s) for s in link_shapes(robot.model, "collision") if s.link == arm.wrist]
            centre = np.mean([b.bounds.mean(0) for b in boxes], axis=0)  # in the wrist link's frame
            to_middle = poses[arm.wrist][0, :3, :3] @ torch.as_tensor(centre)
        assert float(R[:, 0] @ to_middle / to_middle.norm()) > 0.9
    L, Rr = frames["left"], frames["right"]
    # 5e-3: YuMi's published joint-1 angles of the two arms differ by up to 3.4e-3 rad
    tol = 5e-3 if name == "yumi" else 1e-9
    torch.testing.assert_close(L[:, 0], M @ Rr[:, 0], atol=tol, rtol=0)
    torch.testing.assert_close(L[:, 1], M @ Rr[:, 1], atol=tol, rtol=0)
    torch.testing.assert_close(L[:, 2], -(M @ Rr[:, 2]), atol=tol, rtol=0)


@pytest.mark.parametrize("name", ["nao", "pepper"])
def test_nao_pepper_hands_are_palm_down_thumb_in_at_zero(name, robot64):
    """Our NAO/Pepper hands: palm down at the zero pose, thumb towards the body's midline."""
    robot = robot64(name)
    poses = robot.forward_kinematics(torch.zeros(1, robot.n_joints, dtype=torch.float64))
    for side, medial in (("left", -1.0), ("right", 1.0)):
        R = poses[robot.arm(side).wrist][0, :3, :3] @ robot.wrist_alignment(side)
        assert float(R[1, 1]) == pytest.approx(medial, abs=1e-9)  # y (towards index/thumb) medial
        palm = R[:, 2] if side == "left" else -R[:, 2]  # z is the palm for the left hand
        # Pepper's forearm is pitched up by 0.157 rad at the elbow (its published origin rpy)
        tilt = 0.157079 if name == "pepper" else 0.0
        assert float(palm[2]) == pytest.approx(-math.cos(tilt), abs=1e-9)


# --------------------------------------------------------------- graph
@pytest.mark.parametrize("name", ROBOTS)
def test_structure_graph(name, robot64):
    robot = robot64(name)
    g = robot.graph
    assert g.node_names == tuple(robot.joint_names)
    assert g.edge_attr.shape == (g.num_edges, 6)
    src, dst = g.edge_index
    # every node receives at least one message
    assert set(dst.tolist()) == set(range(g.num_nodes))
    # without the root<->root edges the graph is a forest of parent -> child edges: one parent each
    roots = [robot.joint_names.index(n) for n in robot.joint_names if n.startswith(("yumi_joint_1_", "LShoulderPitch", "RShoulderPitch"))]
    assert len(roots) == 2
    tree = [(int(s), int(d)) for s, d in zip(src, dst, strict=True) if not (int(s) in roots and int(d) in roots)]
    assert sorted(d for _, d in tree) == sorted(set(range(g.num_nodes)) - set(roots))
    hand = int((g.node_type == NODE_HAND).sum())
    assert hand == (12 if name == "yumi" else 0)
    assert int((g.node_type == NODE_ARM).sum()) == (14 if name == "yumi" else 10)


def test_graph_edge_features_are_child_joint_origins(robot64):
    robot = robot64("nao")
    g = robot.graph
    i, j = robot.joint_names.index("LShoulderRoll"), robot.joint_names.index("LElbowYaw")
    k = [e for e in range(g.num_edges) if int(g.edge_index[0, e]) == i and int(g.edge_index[1, e]) == j]
    assert len(k) == 1
    torch.testing.assert_close(g.edge_attr[k[0]], torch.tensor([0.105, 0.015, 0, 0, 0, 0], dtype=torch.float64))
    pep = robot64("pepper")
    i, j = pep.joint_names.index("RShoulderRoll"), pep.joint_names.index("RElbowYaw")
    k = [e for e in range(pep.graph.num_edges) if int(pep.graph.edge_index[0, e]) == i and int(pep.graph.edge_index[1, e]) == j]
    torch.testing.assert_close(pep.graph.edge_attr[k[0]], torch.tensor([0.1812, -0.015, 0.00013, 0, -0.157079, 0], dtype=torch.float64))


# --------------------------------------------------------------- collision spec
@pytest.mark.parametrize("name", ROBOTS)
def test_collision_pairs_are_not_adjacent_and_clear_at_neutral_pose(name, robot64):
    robot = robot64(name)
    parent = {j.child: j.parent for j in robot.model.joints}
    for a, b in robot.spec.collision_pairs:
        la, lb = robot.spec.capsule(a).link, robot.spec.capsule(b).link
        assert la != lb and parent.get(la) != lb and parent.get(lb) != la, (a, b)
    assert robot.collision_margins.shape == (len(robot.spec.collision_pairs),)
    assert bool((robot.collision_margins >= 0).all())
    link_of = {c.name: c.link for c in robot.spec.capsules}
    zero = [(a, b) for (a, b), m in zip(robot.spec.collision_pairs, robot.collision_margins.tolist(), strict=True) if m == 0]
    assert all("thumb" in link_of[a] + link_of[b] for a, b in zero), zero  # margin 0: a thumb may touch (a pinch), no other pair
    q = robot.neutral_q
    assert bool(((q >= robot.lower_limits) & (q <= robot.upper_limits)).all())
    d = robot.capsule_distances(robot.forward_kinematics(q[None]))
    assert d.shape == (1, len(robot.spec.collision_pairs))
    bad = [p for p, v in zip(robot.spec.collision_pairs, d[0], strict=True) if v <= 0]
    assert not bad, f"the neutral pose must be collision free; penetrating: {bad}"


def test_to_changes_dtype_of_every_tensor():
    robot = load_robot("nao")
    assert robot.lower_limits.dtype == torch.float32
    r64 = robot.to(dtype=torch.float64)
    for t in (r64.lower_limits, r64.upper_limits, r64.collision_margins, r64.graph.edge_attr, r64.wrist_alignment("left")):
        assert t.dtype == torch.float64
    assert robot.lower_limits.dtype == torch.float32  # the original is unchanged
    poses = r64.forward_kinematics(torch.zeros(3, 10, dtype=torch.float64))
    assert poses["l_wrist"].shape == (3, 4, 4) and poses["l_wrist"].dtype == torch.float64


# --------------------------------------------------------------- bad input
def copy_robot(tmp_path, name="nao"):
    for suffix in (".json", ".urdf"):
        shutil.copy(ROBOTS_DIR / f"{name}{suffix}", tmp_path / f"{name}{suffix}")
    return tmp_path / f"{name}.json", tmp_path / f"{name}.urdf"


def test_unknown_robot_name_lists_known_robots():
    with pytest.raises(UnknownRobotError) as e:
        load_robot("r2d2")
    assert "r2d2" in str(e.value) and "nao" in str(e.value) and "pepper" in str(e.value)


def test_bundled_name_wins_over_a_folder_of_that_name(tmp_path, monkeypatch):
    (tmp_path / "nao").mkdir()
    monkeypatch.chdir(tmp_path)
    assert load_robot("nao").n_joints == 10


def test_missing_spec_file(tmp_path):
    with pytest.raises(RobotDescriptionError, match="no such file"):
        load_robot(tmp_path / "nope.json")


def test_missing_urdf_file(tmp_path):
    spec, urdf = copy_robot(tmp_path)
    urdf.unlink()
    with pytest.raises(RobotDescriptionError, match=r"no such file.*nao\.urdf"):
        load_robot(spec)


def test_truncated_urdf(tmp_path):
    spec, urdf = copy_robot(tmp_path)
    text = urdf.read_text()
    urdf.write_text(text[: len(text) // 2])
    with pytest.raises(RobotDescriptionError, match=r"nao\.urdf.*malformed"):
        load_robot(spec)


def test_one_parse_per_urdf_file(monkeypatch):
    """yourdfpy parses each URDF once (from the bytes nlo_lab read and checked); FK and the viewer's visuals share it."""
    yourdfpy = pytest.importorskip("yourdfpy")
    from nlo_lab.viz.scene import robot_visuals

    calls = []
    real = yourdfpy.URDF.load
    monkeypatch.setattr(yourdfpy.URDF, "load", staticmethod(lambda *a, **k: calls.append(a[0]) or real(*a, **k)))
    robot = load_robot("nao")
    assert isinstance(robot.model.urdf, yourdfpy.URDF)
    assert robot_visuals(robot) and len(calls) == 1 and b"<robot" in calls[0].getvalue()


def test_urdf_with_a_bad_number_names_the_file(tmp_path):
    spec, urdf = copy_robot(tmp_path)
    urdf.write_text(urdf.read_text().replace('<joint name="RWristYaw" type="revolute">', '<joint name="RWristYaw" type="revolute">\n    <origin xyz="0 zero 0"/>', 1))
    with pytest.raises(RobotDescriptionError, match=r"nao\.urdf.*malformed URDF"):
        load_robot(spec)


def test_urdf_joint_without_a_child_names_the_file(tmp_path):
    spec, urdf = copy_robot(tmp_path)
    text = urdf.read_text()
    start = text.index('<joint name="RWristYaw"')
    child = text.index("<child", start)
    urdf.write_text(text[:child] + text[text.index("/>", child) + 2:])
    with pytest.raises(RobotDescriptionError, match=r"nao\.urdf"):
        load_robot(spec)


def test_spec_naming_missing_link(tmp_path):
    spec, _ = copy_robot(tmp_path)
    data = json.loads(spec.read_text())
    data["arms"]["left"]["elbow"] = "LElbowThatIsNot"
    spec.write_text(json.dumps(data))
    with pytest.raises(RobotDescriptionError, match=r"arms\.left\.elbow.*'LElbowThatIsNot'.*does not exist"):
        load_robot(spec)


def test_spec_capsule_on_missing_link(tmp_path):
    spec, _ = copy_robot(tmp_path)
    data = json.loads(spec.read_text())
    data["capsules"][0]["link"] = "Tail"
    spec.write_text(json.dumps(data))
    with pytest.raises(RobotDescriptionError, match=rf"capsule '{data['capsules'][0]['name']}'.*'Tail'"):
        load_robot(spec)


def test_spec_naming_missing_joint(tmp_path):
    spec, _ = copy_robot(tmp_path)
    data = json.loads(spec.read_text())
    data["actuated_joints"][2] = "LElbowPitch"
    spec.write_text(json.dumps(data))
    with pytest.raises(RobotDescriptionError, match=r"nao\.json.*'LElbowPitch' does not exist"):
        load_robot(spec)


def test_unlisted_moving_joint(tmp_path):
    spec, _ = copy_robot(tmp_path)
    data = json.loads(spec.read_text())
    data["actuated_joints"].remove("RWristYaw")
    spec.write_text(json.dumps(data))
    with pytest.raises(RobotDescriptionError, match=r"'RWristYaw' is neither"):
        load_robot(spec)


def test_mimic_of_missing_joint(tmp_path):
    spec, urdf = copy_robot(tmp_path)
    text = urdf.read_text()
    marker = '<joint name="RWristYaw" type="revolute">'
    assert marker in text
    urdf.write_text(text.replace(marker, marker + '\n    <mimic joint="RWristPitch" multiplier="1" offset="0"/>'))
    with pytest.raises(RobotDescriptionError, match=r"'RWristYaw' mimics 'RWristPitch', which does not exist"):
        load_robot(spec)


def test_collision_pair_of_adjacent_links(tmp_path):
    spec, _ = copy_robot(tmp_path)
    data = json.loads(spec.read_text())
    data["capsules"].append({"name": "l_elbow_ball", "link": "LForeArm", "p0": [0, 0, 0], "p1": [0, 0, 0], "radius": 0.02})
    hand = next(c["name"] for c in data["capsules"] if c["link"] == "l_wrist")
    data["collision_pairs"].append(["l_elbow_ball", hand])  # LForeArm is l_wrist's parent
    spec.write_text(json.dumps(data))
    with pytest.raises(RobotDescriptionError, match="adjacent"):
        load_robot(spec)


def test_errors_are_nlo_lab_errors(robot64):
    assert issubclass(RobotDescriptionError, NloLabError) and issubclass(UnknownRobotError, NloLabError)
    assert math.isfinite(robot64("nao").zero_pose_lengths("left")[0])


def test_forward_kinematics_links_equals_the_full_dict():
    robot = load_robot("yumi").to(dtype=torch.float64)
    q = robot.reference_q + 0.1
    names = [robot.arm("right").wrist, robot.link_names[0], robot.arm("left").elbow]
    T = robot.forward_kinematics_links(q[None], names)  # (1, 3, 4, 4)
    full = robot.forward_kinematics(q[None])
    for k, n in enumerate(names):
        torch.testing.assert_close(T[:, k], full[n], atol=1e-12, rtol=0)


# --------------------------------------------------------------- the interface the objective uses
@pytest.mark.parametrize("name", ROBOTS)
def test_root_link_is_the_spec_base_link_at_the_identity(name, robot64):
    robot = robot64(name)
    assert robot.root_link == robot.spec.base_link == robot.link_names[0]
    T = robot.forward_kinematics(robot.reference_q[None])[robot.root_link]
    torch.testing.assert_close(T[0], torch.eye(4, dtype=torch.float64))


@pytest.mark.parametrize("name", ROBOTS)
def test_point_map_puts_link_points_where_fk_does(name, robot64):
    robot = robot64(name)
    links = [robot.arm("left").elbow, robot.arm("right").wrist, robot.root_link]
    local = torch.tensor([[0.03, -0.02, 0.01, 1.0], [0.0, 0.0, 1.0, 0.0], [0.1, 0.2, 0.3, 1.0]], dtype=torch.float64)
    body, vec = robot.point_map(links, local.numpy())
    g = torch.Generator().manual_seed(1)
    q = robot.lower_limits + torch.rand(3, robot.n_joints, generator=g, dtype=torch.float64) * (robot.upper_limits - robot.lower_limits)
    got = robot.map_points(q, torch.as_tensor(body), torch.as_tensor(vec))  # (3, 3, 3)
    T = robot.forward_kinematics_links(q, links)  # (3, 3, 4, 4)
    torch.testing.assert_close(got, (T @ local[..., None]).squeeze(-1)[..., :3])
    with pytest.raises(RobotDescriptionError, match="no link named 'nowhere'"):
        robot.point_map(["nowhere"], [[0.0, 0.0, 0.0, 1.0]])


@pytest.mark.parametrize("name", ROBOTS)
def test_capsule_and_pair_radii_follow_the_spec(name, robot64):
    robot = robot64(name).to(dtype=torch.float32)
    caps = robot.spec.capsules
    assert robot.capsule_radii.dtype == torch.float32
    assert robot.capsule_radii.tolist() == pytest.approx([c.radius for c in caps])
    names = [c.name for c in caps]
    assert [(names[a], names[b]) for a, b in robot.pair_capsules] == list(robot.spec.collision_pairs)
    expected = [caps[a].radius + caps[b].radius for a, b in robot.pair_capsules]
    assert robot.pair_radii.tolist() == pytest.approx(expected)
    # the pair distances are the axis distances minus these radii
    T = robot.forward_kinematics_tensor(robot.neutral_q[None])
    from nlo_lab.robot.collision import segment_distance_ends

    seg = robot.capsule_segments(T)[0]  # (C, 2, 3)
    ends = torch.cat([seg[robot.pair_capsules[:, 0]], seg[robot.pair_capsules[:, 1]]], 1)  # (P, 4, 3)
    torch.testing.assert_close(robot.capsule_distances(T)[0], segment_distance_ends(ends) - robot.pair_radii)


def test_check_angles_shapes_and_errors(robot64):
    robot = robot64("nao")
    n = robot.n_joints
    one = robot.check_angles(torch.zeros(n))
    assert one.shape == (1, n) and one.dtype.name == "float64"
    assert robot.check_angles([[0.0] * n] * 3).shape == (3, n)
    with pytest.raises(NloLabError, match=rf"must be \({n},\) or \(T, {n}\), got shape \(2, {n - 1}\)"):
        robot.check_angles(torch.zeros(2, n - 1))
    bad = torch.zeros(4, n)
    bad[2, 3] = float("nan")
    with pytest.raises(NloLabError, match=f"not finite \\(frame 2, joint '{robot.joint_names[3]}'\\)"):
        robot.check_angles(bad)
    with pytest.raises(NloLabError, match="must be numbers"):
        robot.check_angles([["a"] * n])


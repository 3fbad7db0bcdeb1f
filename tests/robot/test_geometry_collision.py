"""The self-collision check by the URDF's own geometry (nlo_lab.robot.geometry_collision)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from nlo_lab.robot import load_robot
from nlo_lab.robot.geometry_collision import (
    DEPTH_TOLERANCE,
    LP_BATCH,
    GeometryCollision,
    overlap_depth,
    overlap_depths,
    overlap_prefilter,
    overlaps,
    polytope,
)


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


def random_poses(gen, count: int, reach: float) -> np.ndarray:
    T = np.repeat(np.eye(4)[None], count, 0)
    for k in range(count):
        q = gen.normal(size=4)
        T[k, :3, :3] = trimesh.transformations.quaternion_matrix(q / np.linalg.norm(q))[:3, :3]
    T[:, :3, 3] = gen.uniform(-reach, reach, (count, 3))
    return T


def edge_poses(a, b, gen, count: int):
    """``count`` pose pairs of polytopes ``a`` and ``b``: deep overlaps, clear gaps and, every third, b slid from a's
    origin to within a fraction of a mm of where the two part (either side of the 0.1 mm tolerance)."""
    Ta, Tb = random_poses(gen, count, 0.05), random_poses(gen, count, 0.05)
    for k in range(0, count, 3):
        lo, hi = 0.0, 1.0
        way = Tb[k, :3, 3] / max(np.linalg.norm(Tb[k, :3, 3]), 1e-9)
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            Tb[k, :3, 3] = mid * way * 0.2
            lo, hi = (mid, hi) if overlap_depth(a, Ta[k], b, Tb[k]) > 0 else (lo, mid)
        Tb[k, :3, 3] = (lo + (k % 7 - 3) * 2e-4) * way * 0.2
    return Ta, Tb


@pytest.mark.parametrize("shapes", [("box", "box"), ("cylinder", "sphere"), ("box", "cylinder")])
def test_the_prefilter_agrees_with_the_linear_programme(shapes):
    """The capsule draft's fast path settles the poses it can without the linear programme: wherever it says
    apart (-1) or overlapping (+1), overlaps() says the same; the poses span deep overlaps, shallow ones near the
    0.1 mm tolerance and clear gaps, so that both verdicts occur (and 0, left to the programme)."""
    make = {"box": lambda: trimesh.creation.box(extents=(0.12, 0.04, 0.03)),
            "cylinder": lambda: trimesh.creation.cylinder(radius=0.02, height=0.1, sections=64),
            "sphere": lambda: trimesh.creation.icosphere(subdivisions=3, radius=0.03)}
    a, b = polytope("a", make[shapes[0]]()), polytope("b", make[shapes[1]]())
    Ta, Tb = edge_poses(a, b, np.random.default_rng(3), 300)
    verdict = overlap_prefilter(a, Ta, b, Tb)
    truth = np.array([overlaps(a, Ta[k], b, Tb[k]) for k in range(len(Ta))])
    assert not truth[verdict < 0].any() and truth[verdict > 0].all()
    assert (verdict < 0).sum() > 20 and (verdict > 0).sum() > 20 and (verdict == 0).sum() > 0
    assert truth.any() and not truth.all()


def test_programmes_solved_as_one_give_each_pair_its_own_depth():
    """overlap_depths (the capsule draft's fast path) solves up to LP_BATCH pairs' linear programmes as one: each
    pair's depth is the one overlap_depth finds alone, for mixed shapes in one batch (boxes, cylinders, spheres, a
    pair apart by a face plane), more pairs than one batch holds, and poses at the overlap's edge."""
    make = [polytope("a", trimesh.creation.box(extents=(0.12, 0.04, 0.03))),
            polytope("b", trimesh.creation.cylinder(radius=0.02, height=0.1, sections=64)),
            polytope("c", trimesh.creation.icosphere(subdivisions=3, radius=0.03))]
    gen = np.random.default_rng(11)
    items = []
    for k in range(3 * LP_BATCH + 5):
        a, b = make[k % 3], make[(k // 3) % 3]
        Ta, Tb = (poses[0] for poses in edge_poses(a, b, gen, 1)) if k % 3 == 0 else random_poses(gen, 2, 0.05)
        items.append((a, Ta, b, Tb))
    items.append((make[0], moved(), make[0], moved(x=0.5)))  # far apart
    alone = np.array([overlap_depth(*item) for item in items])
    together = overlap_depths(items)
    assert together.shape == (len(items),)
    np.testing.assert_allclose(together, alone, rtol=0, atol=1e-9)
    assert ((together > DEPTH_TOLERANCE) == (alone > DEPTH_TOLERANCE)).all()
    assert (alone > DEPTH_TOLERANCE).sum() > 10 and (alone == 0).sum() > 10
    assert len(overlap_depths([])) == 0


def test_programmes_solved_as_one_fall_back_to_one_by_one_when_the_joint_programme_fails(monkeypatch):
    """Should HiGHS not solve the joint programme (any status but optimal), each pair is solved alone: the same depths."""
    import scipy.optimize

    box = polytope("a", trimesh.creation.box(extents=(0.1, 0.1, 0.1)))
    items = [(box, moved(), box, moved(x=0.1 + gap)) for gap in (-0.03, -0.01, 0.004, -0.002)]
    real = scipy.optimize.linprog
    calls = []

    def failing_when_joint(c, **kwargs):
        calls.append(len(c))
        res = real(c, **kwargs)
        if len(c) > 4:
            res.status = 4  # numerical difficulties
        return res

    monkeypatch.setattr(scipy.optimize, "linprog", failing_when_joint)
    np.testing.assert_allclose(overlap_depths(items), [0.03, 0.01, 0.0, 0.002], atol=1e-7)
    assert calls[0] == 4 * 3 and calls[1:] == [4, 4, 4]  # the joint programme (the apart pair left out), then one by one


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


def test_a_spec_s_shape_contacts_are_left_out_and_must_name_real_links(tmp_path):
    """``"shape_contacts"``: link pairs whose collision elements meet where the parts do not (robot init names them);
    the check leaves them out as it leaves out an SRDF's disabled pairs. A misspelt link is one clear error."""
    from nlo_lab.errors import RobotDescriptionError

    two_link_arm(tmp_path)
    spec = tmp_path / "fold.json"
    data = json.loads(spec.read_text())
    spec.write_text(json.dumps({**data, "shape_contacts": [["base", "fore"]]}))
    check = GeometryCollision(load_robot(spec))
    assert len(check.pairs) == 0 and check.report(np.array([[0.0, 2.0]]))["frames"] == 0  # folded into the base: left out
    spec.write_text(json.dumps({**data, "shape_contacts": [["base", "forearm"]]}))
    with pytest.raises(RobotDescriptionError, match="shape_contacts names link 'forearm'.*closest: fore"):
        load_robot(spec)
    spec.write_text(json.dumps({**data, "shape_contacts": [["base"]]}))
    with pytest.raises(RobotDescriptionError, match="shape_contacts"):
        load_robot(spec)


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


def test_the_prefilters_plane_test_pruned_by_bounding_spheres_is_the_all_planes_test():
    """The prefilter asks whether all corners of one polytope lie beyond a face plane of the other; it measures the
    corners only against the planes the bounding sphere leaves open. Same answer as measuring every plane: one plane
    placed 1 nm or 1 mm above or below the corners' least value, or far below (so that each answer turns on it), the
    others short of them by 1 mm to 1 m; posed and unposed corners."""
    from nlo_lab.robot.geometry_collision import PREFILTER_SLACK, _beyond_a_face

    gen = np.random.default_rng(5)
    shapes = [polytope("a", trimesh.creation.icosphere(subdivisions=2, radius=0.04)),
              polytope("a", trimesh.creation.box(extents=(0.12, 0.04, 0.03))),
              polytope("a", trimesh.creation.cylinder(radius=0.02, height=0.1, sections=32))]
    answers = []
    for k in range(500):
        p = shapes[k % 3]
        T = random_poses(gen, 1, 0.1)[0]
        posed = p.vertices @ T[:3, :3].T + T[:3, 3]
        normals = gen.normal(size=(40, 3))
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        least = (posed @ normals.T).min(0)
        above = gen.uniform(1e-3, 1.0, 40)  # how far each plane's threshold lies above the corners' least value
        above[gen.integers(40)] = (-1e-9, 1e-9, -1e-3, 1e-3, -0.5)[(k // 3) % 5]  # the one that decides
        offsets = least + above + DEPTH_TOLERANCE - PREFILTER_SLACK
        exhaustive = bool((least >= offsets - DEPTH_TOLERANCE + PREFILTER_SLACK).any())
        centre = T[:3, :3] @ p.centre + T[:3, 3]
        assert _beyond_a_face(normals, offsets, p.vertices, centre, p.radius, (T[:3, :3], T[:3, 3])) == exhaustive
        assert _beyond_a_face(normals, offsets, posed, centre, p.radius) == exhaustive
        answers.append(exhaustive)
    assert sum(answers) == sum((k // 3) % 5 in (0, 2, 4) for k in range(500))  # the deciding plane below the least value


def test_the_quick_apart_is_every_face_plane_against_every_corner():
    """overlap_depth's quick "apart" (a face plane of one polytope with all the other's corners beyond it, less the
    tolerance) measures only the corners and planes its bounding spheres and witnesses leave open, in one polytope's
    frame: the same answer as every posed corner against every posed plane, on edge poses where the answer turns on
    fractions of a millimetre."""
    from nlo_lab.robot.geometry_collision import _face_separated

    def exhaustive(a, Ta, b, Tb):
        for p, Tp, o, To in ((a, Ta, b, Tb), (b, Tb, a, Ta)):
            n = p.normals @ Tp[:3, :3].T
            corners = o.vertices @ To[:3, :3].T + To[:3, 3]
            if ((corners @ n.T).min(0) >= p.offsets + n @ Tp[:3, 3] - DEPTH_TOLERANCE).any():
                return True
        return False

    gen = np.random.default_rng(11)
    shapes = [polytope("a", trimesh.creation.icosphere(subdivisions=2, radius=0.04)),
              polytope("b", trimesh.creation.box(extents=(0.12, 0.04, 0.03))),
              polytope("c", trimesh.creation.cylinder(radius=0.02, height=0.1, sections=32))]
    answers = []
    for a, b in [(shapes[0], shapes[1]), (shapes[1], shapes[2]), (shapes[2], shapes[0]), (shapes[1], shapes[1])]:
        for Ta, Tb in zip(*edge_poses(a, b, gen, 120), strict=True):
            answers.append(exhaustive(a, Ta, b, Tb))
            assert _face_separated(a, Ta, b, Tb) == answers[-1]
    assert 0.2 < np.mean(answers) < 0.8  # both answers, many times


def test_the_checks_depths_are_each_pairs_own_programme():
    """GeometryCollision.depths solves the near pairs' programmes together (overlap_depths): each depth is the one
    overlap_depth gives that pair alone, on NAO's collision meshes in random poses within its limits."""
    import torch

    robot = load_robot("nao")
    check = GeometryCollision(robot)
    lower, upper = robot.lower_limits.double().numpy(), robot.upper_limits.double().numpy()
    q = np.random.default_rng(2).uniform(lower, upper, (12, len(lower)))
    depths = check.depths(q)
    with torch.no_grad():
        T = robot.forward_kinematics_tensor(torch.as_tensor(q)).numpy()
    index = [robot.link_index(p.link) for p in check.pieces]
    alone = np.array([[overlap_depth(check.pieces[i], T[t, index[i]], check.pieces[j], T[t, index[j]]) for i, j in check.pairs]
                      for t in range(len(q))])
    np.testing.assert_allclose(depths, alone, rtol=0, atol=1e-9)
    assert (depths > DEPTH_TOLERANCE).sum() >= 3  # collisions to compare, not only zeros

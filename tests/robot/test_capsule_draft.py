"""Capsules and checked pairs drafted from a URDF's geometry (nlo_lab.robot.capsule_draft), on the bundled robots."""

from __future__ import annotations

import importlib.util
import json
import warnings

import numpy as np
import pytest
import torch

from nlo_lab.paths import ROBOTS_DIR
from nlo_lab.robot import load_robot
from nlo_lab.robot.geometry import link_shapes, shape_mesh

ROBOTS = ("yumi", "nao", "pepper")


def held(points: np.ndarray, caps) -> np.ndarray:
    out = np.zeros(len(points), dtype=bool)
    for c in caps:
        a, b = np.array(c.p0), np.array(c.p1)
        ab = b - a
        t = np.clip((points - a) @ ab / max(ab @ ab, 1e-18), 0, 1)
        out |= np.linalg.norm(points - (a + t[:, None] * ab), axis=1) <= c.radius + 1e-6
    return out


@pytest.mark.parametrize("name", ROBOTS)
def test_capsules_hold_every_collision_element(name):
    """Links fixed to a moving body share that body's capsules (on its first link): YuMi's hand base on link 7."""
    robot = load_robot(name)
    tree = robot.tree
    caps = [c for c in robot.spec.capsules if "~" not in c.name]  # thinned copies are for one pair each
    first = {}
    for i, link in enumerate(tree.link_names):
        if np.allclose(tree.link_const[i], np.eye(4)):
            first.setdefault(tree.link_body[i], link)
    for shape in link_shapes(robot.model, "collision"):
        i = tree.link_index[shape.link]
        owner, T = (shape.link, np.eye(4)) if tree.link_body[i] == 0 else (first[tree.link_body[i]], tree.link_const[i])
        v = np.asarray(shape_mesh(shape).vertices) @ T[:3, :3].T + T[:3, 3]  # in the owner's frame
        ok = held(v, [c for c in caps if c.link == owner])
        assert ok.all(), (name, shape.link, int((~ok).sum()))


@pytest.mark.parametrize("name", ROBOTS)
def test_every_pair_clears_its_margin_at_the_neutral_pose(name):
    robot = load_robot(name).to(dtype=torch.float64)
    d = robot.capsule_distances(robot.forward_kinematics(robot.neutral_q[None]))[0]
    assert bool((d > robot.collision_margins).all())  # the collision term is silent at rest


def test_nao_legs_and_pepper_base_are_checked_against_the_hands():
    for name, link in (("nao", "legs"), ("pepper", "base")):
        robot = load_robot(name)
        link_of = {c.name: c.link for c in robot.spec.capsules}
        pairs = {frozenset((link_of[a], link_of[b])) for a, b in robot.spec.collision_pairs}
        assert frozenset((link, "l_wrist")) in pairs and frozenset((link, "r_wrist")) in pairs, name


def test_a_finger_is_checked_against_its_own_palm_where_they_can_meet_and_not_against_the_rest():
    """A finger's outer links against their own palm where their geometry can meet (YuMi's thumb closed 3 mm into
    the hand base while that pair was left out; the other fingers never reach it); the body and the other arm
    meet the hand's envelope, not a finger."""
    robot = load_robot("yumi")
    link_of = {c.name: c.link for c in robot.spec.capsules}
    pairs = {frozenset((link_of[a], link_of[b])) for a, b in robot.spec.collision_pairs}
    for s in "lr":
        palm = f"yumi_link_7_{s}"  # the hand base is fixed to it: its capsules sit there
        assert frozenset((palm, f"yumi_hand_{s}_thumb_distal")) in pairs  # its geometry reaches the hand base
        assert frozenset((palm, f"yumi_hand_{s}_index_intermediate")) not in pairs  # never meets the palm: not checked
        assert frozenset((palm, f"yumi_hand_{s}_index_proximal")) not in pairs  # it hangs from the palm: adjacent
    for pair in pairs:
        fingers = [link for link in pair if link.startswith("yumi_hand_")]
        others = [link for link in pair if not link.startswith("yumi_hand_") and not link.startswith("yumi_link_7_")]
        assert not (fingers and others), sorted(pair)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["nao", "pepper"])
def test_the_specs_hold_what_the_fit_gives(name, capsule_ends_as_written):
    """fit_capsules.py wrote these specs; the fit is deterministic but for which end of a capsule comes first (YuMi:
    tests/robot/test_yumi.py)."""
    spec = importlib.util.spec_from_file_location("fit_capsules", ROBOTS_DIR / "fit_capsules.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    written = json.loads((ROBOTS_DIR / f"{name}.json").read_text())
    expected = {k: written[k] for k in ("capsules", "collision_pairs", "collision_margin")}
    assert capsule_ends_as_written(module.fit(name), expected) == expected


def test_capsule_ends_as_written_forgives_only_the_order_of_the_ends(capsule_ends_as_written):
    capsule = {"name": "a", "link": "l", "p0": [0.0, 0.0, 0.0], "p1": [0.0, 0.0, 1.0], "radius": 0.1}
    written = {"capsules": [capsule], "collision_pairs": []}
    swapped = {"capsules": [{**capsule, "p0": capsule["p1"], "p1": capsule["p0"]}], "collision_pairs": []}
    assert swapped != written and capsule_ends_as_written(swapped, written) == written
    for other in ({**capsule, "p0": [0.0, 0.0, 1.0], "p1": [0.0, 0.0, 0.5]}, {**capsule, "radius": 0.2},
                  {**capsule, "p0": capsule["p1"], "p1": capsule["p0"], "radius": 0.2}, {**capsule, "name": "b"}):
        assert capsule_ends_as_written({"capsules": [other], "collision_pairs": []}, written) != written


def unseen_overlaps(robot, samples: int = 512, seed: int = 7) -> list[tuple[str, str, float]]:
    """``(link a, link b, depth)`` where two links checked with thinned capsules overlap by their URDF geometry
    (deeper than DEPTH_TOLERANCE) in random poses within the limits while none of their checked capsule pairs
    overlap: a collision the thinned capsules would hide. Poses drawn afresh (the draft used seed 0)."""
    from nlo_lab.robot import GeometryCollision
    from nlo_lab.robot.geometry_collision import DEPTH_TOLERANCE, overlap_depth

    robot = robot.to(dtype=torch.float64)
    links = set(robot.model.links)

    def group(name: str) -> str:  # the link whose geometry a capsule holds: LINK, LINK_2, LINK~3mm, LINK_2~3mm
        stem = name.split("~")[0]
        return stem if stem in links else stem.rsplit("_", 1)[0]

    link_of = {c.name: group(c.name) for c in robot.spec.capsules}
    pair_links = [frozenset((link_of[a], link_of[b])) for a, b in robot.spec.collision_pairs]
    thinned = {p for p, (a, b) in zip(pair_links, robot.spec.collision_pairs, strict=True) if "~" in a + b and len(p) == 2}
    gen = np.random.default_rng(seed)
    lo, hi = robot.lower_limits.double().numpy(), robot.upper_limits.double().numpy()
    q = torch.as_tensor(lo + (hi - lo) * gen.random((samples, len(lo))))
    gaps = robot.capsule_distances(robot.forward_kinematics(q)).numpy()  # (S, P)
    with torch.no_grad():
        T = robot.forward_kinematics_tensor(q).numpy()
    pieces = GeometryCollision(robot).pieces
    out = []
    for links in thinned:
        la, lb = sorted(links)
        cols = [k for k, p in enumerate(pair_links) if p == links]
        ia, ib = robot.link_index(la), robot.link_index(lb)
        for s in np.nonzero(gaps[:, cols].min(1) >= 0)[0]:  # the capsules say apart: is the geometry?
            depth = max((overlap_depth(u, T[s, ia], v, T[s, ib]) for u in pieces if u.link == la for v in pieces if v.link == lb), default=0.0)
            if depth > DEPTH_TOLERANCE:
                out.append((la, lb, depth))
    return out


def test_thinned_capsules_hide_no_collision_of_their_geometry():
    """A thinned capsule no longer holds all its geometry; the draft thins a pair at most what still lets the
    capsules overlap wherever the links' geometry does (NAO's torso and left upper arm were thinned 10 mm, more
    than their geometry allows: 8 mm now, and a narrower margin)."""
    robot = load_robot("nao")
    assert any("~" in a + b for a, b in robot.spec.collision_pairs)
    assert unseen_overlaps(robot) == []


@pytest.fixture(scope="module")
def tiago_draft(robot_data, tmp_path_factory):
    from nlo_lab.robot.spec_draft import draft_spec

    hands = {s: {"thumb": f"hand_{s}_thumb_flex_2_link", "index": f"hand_{s}_index_flex_3_link", "middle": f"hand_{s}_middle_flex_3_link"}
             for s in ("left", "right")}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # any default the draft assumes: not what this test is about
        return draft_spec(robot_data / "tiago_description/robots/tiago_dual.urdf", tmp_path_factory.mktemp("tiago") / "tiago.json",
                          left_hand=hands["left"], right_hand=hands["right"])


@pytest.mark.slow
def test_tiago_fingers_cannot_close_into_the_palm_unseen(tiago_draft):
    """TIAGo's fingers closed 1.4 mm into the palm (its URDF's geometry) past capsules thinned 8 mm each. Only the pairs
    the draft names as blind (capsules too loose to tell rest from collision) or as shape contacts may still hide an
    overlap: the left thumb's base and first phalanx, 0.2 mm apart at rest, whose collision shapes overlap by up to
    0.56 mm once the thumb bends (its base's collision mesh is mirrored across y, its visual mesh and its joint across
    z); their visual shapes never do, nor do the right thumb's collision shapes."""
    draft = tiago_draft
    contacts = {frozenset(p) for p in draft.collision.shape_contacts}
    assert contacts == {frozenset(("hand_left_thumb_abd_link", "hand_left_thumb_flex_1_link"))}
    assert [sorted(p) for p in draft.spec["shape_contacts"]] == [sorted(p) for p in contacts]
    assert any("shape_contacts" in n for n in draft.notes)
    blind = {frozenset(p) for p in draft.collision.blind}
    assert not blind & contacts and all("thumb" in "".join(p) for p in blind), blind
    hidden = [h for h in unseen_overlaps(draft.robot) if frozenset(h[:2]) not in blind | contacts]
    assert hidden == []
    names = {n for p in draft.robot.spec.collision_pairs for n in p}
    for s in ("left", "right"):  # the palm and the first phalanges, seen by their own capsules (the palm's sit on the wrist)
        for finger in ("index", "middle"):
            assert any(p[0].startswith(f"hand_{s}_palm_link") and p[1].startswith(f"hand_{s}_{finger}_flex_1_link")
                       for p in draft.robot.spec.collision_pairs), (s, finger)
    assert names


def test_the_fast_draft_equals_the_readable_one(tmp_path):
    """The prefilter (a vectorised test before each linear programme) and the pruned weighing of cuts change how fast
    a spec is drafted, not what it says: NAO (thinned pairs, narrowed margins) drafted both ways."""
    from nlo_lab.robot.spec_draft import draft_spec

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fast, readable = (draft_spec(ROBOTS_DIR / "nao.urdf", tmp_path / "nao.json", samples=200, prefilter=p).spec for p in (True, False))
    assert any("~" in a + b for a, b in fast["collision_pairs"])  # the thinning bound was at work
    assert {k: fast[k] for k in ("capsules", "collision_pairs", "collision_margin")} == \
        {k: readable[k] for k in ("capsules", "collision_pairs", "collision_margin")}


def test_a_thinning_bound_stopped_at_a_bar_says_the_same_as_one_searched_to_the_end(tmp_path):
    """_refine asks only whether a cut's pair beats the best so far: the bound's search stops once it falls below
    the bar (it only falls as the search goes on). Stopped or not, the verdict against the bar is the same, and an
    unstopped search returns the bound itself: a forearm folding onto its base, four bars around its value."""
    from nlo_lab.robot.capsule_draft import _path_joints, _path_poses, _thinning_bound
    from nlo_lab.robot.capsule_fit import fit_link_capsules

    (tmp_path / "fold.urdf").write_text("""<robot name="fold">
  <link name="base"><collision><origin xyz="0 0 -0.1"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  <link name="upper"><collision><origin xyz="0.075 0 0"/><geometry><box size="0.15 0.04 0.04"/></geometry></collision></link>
  <link name="fore"><collision><origin xyz="0.075 0 0"/><geometry><cylinder radius="0.02" length="0.15"/></geometry></collision></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.05"/>
    <axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" velocity="1" effort="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0.15 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-3.0" upper="3.0" velocity="1" effort="1"/></joint>
</robot>""")
    (tmp_path / "fold.json").write_text(json.dumps({
        "name": "fold", "urdf": "fold.urdf", "base_link": "base", "actuated_joints": ["shoulder", "elbow"],
        "arms": {side: {"shoulder": "upper", "elbow": "fore", "wrist": "fore"} for side in ("left", "right")}}))
    robot = load_robot(tmp_path / "fold.json")
    tree = robot.tree
    hulls = {s.link: shape_mesh(s).convex_hull for s in link_shapes(robot.model, "collision")}
    a, b = fit_link_capsules("base", [hulls["base"]])[0], fit_link_capsules("fore", [hulls["fore"]])[0]
    q0 = robot.reference_q.double().numpy()
    lo, hi = robot.lower_limits.double().numpy(), robot.upper_limits.double().numpy()
    sample = _path_poses(tree, _path_joints(tree, "base", "fore"), q0, lo, hi, 0)
    full = _thinning_bound(tree, sample, a, b)
    assert np.isfinite(full) and full > 0  # the folded forearm reaches the base: a finite bound
    for bar in (full - 0.01, full - 1e-4, full + 1e-4, full + 0.01):
        stopped = _thinning_bound(tree, sample, a, b, below=bar)
        assert (stopped < bar) == (full < bar), bar
        assert stopped >= full - 1e-12  # the search only lowers the bound: stopped early, it is no lower
        if full >= bar:
            assert stopped == full

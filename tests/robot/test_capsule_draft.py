"""Capsules and checked pairs drafted from a URDF's geometry (nlo_lab.robot.capsule_draft), on the bundled robots."""

from __future__ import annotations

import importlib.util
import json

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
def test_the_specs_hold_what_the_fit_gives(name):
    """fit_capsules.py wrote these specs; the fit is deterministic (YuMi: tests/robot/test_yumi.py)."""
    spec = importlib.util.spec_from_file_location("fit_capsules", ROBOTS_DIR / "fit_capsules.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    written = json.loads((ROBOTS_DIR / f"{name}.json").read_text())
    assert module.fit(name) == {k: written[k] for k in ("capsules", "collision_pairs", "collision_margin")}

"""benchmarks/hands.py's self-collision count: the hand-frames where a hand overlaps itself by yumi.urdf's
collision geometry (dex-retargeting does not avoid it; the count is what makes the methods' figures comparable)."""

from __future__ import annotations

import numpy as np
import pytest

from nlo_lab.evaluation.hands import hand_joint_indices
from nlo_lab.robot import load_robot
from nlo_lab.robot.geometry_collision import GeometryCollision


@pytest.fixture(scope="module")
def hands(checkout_script):
    return checkout_script("benchmarks/hands.py")


@pytest.fixture(scope="module")
def yumi():
    robot = load_robot("yumi")
    return robot, GeometryCollision(robot)


def test_own_hand_pairs_join_two_links_of_one_hand(hands, yumi):
    robot, geometry = yumi
    own = hands.own_hand_pairs(robot, geometry)
    for s, side in enumerate(("left", "right")):
        below = set(robot.model.subtree(robot.arm(side).wrist))
        links = {geometry.pieces[k].link for pair in geometry.pairs[own[s]] for k in pair}
        assert links and links <= below
        assert any("thumb" in link for link in links) and any("index" in link for link in links)
    assert not (own[0] & own[1]).any()


def test_a_fist_with_the_thumb_across_counts_on_its_hand_only(hands, yumi):
    robot, geometry = yumi
    open_hand = robot.neutral_q.double().numpy()
    fist = open_hand.copy()
    left = hand_joint_indices(robot, "left")
    fist[left] = robot.upper_limits.double().numpy()[left]  # every left finger and the thumb closed: the thumb goes through the index
    q = np.stack([open_hand, fist])
    both = np.ones((2, 2), dtype=bool)
    frames, deepest = hands.hand_collisions(geometry, hands.own_hand_pairs(robot, geometry), q, both)
    assert frames == 1 and deepest > 0.005
    right_only = np.array([[False, True], [False, True]])
    assert hands.hand_collisions(geometry, hands.own_hand_pairs(robot, geometry), q, right_only) == (0, 0.0)
    # per hand-frame, in hand_scores' row order (frame-major): only frame 1's left hand goes through itself
    depth = hands.hand_frame_depths(geometry, hands.own_hand_pairs(robot, geometry), q, both)
    assert list(depth > 0.005) == [False, False, True, False]


def test_the_hand_refinement_moves_only_the_hand_joints_within_their_limits_and_lowers_the_objective(hands, yumi):
    import torch

    from nlo_lab.human import load_demonstration
    from nlo_lab.inference import smoothness_term
    from nlo_lab.objective import LossWeights, Objective, targets_from_demonstration

    robot, _ = yumi
    demo = load_demonstration(hands.RECORDINGS / "holistic_both_hands_47f.pose").slice(10, 16)
    q = np.tile(robot.neutral_q.double().numpy(), (len(demo), 1))  # an open hand: far from the signer's
    weights = LossWeights()
    refined = hands.refine_hands(robot, q, demo, weights)
    hand = [i for side in ("left", "right") for i in hand_joint_indices(robot, side)]
    arms = np.setdiff1d(np.arange(robot.n_joints), hand)
    assert np.allclose(refined[:, arms], q[:, arms], atol=1e-6)  # float32 round trip
    assert np.abs(refined[:, hand] - q[:, hand]).max() > 0.05
    lo, hi = robot.lower_limits.double().numpy(), robot.upper_limits.double().numpy()
    assert ((refined >= lo - 1e-6) & (refined <= hi + 1e-6)).all()
    targets = targets_from_demonstration(demo, dtype=robot.lower_limits.dtype)
    loss, smooth = Objective(robot, targets, weights), smoothness_term(robot, targets, weights)

    def total(x):
        x = torch.as_tensor(x, dtype=robot.lower_limits.dtype)
        return float((loss(x)[0] + smooth(x)).sum())

    assert total(refined) < 0.9 * total(q)

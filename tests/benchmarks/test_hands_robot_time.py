"""benchmarks/hands.py's robot time: each method's output retimed to the joint velocity limits, dex-retargeting's hands on
nlo_lab's arms (held while a hand is not seen)."""

from __future__ import annotations

import numpy as np
import pytest

from nlo_lab.evaluation.hands import hand_frames_mask
from nlo_lab.robot import load_robot


@pytest.fixture(scope="module")
def hands(checkout_script):
    return checkout_script("benchmarks/hands.py")


@pytest.fixture(scope="module")
def yumi():
    return load_robot("yumi")


def test_a_still_robot_takes_the_recording_s_time_and_a_jump_takes_its_slowest_joint_s(hands, yumi):
    T, fps = 5, 25.0
    q = np.tile(yumi.neutral_q.double().numpy(), (T, 1))
    assert hands.robot_seconds(yumi, q, fps) == pytest.approx(T / fps)
    j = hands.hand_joints(yumi)[1][2]  # the right index
    q[3:, j] += 1.0  # one 1-rad step between frames 2 and 3
    v = float(yumi.velocity_limits[j])
    assert hands.robot_seconds(yumi, q, fps) == pytest.approx((T - 1) / fps + 1.0 / v, rel=1e-6)


def test_dex_hands_go_on_the_arms_in_seen_frames_and_are_held_between(hands, yumi, demonstration_from_robot, random_feasible_pose):
    q = random_feasible_pose(yumi, 6, seed=3).double()
    demo = demonstration_from_robot(yumi, q)
    seen = np.ones((6, 2), dtype=bool)
    seen[[0, 3, 4], 1] = False  # the right hand unseen in frames 0, 3 and 4
    demo.finger_mask[~seen] = False
    assert (hand_frames_mask(demo) == seen).all()
    arms = np.zeros((6, yumi.n_joints))
    dex = np.arange(6, dtype=np.float64)[:, None] + np.zeros((6, yumi.n_joints))  # frame t: every joint t
    out = hands.on_arms(yumi, demo, arms, dex)
    left, right = hands.hand_joints(yumi)[0], hands.hand_joints(yumi)[1]
    assert (out[:, left] == np.arange(6)[:, None]).all()
    assert (out[:, right] == np.array([0, 1, 2, 2, 2, 5])[:, None]).all()  # frame 0: the arms' own; 3, 4: frame 2's
    others = np.setdiff1d(np.arange(yumi.n_joints), left + right)
    assert (out[:, others] == 0).all()

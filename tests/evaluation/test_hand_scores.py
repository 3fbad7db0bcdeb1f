"""The handshape scorer (nlo_lab.evaluation.hands, used by benchmarks/hands.py) on hands posed by hand,
where each error is known exactly."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.evaluation.hands import HandScores, angle_deg, hand_frames_mask, hand_scores
from nlo_lab.robot import load_robot


@pytest.fixture(scope="module")
def yumi():
    return load_robot("yumi").to(dtype=torch.float64)


def hand_poses(robot, T=12, seed=0) -> torch.Tensor:
    """Neutral arms, hands from open to closed with a different mix per frame."""
    g = np.random.default_rng(seed)
    q = robot.neutral_q[None].repeat(T, 1).clone()
    hand = [i for i, n in enumerate(robot.joint_names) if "_hand_" in n]
    lo, hi = robot.lower_limits[hand].numpy(), robot.upper_limits[hand].numpy()
    q[:, hand] = torch.as_tensor(lo + (hi - lo) * g.uniform(0.05, 0.95, (T, len(hand))))
    return q


def turned(u: np.ndarray, angle_deg_: float) -> np.ndarray:
    """Unit vectors ``u (..., 3)`` turned by exactly ``angle`` towards a perpendicular direction."""
    u = u / np.linalg.norm(u, axis=-1, keepdims=True)
    w = np.cross(u, [0.3, -0.5, 0.8])
    w /= np.linalg.norm(w, axis=-1, keepdims=True)
    a = np.radians(angle_deg_)
    return np.cos(a) * u + np.sin(a) * w


def test_angle_deg():
    assert angle_deg(np.array([1.0, 0, 0]), np.array([0, 2.0, 0])) == pytest.approx(90.0)
    assert angle_deg(np.array([1.0, 0, 0]), np.array([-1.0, 1e-9, 0])) == pytest.approx(180.0)
    assert angle_deg(np.array([1.0, 1, 0]), np.array([3.0, 3, 0])) == pytest.approx(0.0, abs=1e-6)


def test_a_perfect_match_scores_zero_and_full_pinch_correlation(yumi, demonstration_from_robot):
    q = hand_poses(yumi)
    s = hand_scores(yumi, q.numpy(), demonstration_from_robot(yumi, q))
    assert len(s) == 2 * len(q)
    summary = s.summary()
    assert summary["tip_deg"] < 1e-6 and summary["thumb_deg"] < 1e-5 and summary["finger_deg"] < 1e-6
    assert summary["pinch_r"] == pytest.approx(1.0)
    np.testing.assert_allclose(s.pinch_human, s.pinch_robot, rtol=1e-9)


@pytest.mark.parametrize("alpha", [7.0, 30.0, 95.0])
def test_fingertips_turned_about_the_wrist_by_a_known_angle(yumi, alpha, demonstration_from_robot):
    q = hand_poses(yumi, seed=1)
    demo = demonstration_from_robot(yumi, q)
    wrist = demo.arm_positions[:, :, 2][:, :, None]  # (T, 2, 1, 3)
    v = demo.finger_positions[:, :, :, 1] - wrist
    demo.finger_positions[:, :, :, 1] = wrist + np.linalg.norm(v, axis=-1, keepdims=True) * turned(v, alpha)
    s = hand_scores(yumi, q.numpy(), demo)
    np.testing.assert_allclose(s.tip, alpha, atol=1e-6)  # every finger off by alpha: the mean is alpha
    assert s.summary()["tip_deg"] == pytest.approx(alpha)
    assert s.summary()["thumb_deg"] > 0.1  # the tips moved against each other too


@pytest.mark.parametrize("finger", range(5))
def test_one_fingertip_turned_shows_in_its_own_column(yumi, finger, demonstration_from_robot):
    q = hand_poses(yumi, seed=3)
    demo = demonstration_from_robot(yumi, q)
    wrist = demo.arm_positions[:, :, 2]  # (T, 2, 3)
    v = demo.finger_positions[:, :, finger, 1] - wrist
    demo.finger_positions[:, :, finger, 1] = wrist + np.linalg.norm(v, axis=-1, keepdims=True) * turned(v, 20.0)
    s = hand_scores(yumi, q.numpy(), demo)
    expected = np.zeros(5)
    expected[finger] = 20.0
    np.testing.assert_allclose(s.tip_fingers, np.broadcast_to(expected, s.tip_fingers.shape), atol=1e-6)
    np.testing.assert_allclose(s.tip_per_finger(), expected, atol=1e-6)
    np.testing.assert_allclose(s.tip, 4.0, atol=1e-6)  # the mean over the five fingers
    assert s.summary()["tip_deg"] == pytest.approx(4.0)


def test_per_finger_means_survive_pooling_and_are_nan_without_hand_frames(yumi, demonstration_from_robot):
    q = hand_poses(yumi, seed=4)
    a = hand_scores(yumi, q[:5].numpy(), demonstration_from_robot(yumi, q[:5]))
    b = hand_scores(yumi, q[5:].numpy(), demonstration_from_robot(yumi, q[5:]))
    both = HandScores.cat([a, b])
    assert both.tip_fingers.shape == (len(a) + len(b), 5)
    empty = HandScores(**{f.name: getattr(a, f.name)[:0] for f in dataclasses.fields(HandScores)})
    assert np.isnan(empty.tip_per_finger()).all() and empty.tip_per_finger().shape == (5,)


@pytest.mark.parametrize("beta", [10.0, 45.0])
def test_finger_bases_moved_change_only_the_base_tip_measure(yumi, beta, demonstration_from_robot):
    q = hand_poses(yumi, seed=2)
    demo = demonstration_from_robot(yumi, q)
    base, tip = demo.finger_positions[:, :, :, 0], demo.finger_positions[:, :, :, 1]
    demo.finger_positions[:, :, :, 0] = tip - np.linalg.norm(tip - base, axis=-1, keepdims=True) * turned(tip - base, beta)
    s = hand_scores(yumi, q.numpy(), demo)
    summary = s.summary()
    assert summary["finger_deg"] == pytest.approx(beta)
    assert summary["tip_deg"] < 1e-6 and summary["thumb_deg"] < 1e-5  # tips untouched
    for side in (0, 1):  # each hand's length changed by a factor of its own: per hand the pinch still correlates fully
        left = s.side == side
        assert np.corrcoef(s.pinch_human[left], s.pinch_robot[left])[0, 1] == pytest.approx(1.0)
    assert summary["pinch_r"] < 1.0


def test_pinch_correlation_of_an_opposite_pinch_is_minus_one(yumi, demonstration_from_robot):
    q = hand_poses(yumi, seed=3)
    demo = demonstration_from_robot(yumi, q)
    tip = demo.finger_positions[:, :, :, 1]
    robot_d = np.linalg.norm(tip[:, :, 1] - tip[:, :, 0], axis=-1)  # (T, 2) [m]
    direction = turned(tip[:, :, 0] - tip[:, :, 1], 0.0)
    # the human's thumb tip now sits the robot's distance from the index tip, reversed: 0.2 m - d
    demo.finger_positions[:, :, 0, 1] = tip[:, :, 1] + (0.2 - robot_d)[..., None] * direction
    s = hand_scores(yumi, q.numpy(), demo)
    assert s.pinch_correlation() == pytest.approx(-1.0)


def test_only_hand_frames_count(yumi, demonstration_from_robot):
    q = hand_poses(yumi, T=6, seed=4)
    demo = demonstration_from_robot(yumi, q)
    demo.finger_mask[2, 0, 3] = False  # left ring finger unseen in frame 2: not a hand-frame
    demo.finger_positions[2, 0, 3] = np.nan
    demo.wrist_mask[4, 1] = False  # right wrist frame unseen in frame 4
    demo.wrist_rotations[4, 1] = np.nan
    assert hand_frames_mask(demo).sum() == 10
    s = hand_scores(yumi, q.numpy(), demo)
    assert len(s) == 10 and s.summary()["tip_deg"] < 1e-6
    assert (2, 0) not in set(zip(s.frame, s.side, strict=True)) and (4, 1) not in set(zip(s.frame, s.side, strict=True))


def test_bad_input_is_named(yumi, demonstration_from_robot):
    q = hand_poses(yumi, T=3)
    demo = demonstration_from_robot(yumi, q)
    with pytest.raises(SettingsError, match="do not fit"):
        hand_scores(yumi, q.numpy()[:, :5], demo)
    nao = load_robot("nao")
    with pytest.raises(SettingsError, match="no fingers"):
        hand_scores(nao, np.zeros((3, nao.n_joints)), demo)


def test_the_summarys_hand_keys_are_the_scorers_means(yumi, demonstration_from_robot):
    """``hand_summary`` (the retargeting summary's hand keys) names the scorer's means; a hand turned by a known angle
    shows in ``wrist_tip_deg``."""
    from nlo_lab.metrics import HAND_KEYS, hand_summary

    q = hand_poses(yumi, seed=7)
    demo = demonstration_from_robot(yumi, q)
    perfect = hand_summary(yumi, q.numpy(), demo)
    assert tuple(perfect) == HAND_KEYS and perfect["hand_frames"] == 2 * len(q)
    assert perfect["wrist_tip_deg"] < 1e-6 and perfect["base_tip_deg"] < 1e-6 and perfect["pinch_r"] == pytest.approx(1.0)
    other = hand_poses(yumi, seed=8)  # the robot's hands elsewhere: every measure as the scorer has it
    got, s = hand_summary(yumi, other.numpy(), demo), hand_scores(yumi, other.numpy(), demo).summary()
    assert got == {"hand_frames": s["hand_frames"], "wrist_tip_deg": s["tip_deg"], "thumb_tips_deg": s["thumb_deg"],
                   "base_tip_deg": s["finger_deg"], "pinch_r": s["pinch_r"]}
    assert got["wrist_tip_deg"] > 1.0


def test_the_summarys_hand_keys_without_hands_to_score(yumi, demonstration_from_robot):
    from nlo_lab.metrics import HAND_KEYS, hand_summary

    nao = load_robot("nao")
    q = nao.neutral_q[None].repeat(4, 1)
    assert hand_summary(nao, q.numpy(), demonstration_from_robot(nao, q)) == dict.fromkeys(HAND_KEYS)  # no fingers
    q = hand_poses(yumi, T=4)
    demo = demonstration_from_robot(yumi, q)
    demo.finger_mask[:] = False  # no hand-frame: a count of 0, no measure (not NaN: the JSON has none)
    demo.finger_positions[:] = np.nan
    assert hand_summary(yumi, q.numpy(), demo) == {"hand_frames": 0, **dict.fromkeys(HAND_KEYS[1:])}

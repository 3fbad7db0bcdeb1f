"""Transforms of demonstrations: wrist frame, quaternions, gaps, arm-length normalisation, resampling, robot mapping."""

from __future__ import annotations

import numpy as np
import pytest

from nlo_lab.errors import DemonstrationError
from nlo_lab.human import map_to_robot, normalize_arm_lengths, resample, wrist_frame_from_hand
from nlo_lab.human.transforms import fill_gaps, matrix_to_quat, quat_to_matrix


# ---------------------------------------------------------------- wrist frame
def test_wrist_frame_axes_follow_the_convention():
    wrist = np.array([0.0, 0.0, 0.0])
    middle = np.array([0.1, 0.0, 0.0])  # along +x
    index = np.array([0.09, 0.03, 0.01])
    pinky = np.array([0.08, -0.03, 0.0])
    R = wrist_frame_from_hand(wrist, index, pinky, middle)
    np.testing.assert_allclose(R[:, 0], [1, 0, 0], atol=1e-12)  # x towards the middle base
    y = np.array([0.0, 0.06, 0.01]) / np.linalg.norm([0.0, 0.06, 0.01])  # pinky->index without its x part
    np.testing.assert_allclose(R[:, 1], y, atol=1e-12)
    np.testing.assert_allclose(R[:, 2], np.cross([1, 0, 0], y), atol=1e-12)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_wrist_frame_degenerate_is_nan():
    p = np.zeros(3)
    assert np.isnan(wrist_frame_from_hand(p, p, p, p)).all()


def test_quaternion_round_trip_and_known_value():
    rng = np.random.default_rng(1)
    R = quat_to_matrix(rng.normal(size=(50, 4)))  # random rotations
    np.testing.assert_allclose(quat_to_matrix(matrix_to_quat(R)), R, atol=1e-12)
    # 90 degrees about z: (x, y, z, w) = (0, 0, sin 45, cos 45) maps x to y
    Rz = quat_to_matrix(np.array([0, 0, np.sqrt(0.5), np.sqrt(0.5)]))
    np.testing.assert_allclose(Rz @ [1, 0, 0], [0, 1, 0], atol=1e-12)


# ---------------------------------------------------------------- gaps
def test_fill_gaps_interpolates_short_interior_gaps_only():
    v = np.arange(12, dtype=float)[:, None] * np.ones((1, 3))
    ok = np.ones(12, bool)
    ok[[0, 3, 4]] = False  # start gap (never filled) and a gap of 2
    ok[6:10] = False  # a gap of 4
    out, valid = fill_gaps(v, ok, max_gap=2)
    assert not valid[0] and np.isnan(out[0]).all()
    assert valid[3] and valid[4]
    np.testing.assert_allclose(out[3:5, 0], [3.0, 4.0])
    assert not valid[6:10].any() and np.isnan(out[6:10]).all()


# ---------------------------------------------------------------- arm lengths
def test_normalize_arm_lengths_sets_lengths_keeps_directions(make_demo):
    demo = make_demo()
    out = normalize_arm_lengths(demo, upper=0.2, fore=0.24)
    for side in ("left", "right"):
        S, E, W = (out.position(side, j) for j in ("shoulder", "elbow", "wrist"))
        np.testing.assert_allclose(np.linalg.norm(E - S, axis=1), 0.2, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(W - E, axis=1), 0.24, atol=1e-12)
        d_old = demo.position(side, "elbow") - demo.position(side, "shoulder")
        cos = np.sum((E - S) * d_old, -1) / (0.2 * np.linalg.norm(d_old, axis=-1))
        np.testing.assert_allclose(cos, 1.0, atol=1e-12)
        # the hand is scaled about the wrist by (0.44 / human arm length)
        hu, hf = demo.arm_lengths(side)
        rel_old = demo.fingers(side) - demo.position(side, "wrist")[:, None, None]
        rel_new = out.fingers(side) - W[:, None, None]
        np.testing.assert_allclose(rel_new, rel_old * 0.44 / (hu + hf), atol=1e-12)
    np.testing.assert_array_equal(out.wrist_rotations, demo.wrist_rotations)


def test_normalize_arm_lengths_masks_a_broken_chain(make_demo):
    demo = make_demo()
    demo.arm_mask[5, 0, 1] = False  # left elbow missing at frame 5
    demo.validate()
    out = normalize_arm_lengths(demo)
    assert not out.arm_mask[5, 0, 1] and not out.arm_mask[5, 0, 2]
    assert np.isnan(out.arm_positions[5, 0, 2]).all()
    assert not out.finger_mask[5, 0].any()
    assert out.arm_mask[4, 0].all()


def test_normalize_arm_lengths_rejects_bad_targets(make_demo):
    with pytest.raises(DemonstrationError):
        normalize_arm_lengths(make_demo(), upper=0.0)


# ---------------------------------------------------------------- resampling
def test_resample_identity_and_duration(make_demo):
    demo = make_demo(T=21, fps=10.0)
    same = resample(demo, 10.0)
    np.testing.assert_allclose(same.arm_positions, demo.arm_positions, atol=1e-12)
    np.testing.assert_allclose(same.wrist_rotations, demo.wrist_rotations, atol=1e-9)
    up = resample(demo, 30.0)
    assert len(up) == 61 and up.fps == 30.0
    np.testing.assert_allclose(up.arm_positions[::3], demo.arm_positions, atol=1e-12)
    # positions halfway are the mean of the neighbours (linear)
    half = resample(demo, 20.0)
    np.testing.assert_allclose(half.arm_positions[1], (demo.arm_positions[0] + demo.arm_positions[1]) / 2, atol=1e-12)


def test_resample_rotations_are_rotations_and_slerp_midpoint(make_demo):
    demo = make_demo(T=5, fps=10.0)
    Ra = quat_to_matrix(np.array([0, 0, 0, 1.0]))
    Rb = quat_to_matrix(np.array([0, 0, np.sin(0.5), np.cos(0.5)]))  # 1 rad about z
    demo.wrist_rotations[0, 0], demo.wrist_rotations[1, 0] = Ra, Rb
    out = resample(demo, 20.0)
    R = out.wrist_rotations[out.wrist_mask]
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
    mid = quat_to_matrix(np.array([0, 0, np.sin(0.25), np.cos(0.25)]))  # 0.5 rad
    np.testing.assert_allclose(out.wrist_rotations[1, 0], mid, atol=1e-9)


def test_resample_masks_need_both_neighbours(make_demo):
    demo = make_demo(T=10, fps=10.0)
    demo.arm_mask[4, 1, 2] = False
    demo.validate()
    out = resample(demo, 20.0)  # new frame k at original k/2
    assert out.arm_mask[6, 1, 2] and not out.arm_mask[7, 1, 2] and not out.arm_mask[8, 1, 2] and not out.arm_mask[9, 1, 2]
    assert out.arm_mask[10, 1, 2]
    assert np.isnan(out.arm_positions[7, 1, 2]).all()


@pytest.mark.parametrize("fps", [0.0, -5.0, float("nan")])
def test_resample_rejects_bad_fps(fps, make_demo):
    with pytest.raises(DemonstrationError, match="fps"):
        resample(make_demo(), fps)


# ---------------------------------------------------------------- robot mapping
class FakeRobot:
    def __init__(self):
        self.shoulders = {"left": np.array([0.0, 0.2, 0.5]), "right": np.array([0.0, -0.2, 0.5])}

    def zero_pose_lengths(self, side):
        return (0.1, 0.12) if side == "left" else (0.15, 0.15)

    def shoulder_position(self, side):
        import torch

        return torch.tensor(self.shoulders[side])


def test_map_to_robot_scales_about_the_shoulder(make_demo):
    demo = make_demo()
    robot = FakeRobot()
    out = map_to_robot(demo, robot)
    assert out.shape == (len(demo), 2, 3, 3)
    for s, side in enumerate(("left", "right")):
        hu, hf = demo.arm_lengths(side)
        k = sum(robot.zero_pose_lengths(side)) / (hu + hf)
        np.testing.assert_allclose(out[:, s, 0], np.broadcast_to(robot.shoulders[side], (len(demo), 3)), atol=1e-12)
        rel = demo.arm_positions[:, s] - demo.arm_positions[:, s, :1]
        np.testing.assert_allclose(out[:, s] - robot.shoulders[side], k * rel, atol=1e-12)
        # total arm length becomes the robot's
        length = np.linalg.norm(out[:, s, 1] - out[:, s, 0], axis=-1) + np.linalg.norm(out[:, s, 2] - out[:, s, 1], axis=-1)
        np.testing.assert_allclose(np.median(length), sum(robot.zero_pose_lengths(side)), rtol=0.05)


def test_map_to_robot_keeps_masked_points_nan(make_demo):
    demo = make_demo()
    demo.arm_mask[3, 0, 2] = False
    demo.validate()
    out = map_to_robot(demo, FakeRobot())
    assert np.isnan(out[3, 0, 2]).all() and np.isfinite(out[3, 0, 1]).all()


def test_map_to_robot_with_a_real_robot(make_demo):
    from nlo_lab.robot import load_robot

    robot = load_robot("nao")
    demo = make_demo()
    out = map_to_robot(demo, robot)
    shoulder = np.asarray(robot.shoulder_position("left").detach().cpu().numpy(), float)
    np.testing.assert_allclose(out[:, 0, 0], np.broadcast_to(shoulder, (len(demo), 3)), atol=1e-9)
    upper, fore = (float(v) for v in robot.zero_pose_lengths("left"))
    length = np.linalg.norm(out[:, 0, 1] - out[:, 0, 0], axis=-1) + np.linalg.norm(out[:, 0, 2] - out[:, 0, 1], axis=-1)
    np.testing.assert_allclose(np.median(length), upper + fore, rtol=0.05)

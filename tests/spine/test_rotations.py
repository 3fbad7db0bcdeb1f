"""nlo_lab.rotations: the conventions (URDF RPY, quaternions x y z w), batches, gimbal lock, slerp."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nlo_lab.rotations import matrix_to_quat, matrix_to_rpy, quat_to_matrix, rpy_to_matrix, slerp


def Rx(a):
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def Ry(a):
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def Rz(a):
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def random_rpy(n, seed=0):
    return np.random.default_rng(seed).uniform([-3, -1.5, -3], [3, 1.5, 3], size=(n, 3))


def test_rpy_is_urdfs_fixed_axes_convention():
    for r, p, y in random_rpy(20):
        np.testing.assert_allclose(rpy_to_matrix([r, p, y]), Rz(y) @ Ry(p) @ Rx(r), atol=1e-15)


def test_rpy_round_trip_batched():
    rpy = random_rpy(24).reshape(2, 3, 4, 3)
    R = rpy_to_matrix(rpy)
    assert R.shape == (2, 3, 4, 3, 3)
    np.testing.assert_allclose(matrix_to_rpy(R), rpy, atol=1e-12)


@pytest.mark.parametrize("pitch", [math.pi / 2, -math.pi / 2])
def test_gimbal_lock_puts_the_angle_into_yaw(pitch):
    R = Rz(0.7) @ Ry(pitch) @ Rx(0.3)
    rpy = matrix_to_rpy(R)
    assert rpy[0] == 0.0 and rpy[1] == pytest.approx(pitch)
    np.testing.assert_allclose(rpy_to_matrix(rpy), R, atol=1e-12)


def test_yaw_of_pi_keeps_atan2s_branch():
    # the robot graph's edge features (seen by the checkpoints) must not flip between +pi and -pi
    R = Rz(math.pi) @ Rx(0.2)
    R[1, 0] = -0.0
    assert matrix_to_rpy(R)[2] == math.atan2(-0.0, R[0, 0])


def test_quaternions_are_xyzw_with_nonnegative_w():
    a = 0.8
    q = np.array([0.0, 0.0, math.sin(a / 2), math.cos(a / 2)])  # a about z
    np.testing.assert_allclose(quat_to_matrix(q), Rz(a), atol=1e-15)
    np.testing.assert_allclose(quat_to_matrix(-q), Rz(a), atol=1e-15)
    np.testing.assert_allclose(quat_to_matrix(3 * q), Rz(a), atol=1e-15)  # normalised
    R = rpy_to_matrix(random_rpy(30)).reshape(5, 6, 3, 3)
    Q = matrix_to_quat(R)
    assert Q.shape == (5, 6, 4) and np.all(Q[..., 3] >= 0)
    np.testing.assert_allclose(np.linalg.norm(Q, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(quat_to_matrix(Q), R, atol=1e-12)


def test_slerp_walks_the_shorter_arc_at_constant_speed():
    q0 = matrix_to_quat(np.eye(3))
    q1 = matrix_to_quat(Rz(1.0))
    for a in (0.0, 0.25, 0.5, 1.0):
        np.testing.assert_allclose(quat_to_matrix(slerp(q0, q1, a)), Rz(a * 1.0), atol=1e-12)
    np.testing.assert_allclose(quat_to_matrix(slerp(q0, -q1, 0.5)), Rz(0.5), atol=1e-12)  # -q1 is the same rotation
    far = matrix_to_quat(Rz(3.0))  # 3 rad one way is 3.28 rad the other: stay on the 3 rad side
    np.testing.assert_allclose(quat_to_matrix(slerp(q0, far, 0.5)), Rz(1.5), atol=1e-12)


def test_slerp_is_element_by_element():
    Ra, Rb = rpy_to_matrix(random_rpy(8, seed=1)), rpy_to_matrix(random_rpy(8, seed=2))
    a = np.linspace(0, 1, 8)
    out = slerp(matrix_to_quat(Ra), matrix_to_quat(Rb), a)
    for i in range(8):
        one = slerp(matrix_to_quat(Ra[i]), matrix_to_quat(Rb[i]), a[i])
        np.testing.assert_allclose(out[i], one, atol=1e-12)


def test_bad_shapes_are_refused():
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        rpy_to_matrix([1.0, 2.0])
    with pytest.raises(ValueError, match=r"\(\.\.\., 4\)"):
        quat_to_matrix(np.zeros((2, 3)))


def test_hand_frame_is_a_rotation_with_x_along_the_hand_and_y_across():
    from nlo_lab.rotations import hand_frame

    rng = np.random.default_rng(4)
    wrist, middle, index, pinky = rng.normal(size=(4, 50, 3))
    R = hand_frame(wrist, middle, index, pinky)  # (50, 3, 3)
    np.testing.assert_allclose(R.swapaxes(-1, -2) @ R, np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    along = (middle - wrist) / np.linalg.norm(middle - wrist, axis=-1, keepdims=True)
    np.testing.assert_allclose(R[..., 0], along, atol=1e-12)
    assert (np.sum(R[..., 1] * (index - pinky), axis=-1) > 0).all()  # y points little finger -> index
    flat = hand_frame(np.zeros(3), np.array([1.0, 0, 0]), np.array([2.0, 0, 0]), np.array([3.0, 0, 0]))  # collinear
    assert np.isnan(flat[:, 1:]).all() and np.isfinite(flat[:, 0]).all()  # no direction across the hand
    assert np.isnan(hand_frame(*np.zeros((4, 3)))).all()  # coincident: no direction at all


def test_the_hand_frame_is_one_formulation():
    """The synthetic body's and the readers' wrist frames are rotations.hand_frame."""
    from nlo_lab.corpus import hand_frame as body_hand_frame
    from nlo_lab.human.transforms import wrist_frame_from_hand
    from nlo_lab.rotations import hand_frame

    rng = np.random.default_rng(5)
    wrist, bases = rng.normal(size=(7, 3)), rng.normal(size=(7, 5, 3))
    expected = hand_frame(wrist, bases[:, 2], bases[:, 1], bases[:, 4])
    np.testing.assert_array_equal(body_hand_frame(wrist, bases), expected)
    np.testing.assert_array_equal(wrist_frame_from_hand(wrist, bases[:, 1], bases[:, 4], bases[:, 2]), expected)

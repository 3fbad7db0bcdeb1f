"""The parametric human body: forward kinematics, conventions, IK, primitives, handshapes."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from nlo_lab.corpus import (
    ARM_RANGES,
    BODY_RANGES,
    FINGER_RANGES,
    HANDSHAPES,
    BodyParams,
    arm_fk,
    arm_ik,
    body_gradient,
    body_signed_distance,
    head_signed_distance,
    knuckle_centre,
    random_body,
    torso_signed_distance,
    wrist_position,
)
from nlo_lab.errors import SettingsError

SIDES = ("left", "right")


def _random_angles(rng, n):
    arm = rng.uniform(ARM_RANGES[:, 0], ARM_RANGES[:, 1], (n, 7))
    fingers = rng.uniform(FINGER_RANGES[..., 0], FINGER_RANGES[..., 1], (n, 5, 4))
    return arm, fingers


@pytest.mark.parametrize("side", SIDES)
def test_segment_lengths_are_preserved_at_random_angles(side):
    rng = np.random.default_rng(1)
    body = random_body(rng)
    arm, fingers = _random_angles(rng, 200)
    pose = arm_fk(body, arm, fingers, side)
    np.testing.assert_allclose(np.linalg.norm(pose.elbow - pose.shoulder, axis=-1), body.upper_arm, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(pose.wrist - pose.elbow, axis=-1), body.forearm, atol=1e-12)
    seg = np.linalg.norm(np.diff(pose.chain, axis=-2), axis=-1)  # (n, 5, 4)
    np.testing.assert_allclose(seg[..., 1:], np.broadcast_to(body.segment_lengths(), seg[..., 1:].shape), atol=1e-12)
    # root -> j1 is fixed in the hand: the same length in every pose
    np.testing.assert_allclose(seg[..., 0], np.broadcast_to(seg[0, :, 0], seg[..., 0].shape), atol=1e-12)
    # the hand is rigid: wrist -> MCP distances do not depend on the angles
    d = np.linalg.norm(pose.finger_base[:, 1:] - pose.wrist[:, None], axis=-1)
    np.testing.assert_allclose(d, np.broadcast_to(d[0], d.shape), atol=1e-12)


def test_realistic_dimensions():
    body = BodyParams()
    pose = arm_fk(body, np.zeros(7), np.zeros((5, 4)), "right")
    middle = np.linalg.norm(pose.finger_tip[2] - pose.wrist)
    assert 0.85 * body.hand_length < middle < 1.0 * body.hand_length  # wrist joint sits a little distal of the crease
    breadth = np.linalg.norm(pose.finger_base[1] - pose.finger_base[4])
    assert 0.05 < breadth < 0.08  # index-to-little MCP joint centres of an adult hand
    assert np.linalg.norm(pose.finger_tip[1] - pose.finger_base[1]) < np.linalg.norm(pose.finger_tip[2] - pose.finger_base[2])


def test_left_arm_is_the_mirror_image_on_plus_y():
    rng = np.random.default_rng(2)
    body = BodyParams()
    arm, fingers = _random_angles(rng, 50)
    left, right = arm_fk(body, arm, fingers, "left"), arm_fk(body, arm, fingers, "right")
    assert left.shoulder[0, 1] == pytest.approx(body.shoulder_width / 2)
    assert right.shoulder[0, 1] == pytest.approx(-body.shoulder_width / 2)
    mirror = np.array([1.0, -1.0, 1.0])
    np.testing.assert_allclose(left.chain, right.chain * mirror, atol=1e-12)
    np.testing.assert_allclose(left.wrist, right.wrist * mirror, atol=1e-12)
    np.testing.assert_allclose(wrist_position(body, arm, "left"), left.wrist, atol=1e-12)
    # zero pose: arms hang down beside the body, thumbs forward
    for side in SIDES:
        p = arm_fk(body, np.zeros(7), np.zeros((5, 4)), side)
        np.testing.assert_allclose(p.elbow - p.shoulder, [0, 0, -body.upper_arm], atol=1e-12)
        assert p.finger_tip[0, 0] > p.wrist[0] + 0.03  # thumb points forward


@pytest.mark.parametrize("side", SIDES)
def test_wrist_frame_follows_the_demonstration_convention(side):
    rng = np.random.default_rng(3)
    body = BodyParams()
    arm, fingers = _random_angles(rng, 100)
    pose = arm_fk(body, arm, fingers, side)
    R = pose.wrist_rotation
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    x = pose.finger_base[:, 2] - pose.wrist
    np.testing.assert_allclose(R[..., 0], x / np.linalg.norm(x, axis=-1, keepdims=True), atol=1e-12)
    assert np.all(np.einsum("ni,ni->n", R[..., 1], pose.finger_base[:, 1] - pose.finger_base[:, 4]) > 0.05)
    # z is the back of the right hand and the palm of the left hand: curling the fingers
    # moves the fingertips to the palm side
    flat = arm_fk(body, arm, np.zeros_like(fingers), side)
    fist = arm_fk(body, arm, np.broadcast_to(HANDSHAPES["fist"], fingers.shape), side)
    palm_side = -1.0 if side == "right" else 1.0
    move = fist.finger_tip[:, 2] - flat.finger_tip[:, 2]
    assert np.all(np.einsum("ni,ni->n", move, R[..., 2]) * palm_side > 0.02)
    assert np.all(np.einsum("ni,ni->n", move, R[..., 0]) < -0.08)  # and back towards the wrist


def test_anatomical_directions():
    body = BodyParams()
    f = np.zeros((5, 4))
    # elbow flexion brings the forearm forward; pronation turns the right palm down
    q = np.array([0, 0, 0, np.pi / 2, 0, 0, 0])
    p = arm_fk(body, q, f, "right")
    assert p.wrist[0] == pytest.approx(body.forearm)
    q[4] = np.pi / 2
    palm = -arm_fk(body, q, f, "right").wrist_rotation[:, 2]
    np.testing.assert_allclose(palm, [0, 0, -1], atol=0.08)
    # shoulder flexion raises the arm forward, abduction sideways (away from the body on both sides)
    for side, out in (("left", 1), ("right", -1)):
        up = arm_fk(body, np.array([np.pi / 2, 0, 0, 0, 0, 0, 0]), f, side)
        assert up.elbow[0] == pytest.approx(body.upper_arm)
        ab = arm_fk(body, np.array([0, np.pi / 2, 0, 0, 0, 0, 0]), f, side)
        assert (ab.elbow[1] - ab.shoulder[1]) * out == pytest.approx(body.upper_arm)
    # wrist flexion bends the hand to the palm side
    flexed = arm_fk(body, np.array([0, 0, 0, 0, 0, 0.8, 0]), f, "right")
    assert flexed.finger_tip[2, 1] > -body.shoulder_width / 2 + 0.05  # right palm faces +Y at rest


@pytest.mark.parametrize("side", SIDES)
def test_ik_reaches_the_target_with_a_natural_elbow(side):
    rng = np.random.default_rng(4)
    body = random_body(rng)
    sy = 1.0 if side == "left" else -1.0
    targets = np.stack([rng.uniform(0.15, 0.40, 300), sy * rng.uniform(-0.05, 0.30, 300), rng.uniform(-0.35, 0.15, 300)], -1)
    distal = rng.uniform(ARM_RANGES[4:, 0], ARM_RANGES[4:, 1], (300, 3))
    q = arm_ik(body, targets, side, distal, 0.5)
    pose = arm_fk(body, q, np.zeros((300, 5, 4)), side)
    np.testing.assert_allclose(pose.wrist, targets, atol=1e-9)
    np.testing.assert_allclose(q[:, 4:], distal)
    assert np.all((q >= ARM_RANGES[:, 0]) & (q <= ARM_RANGES[:, 1]))
    # natural swivel: of all elbow positions on the circle around the shoulder->wrist axis,
    # the chosen one lies furthest along the reference direction "down and out"
    ref = np.array([0.0, 0.5 * sy, -1.0])
    axis = (pose.wrist - pose.shoulder) / np.linalg.norm(pose.wrist - pose.shoulder, axis=-1, keepdims=True)
    rel = pose.elbow - pose.shoulder
    for angle in (-0.4, -0.1, 0.1, 0.4):  # Rodrigues rotation of the elbow about the axis
        c, s = np.cos(angle), np.sin(angle)
        other = rel * c + np.cross(axis, rel) * s + axis * np.sum(axis * rel, -1, keepdims=True) * (1 - c)
        assert np.all(rel @ ref >= other @ ref - 1e-12)
    assert np.all(pose.elbow[:, 2] < 0.5 * (pose.shoulder + pose.wrist)[:, 2])
    # knuckle_centre agrees with the full FK
    kc = knuckle_centre(body, q) * ([1, -1, 1] if side == "left" else 1)
    np.testing.assert_allclose(kc, pose.finger_base[:, 1:].mean(axis=1), atol=1e-12)


def test_float32_input_gives_the_same_pose():
    rng = np.random.default_rng(5)
    arm, fingers = _random_angles(rng, 10)
    a = arm_fk(BodyParams(), arm, fingers, "left")
    b = arm_fk(BodyParams(), arm.astype(np.float32), fingers.astype(np.float32), "left")
    np.testing.assert_allclose(a.chain, b.chain, atol=1e-6)


def test_body_params_are_validated_and_vary():
    for name, (_lo, hi) in BODY_RANGES.items():
        with pytest.raises(SettingsError, match=name):
            BodyParams(**{name: hi + 0.1})
        with pytest.raises(SettingsError, match=name):
            BodyParams(**{name: float("nan")})
    with pytest.raises(SettingsError, match=r"^BodyParams.upper_arm must be in \[0.27, 0.32\] m, got 0.5$"):
        BodyParams(upper_arm=0.5)
    with pytest.raises(SettingsError, match="BodyParams.forearm must be a number"):
        BodyParams(forearm=True)
    assert type(BodyParams(forearm=np.float32(0.25)).forearm) is float  # stored as the checked float
    rng = np.random.default_rng(6)
    bodies = [random_body(rng) for _ in range(20)]
    arms = np.array([b.upper_arm for b in bodies])
    assert arms.std() > 0.01 and np.all((arms >= 0.27) & (arms <= 0.32))
    with pytest.raises(SettingsError, match="side"):
        arm_fk(BodyParams(), np.zeros(7), np.zeros((5, 4)), "middle")
    with pytest.raises(SettingsError, match="fingers"):
        arm_fk(BodyParams(), np.zeros(7), np.zeros((4, 4)), "left")


def test_body_primitives():
    body = BodyParams()
    assert head_signed_distance(body, body.head_center) == pytest.approx(-body.head_radius)
    top = body.head_center + [0, 0, body.head_radius + 0.05]
    assert head_signed_distance(body, top) == pytest.approx(0.05)
    front = np.array([body.torso_center[0] + body.torso_half_extents[0] + 0.03, 0.0, -0.2])
    assert torso_signed_distance(body, front) == pytest.approx(0.03)
    assert torso_signed_distance(body, body.torso_center) < -0.1
    assert body_signed_distance(body, np.array([0.0, 0.0, 0.05])) < 0  # the neck
    np.testing.assert_allclose(body_gradient(body, front), [1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(body_gradient(body, top), [0, 0, 1], atol=1e-6)
    # the shoulders sit on the torso's top corners, outside it, and the hanging hand clears it
    rest = arm_fk(body, np.zeros(7), np.zeros((5, 4)), "left")
    assert torso_signed_distance(body, rest.shoulder) > 0
    assert body_signed_distance(body, rest.hand_points()).min() > 0


def test_handshapes_are_many_valid_and_distinguishable():
    assert len(HANDSHAPES) >= 10
    body = BodyParams()
    tips = {}
    for name, f in HANDSHAPES.items():
        assert f.shape == (5, 4)
        assert np.all((f >= FINGER_RANGES[..., 0]) & (f <= FINGER_RANGES[..., 1])), name
        pose = arm_fk(body, np.zeros(7), f, "right")
        tips[name] = pose.finger_tip - pose.wrist  # (5, 3) in the hand's (fixed) frame
    for a, b in itertools.combinations(tips, 2):
        assert np.linalg.norm(tips[a] - tips[b], axis=-1).max() > 0.02, (a, b)
    # thumb meets index in O and pinch; curled fingers are closer to the wrist than straight ones
    for name in ("O", "pinch"):
        assert np.linalg.norm(tips[name][0] - tips[name][1]) < 0.025, name
    assert np.all(np.linalg.norm(tips["fist"][1:], axis=-1) < np.linalg.norm(tips["flat"][1:], axis=-1) - 0.04)

"""Tests of nlo_lab.metrics: Fréchet exactness, derivative errors, feasibility counts."""

from __future__ import annotations

import itertools
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from nlo_lab.errors import NloLabError
from nlo_lab.human import Demonstration
from nlo_lab.metrics import (
    acceleration_error,
    frechet_distance,
    frechet_distance_reference,
    limit_violations,
    tracking_errors,
    velocity_error,
)


def brute_force_frechet(P: np.ndarray, Q: np.ndarray) -> float:
    """Min over every monotone coupling (steps (1,0), (0,1), (1,1)) of the max pair distance."""
    n, m = len(P), len(Q)
    D = np.linalg.norm(P[:, None] - Q[None], axis=-1)
    best = np.inf

    def walk(i: int, j: int, worst: float) -> None:
        nonlocal best
        worst = max(worst, D[i, j])
        if worst >= best:
            return
        if i == n - 1 and j == m - 1:
            best = worst
            return
        for di, dj in ((1, 0), (0, 1), (1, 1)):
            if i + di < n and j + dj < m:
                walk(i + di, j + dj, worst)

    walk(0, 0, 0.0)
    return float(best)


def brute_force_enumerate(P: np.ndarray, Q: np.ndarray) -> float:
    """Independent check without pruning: enumerate step sequences explicitly."""
    n, m = len(P), len(Q)
    values = []
    steps = ((1, 0), (0, 1), (1, 1))
    max_len = n + m - 2
    for length in range(max(n, m) - 1, max_len + 1):
        for seq in itertools.product(steps, repeat=length):
            i = j = 0
            worst = np.linalg.norm(P[0] - Q[0])
            for di, dj in seq:
                i, j = i + di, j + dj
                if i >= n or j >= m:
                    break
                worst = max(worst, np.linalg.norm(P[i] - Q[j]))
            else:
                if i == n - 1 and j == m - 1:
                    values.append(worst)
    return float(min(values))


@pytest.mark.parametrize("seed", range(40))
def test_frechet_matches_brute_force_on_small_cases(seed):
    rng = np.random.default_rng(seed)
    n, m = rng.integers(1, 6, size=2)
    P, Q = rng.normal(size=(n, 3)), rng.normal(size=(m, 3))
    expected = brute_force_frechet(P, Q)
    assert frechet_distance_reference(P, Q) == pytest.approx(expected, abs=1e-12)
    assert frechet_distance(P, Q) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_brute_force_helpers_agree(seed):
    rng = np.random.default_rng(100 + seed)
    n, m = rng.integers(1, 5, size=2)
    P, Q = rng.normal(size=(n, 3)), rng.normal(size=(m, 3))
    assert brute_force_frechet(P, Q) == pytest.approx(brute_force_enumerate(P, Q), abs=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_fast_equals_reference_on_200_points(seed):
    rng = np.random.default_rng(seed)
    n, m = 200, int(rng.integers(150, 260))
    P = np.cumsum(rng.normal(scale=0.02, size=(n, 3)), axis=0)
    Q = np.cumsum(rng.normal(scale=0.02, size=(m, 3)), axis=0)
    assert frechet_distance(P, Q) == pytest.approx(frechet_distance_reference(P, Q), rel=1e-12, abs=1e-15)


def test_frechet_symmetric():
    rng = np.random.default_rng(7)
    P, Q = rng.normal(size=(37, 3)), rng.normal(size=(23, 3))
    assert frechet_distance(P, Q) == pytest.approx(frechet_distance(Q, P), abs=1e-14)
    assert frechet_distance_reference(P, Q) == pytest.approx(frechet_distance_reference(Q, P), abs=1e-14)


def test_frechet_known_cases():
    t = np.linspace(0.0, 1.0, 50)
    curve = np.stack([np.cos(3 * t), np.sin(2 * t), t], axis=-1)
    assert frechet_distance(curve, curve) == 0.0
    shift = np.array([0.03, -0.04, 0.0])  # |shift| = 0.05
    assert frechet_distance(curve, curve + shift) == pytest.approx(0.05, abs=1e-12)
    # One curve sampled twice as densely: still the same curve at the vertices it shares.
    assert frechet_distance(np.array([[0.0, 0, 0], [1, 0, 0]]), np.array([[0.0, 0, 0], [0.5, 0, 0], [1, 0, 0]])) == pytest.approx(0.5)
    # A single point against a segment: the farthest end.
    assert frechet_distance(np.zeros((1, 3)), np.array([[1.0, 0, 0], [0, 3, 0]])) == pytest.approx(3.0)


def test_frechet_bad_input():
    with pytest.raises(NloLabError, match="same point dimension"):
        frechet_distance(np.zeros((3, 3)), np.zeros((3, 2)))
    with pytest.raises(NloLabError, match="NaN"):
        frechet_distance(np.array([[0.0, 0, 0], [np.nan, 0, 0]]), np.zeros((2, 3)))
    with pytest.raises(NloLabError, match="non-empty"):
        frechet_distance(np.zeros((0, 3)), np.zeros((2, 3)))


def test_velocity_and_acceleration_errors():
    rng = np.random.default_rng(3)
    fps = 25.0
    a = np.cumsum(rng.normal(scale=0.01, size=(60, 2, 3)), axis=0)
    assert velocity_error(a, a, fps) == 0.0
    assert acceleration_error(a, a, fps) == 0.0
    # b drifts away from a at a constant velocity v: velocity error |v|, acceleration error 0.
    v = np.array([0.3, 0.0, 0.4])  # [m/s], |v| = 0.5
    t = np.arange(60) / fps
    b = a + t[:, None, None] * v
    assert velocity_error(a, b, fps) == pytest.approx(0.5, rel=1e-9)
    assert acceleration_error(a, b, fps) == pytest.approx(0.0, abs=1e-9)
    # constant acceleration c: acceleration error |c|.
    c = np.array([0.0, 2.0, 0.0])
    b2 = a + 0.5 * (t**2)[:, None, None] * c
    assert acceleration_error(a, b2, fps) == pytest.approx(2.0, rel=1e-9)
    # NaN points are skipped, not propagated.
    b3 = b.copy()
    b3[10, 0] = np.nan
    assert velocity_error(a, b3, fps) == pytest.approx(0.5, rel=1e-9)
    with pytest.raises(NloLabError, match="fps"):
        velocity_error(a, b, 0)
    with pytest.raises(NloLabError, match="same shape"):
        velocity_error(a, b[:-1], fps)


def _fake_limits_robot(n=4):
    return SimpleNamespace(
        name="fake",
        n_joints=n,
        lower_limits=torch.full((n,), -1.0),
        upper_limits=torch.full((n,), 1.0),
    )


def test_limit_violations_counts_synthetic_violations():
    robot = _fake_limits_robot()
    q = np.zeros((10, 4))
    assert limit_violations(robot, q) == 0
    q[3, 1] = 1.2
    q[7, 0] = -1.5
    q[7, 3] = 1.0 + 1e-9  # within tolerance
    assert limit_violations(robot, q) == 2
    assert limit_violations(robot, q, tol=0.0) == 3
    with pytest.raises(NloLabError, match=r"\(T, 4\)"):
        limit_violations(robot, np.zeros((10, 3)))


class _PointRobot:
    """A stand-in robot whose elbow and wrist positions are the joint values (12 joints)."""

    name = "point"
    n_joints = 12
    lower_limits = torch.full((12,), -10.0, dtype=torch.float64)
    upper_limits = torch.full((12,), 10.0, dtype=torch.float64)

    def arm(self, side):
        return SimpleNamespace(elbow=f"{side}_elbow", wrist=f"{side}_wrist")

    def zero_pose_lengths(self, side):
        return (0.2, 0.2)

    def shoulder_position(self, side):
        return torch.tensor([0.0, 0.15 if side == "left" else -0.15, 0.0], dtype=torch.float64)

    def forward_kinematics(self, q):
        out = {}
        for s, side in enumerate(("left", "right")):
            for j, joint in enumerate(("elbow", "wrist")):
                T = torch.eye(4, dtype=q.dtype).repeat(q.shape[0], 1, 1)
                T[:, :3, 3] = q[:, 6 * s + 3 * j: 6 * s + 3 * j + 3]
                out[f"{side}_{joint}"] = T
        return out


def _demo(T=40, seed=0):
    rng = np.random.default_rng(seed)
    arm = np.zeros((T, 2, 3, 3))
    arm[:, 0, 0] = [0, 0.2, 0]
    arm[:, 1, 0] = [0, -0.2, 0]
    for s in range(2):
        arm[:, s, 1] = arm[:, s, 0] + [0.0, 0.0, -0.3] + np.cumsum(rng.normal(scale=0.003, size=(T, 3)), 0)
        arm[:, s, 2] = arm[:, s, 1] + [0.3, 0.0, 0.0] + np.cumsum(rng.normal(scale=0.003, size=(T, 3)), 0)
    rot = np.broadcast_to(np.eye(3), (T, 2, 3, 3)).copy()
    return Demonstration(
        30.0, arm, np.ones((T, 2, 3), bool), rot, np.ones((T, 2), bool),
        np.zeros((T, 2, 5, 2, 3)), np.ones((T, 2, 5), bool), name="synthetic",
    )


def test_tracking_errors_zero_when_robot_follows_mapped_human_and_shift_is_measured():
    from nlo_lab.metrics import _mapped_human

    demo, robot = _demo(), _PointRobot()
    mapped = _mapped_human(demo, robot)  # (T, 2, 3, 3)
    q = mapped[:, :, 1:].reshape(len(demo), 12)
    errs = tracking_errors(demo, robot, q)
    assert set(errs) == {"frechet_wrist_m", "frechet_elbow_m", "frechet_m", "velocity_error", "acceleration_error"}
    for key, value in errs.items():
        assert value == pytest.approx(0.0, abs=1e-12), key
    shifted = q.copy()
    shifted[:, 3:6] += [0.0, 0.0, 0.08]  # left wrist 8 cm higher
    errs = tracking_errors(demo, robot, shifted)
    assert errs["frechet_wrist_m"] == pytest.approx(0.04, abs=1e-12)  # mean over the two arms
    assert errs["frechet_elbow_m"] == pytest.approx(0.0, abs=1e-12)
    assert errs["frechet_m"] == pytest.approx(0.02, abs=1e-12)
    assert errs["velocity_error"] == pytest.approx(0.0, abs=1e-9)


def test_tracking_errors_drop_masked_frames():
    from nlo_lab.metrics import _mapped_human

    demo, robot = _demo(), _PointRobot()
    q = _mapped_human(demo, robot)[:, :, 1:].reshape(len(demo), 12)
    demo.arm_mask[5:9, 1, 2] = False  # right wrist unseen for 4 frames
    demo.validate()
    q[5:9, 9:12] = 5.0  # the robot does anything there
    errs = tracking_errors(demo, robot, q)
    assert errs["frechet_wrist_m"] == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(NloLabError, match="frames"):
        tracking_errors(demo, robot, q[:-1])


def test_self_collision_frames_counts_frames_with_any_penetration():
    from nlo_lab.metrics import self_collision_frames

    class _Fake:
        name, n_joints = "fake", 2
        lower_limits = torch.full((2,), -1.0)

        def forward_kinematics(self, q):
            return {"q": q}

        def capsule_distances(self, poses):  # (T, P=2): pair distances are the joint values
            return poses["q"]

    q = np.array([[0.1, 0.2], [-0.01, 0.3], [0.2, -0.5], [0.0, 0.0], [-0.1, -0.1]])
    assert self_collision_frames(_Fake(), q) == 3  # frames 1, 2, 4; touching (0.0) is not penetrating


def test_real_robot_mid_pose_is_feasible():
    from nlo_lab.metrics import self_collision_frames
    from nlo_lab.robot import load_robot

    robot = load_robot("nao")
    mid = 0.5 * (robot.lower_limits + robot.upper_limits).double().numpy()
    q = np.tile(mid, (3, 1))
    assert limit_violations(robot, q) == 0
    q[1, 0] = robot.upper_limits[0].item() + 0.1
    assert limit_violations(robot, q) == 1
    assert isinstance(self_collision_frames(robot, q), int)


@pytest.mark.slow
def test_read_only_angles_give_no_torch_warning():
    """Angles read from a file can be a read-only array; scoring them must not print torch's
    'non-writable tensor' warning to the user (torch prints it once per process: a fresh one)."""
    import subprocess
    import sys

    code = (
        "import warnings, numpy as np\n"
        "warnings.simplefilter('error')\n"
        "from nlo_lab.robot import load_robot\n"
        "from nlo_lab.metrics import self_collision_frames\n"
        "robot = load_robot('nao')\n"
        "q = np.repeat(robot.neutral_q.double().numpy()[None], 3, axis=0)\n"
        "q.setflags(write=False)\n"
        "print(self_collision_frames(robot, q))\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.strip() == "0"


@pytest.mark.parametrize("name", ["yumi", "nao", "pepper"])
def test_self_collision_frames_culled_gives_the_exact_count(name):
    """Random poses over the joint ranges (both verdicts occur), more frames than one chunk of the metrics."""
    from nlo_lab.metrics import METRIC_CHUNK_FRAMES, self_collision_frames
    from nlo_lab.robot import load_robot

    robot = load_robot(name)
    g = torch.Generator().manual_seed(31)
    lo, hi = robot.lower_limits.double(), robot.upper_limits.double()
    q = (lo + (hi - lo) * torch.rand(2 * METRIC_CHUNK_FRAMES + 17, lo.shape[0], generator=g, dtype=torch.float64)).numpy()
    exact = self_collision_frames(robot, q)
    assert 10 < exact < len(q) - 10
    assert self_collision_frames(robot, q, cull=True) == exact

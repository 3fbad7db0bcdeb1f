"""Joint limits always, velocity limits between successive outputs: also across a jump of the targets."""

from __future__ import annotations

import numpy as np

from nlo_lab.live import MotionLimits, ease_toward
from nlo_lab.metrics import limit_violations, velocity_violations
from nlo_lab.robot import load_robot


def test_a_stream_with_a_jump_never_breaks_a_limit():
    robot = load_robot("yumi")
    limits = MotionLimits.of(robot)
    rng = np.random.default_rng(0)
    lo, hi = limits.lower, limits.upper
    n = len(lo)
    # irregular camera times (8-40 fps); targets that wander, then jump from one end of the ranges to the other,
    # leave the limits, turn NaN for a while
    times = np.cumsum(rng.uniform(1 / 40, 1 / 8, size=200))
    targets = lo + (hi - lo) * np.clip(0.5 + 0.05 * np.cumsum(rng.normal(size=(200, n)), axis=0), 0, 1)
    targets[80:120] = hi + 1.0
    targets[120:140] = lo
    targets[140:150] = np.nan
    q = [robot.neutral_q.double().numpy()]
    for i in range(1, 200):
        q.append(limits.step(q[-1], targets[i], times[i] - times[i - 1]))
    q = np.stack(q)
    assert limit_violations(robot, q) == 0
    assert velocity_violations(robot, q, times) == 0
    # the jump is followed at the joints' full speed, not faster: some joint runs at its limit
    speed = np.abs(np.diff(q, axis=0)) / np.diff(times)[:, None] / limits.velocity
    assert speed[119:125].max() > 0.99
    assert np.allclose(q[119], hi, atol=1e-9)  # the targets beyond the upper limits are clipped to them
    assert np.array_equal(q[140:150], np.repeat(q[139:140], 10, axis=0))  # NaN targets: the joints stay


def test_the_control_a_jump_without_limits_breaks_them():
    robot = load_robot("yumi")
    q = np.stack([robot.neutral_q.double().numpy(), robot.upper_limits.double().numpy()])
    assert velocity_violations(robot, q, np.array([0.0, 0.03])) > 0  # what MotionLimits prevents: the check can fail


def test_easing_approaches_rest_exponentially():
    q, rest = np.array([1.0, -2.0]), np.zeros(2)
    once = ease_toward(q, rest, 0.5, 0.5)
    assert np.allclose(once, q * np.exp(-1))
    assert np.array_equal(ease_toward(q, rest, 0.0, 0.5), q)


def test_unlimited_joints_move_at_once():
    limits = MotionLimits([-1.0, -1.0], [1.0, 1.0], [np.inf, 1.0])
    out = limits.step(np.zeros(2), np.ones(2), 0.1)
    assert out[0] == 1.0 and np.isclose(out[1], 0.1)
    assert np.array_equal(limits.step(np.zeros(2), np.ones(2), 0.0), [1.0, 0.0])

"""Joint speeds against the velocity limits (nlo_lab.robot.speeds): what retiming stretches and the metrics count."""

from __future__ import annotations

import numpy as np
import pytest

import nlo_lab.metrics
from nlo_lab.errors import SettingsError
from nlo_lab.inference import retime_times
from nlo_lab.robot import joint_speeds, speed_ratios


def test_speeds_and_ratios_on_a_hand_worked_trajectory():
    q = np.array([[0.0, 0.0], [0.5, -1.0], [0.5, 2.0]])  # rad
    t = np.array([0.0, 0.5, 1.5])  # s
    assert joint_speeds(q, t) == pytest.approx(np.array([[1.0, 2.0], [0.0, 3.0]]))
    assert speed_ratios(q, t, [2.0, np.inf]) == pytest.approx(np.array([[0.5, 0.0], [0.0, 0.0]]))


def test_retiming_leaves_no_ratio_over_one():
    q = np.cumsum(np.random.default_rng(0).normal(scale=0.3, size=(50, 3)), axis=0)
    limits = np.array([1.0, 2.0, 0.5])
    assert speed_ratios(q, retime_times(q, 30.0, limits), limits).max() <= 1.0


def test_bad_shapes_and_limits_are_one_settings_error():
    with pytest.raises(SettingsError, match="to match the velocity limits"):
        speed_ratios(np.zeros((3, 2)), np.arange(3.0), [1.0])
    with pytest.raises(SettingsError, match="must be > 0"):
        speed_ratios(np.zeros((3, 1)), np.arange(3.0), [0.0])
    with pytest.raises(SettingsError, match="times must be"):
        joint_speeds(np.zeros((3, 1)), np.arange(2.0))


def test_the_metrics_keep_their_names():
    assert nlo_lab.metrics.joint_speeds is joint_speeds
    assert nlo_lab.metrics.speed_ratios is speed_ratios

"""The One-Euro filter: causal (no future sample changes a past output), smooths jitter, follows motion."""

from __future__ import annotations

import numpy as np
import pytest

from nlo_lab.errors import SettingsError
from nlo_lab.human.conditioning import savgol
from nlo_lab.live import OneEuroFilter


def _run(filt_or_fn, x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The filter's outputs over a stream, one sample at a time."""
    f = filt_or_fn()
    return np.stack([f(x[i], t[i]) for i in range(len(x))])


def _offline_savgol(x: np.ndarray, _t: np.ndarray) -> np.ndarray:
    return savgol(x, np.ones(len(x), bool), 7)


def _uses_future(smooth, rng) -> bool:
    """Whether outputs before frame k change when only the frames from k on change (two streams, one prefix)."""
    T, k = 60, 30
    t = np.arange(T) / 25.0
    a = rng.normal(size=(T, 4, 3)) * 0.01 + np.linspace(0, 1, T)[:, None, None]
    b = a.copy()
    b[k:] += rng.normal(size=(T - k, 4, 3)) * 0.3  # another future
    return not np.array_equal(smooth(a, t)[:k], smooth(b, t)[:k])


def test_no_future_frame_changes_an_output():
    rng = np.random.default_rng(0)
    for settings in ({}, {"min_cutoff": 0.3, "beta": 5.0}, {"min_cutoff": 10.0, "beta": 0.0}):
        assert not _uses_future(lambda x, t, s=settings: _run(lambda: OneEuroFilter(**s), x, t), rng), settings
    # the check can fail: the offline Savitzky-Golay smoothing looks ahead, and it says so
    assert _uses_future(_offline_savgol, rng)


def test_it_smooths_a_point_at_rest_and_follows_a_fast_one():
    rng = np.random.default_rng(1)
    t = np.arange(200) / 30.0
    still = 0.5 + rng.normal(scale=0.01, size=(200, 1, 3))
    out = _run(lambda: OneEuroFilter(min_cutoff=1.0, beta=0.0), still, t)
    # at rest the filter is an exponential smoothing, alpha = 0.173 at 1 Hz and 30 fps: white noise keeps
    # sqrt(alpha / (2 - alpha)) = 0.31 of its standard deviation
    ratio = np.std(out[50:], axis=0) / np.std(still[50:], axis=0)
    assert np.all((ratio > 0.2) & (ratio < 0.42)), ratio
    # a ramp at 1 m/s: the speed raises the cutoff, so beta > 0 lags less than the same filter without it
    ramp = np.stack([t, 0 * t, 0 * t], axis=-1)[:, None]
    lag = {beta: np.abs(_run(lambda b=beta: OneEuroFilter(min_cutoff=1.0, beta=b), ramp, t) - ramp)[100:].max() for beta in (0.0, 5.0)}
    assert lag[5.0] < 0.3 * lag[0.0], lag


def test_missing_points_keep_their_state_and_use_the_true_gap():
    f = OneEuroFilter(min_cutoff=1.0)
    f(np.zeros((2, 3)), 0.0)
    out = f(np.ones((2, 3)), 0.1, valid=np.array([True, False]))
    assert np.isnan(out[1]).all() and 0 < out[0, 0] < 1
    later = f(np.ones((2, 3)), 1.0)  # point 1 last seen at t = 0: smoothed over 1 s, it moves further than point 0 did in 0.1 s
    assert later[1, 0] > out[0, 0]
    f.reset(np.array([False, True]))
    assert f(np.full((2, 3), 5.0), 1.1)[1, 0] == 5.0  # forgotten: passes unfiltered


def test_bad_settings_and_time_order_are_refused():
    with pytest.raises(SettingsError, match="min_cutoff"):
        OneEuroFilter(min_cutoff=0)
    with pytest.raises(SettingsError, match="beta"):
        OneEuroFilter(beta=-1)
    f = OneEuroFilter()
    f(np.zeros((1, 3)), 1.0)
    f(np.zeros((1, 3)), 2.0)
    with pytest.raises(SettingsError, match="time order"):
        f(np.zeros((1, 3)), 2.0)

"""Retiming: slow a joint trajectory down where it is faster than the robot's joints.

A retargeted trajectory has one sample per recorded frame, ``1/fps`` apart. Signing is
often faster than a robot: YuMi's axes 1, 2, 7 and 3 turn at most 3.14 rad/s. Retiming
keeps every sample (the path) and moves the samples further apart in time wherever a
joint would otherwise exceed its limit.

The scheme. The robot moves linearly between consecutive samples (the controller's
interpolation of a ``trajectory.csv``). Under velocity limits alone, the fastest
traversal of such a piecewise-linear path takes each segment at the highest speed its
most constrained joint allows, and never faster than the recording::

    dt_i = max(1/fps, max_j |q[i+1, j] - q[i, j]| / v_max_j)

This is the time-optimal parameterisation for velocity constraints (what TOPP-RA would
return without acceleration limits), in one line of numpy; acceleration limits are not
published for the three robots, so there is nothing more to respect. The finite-difference
speed of every joint on the returned time base is then at most its limit (the
:data:`SAFETY` factor absorbs the rounding of the cumulative sum).

Retiming does not hide jitter: a jittery trajectory retimes to a long one. The
objective's smoothness term (``LossWeights.smooth``) removes the jitter first; the
summary's ``slowdown`` reports what retiming still had to do.
"""

from __future__ import annotations

import numpy as np

from nlo_lab.errors import SettingsError
from nlo_lab.robot.speeds import speed_ratios

__all__ = ["SAFETY", "segment_durations", "retime_times"]

SAFETY = 1.0 + 1e-9  # segments are stretched by this much more than needed (float rounding of cumsum)


def segment_durations(angles, fps: float, limits) -> np.ndarray:
    """``(T-1,)`` durations [s] of the segments between consecutive samples (see the module docstring).

    Args:
        angles: ``(T, n)`` joint angles [rad].
        fps: the recording's frame rate; no segment is faster than ``1/fps``.
        limits: ``(n,)`` joint velocity limits [rad/s] (``inf`` = unlimited).
    """
    if not fps > 0:
        raise SettingsError(f"fps must be > 0, got {fps!r}")
    q = np.asarray(angles, dtype=np.float64)
    # a segment's speed ratio when it takes one second is the time [s] it needs at full speed
    ratios = speed_ratios(q, np.arange(len(q), dtype=np.float64), limits)  # (T-1, n), validates the shapes
    if len(q) < 2:
        return np.zeros(0)
    return np.maximum(ratios.max(axis=1) * SAFETY, 1.0 / fps)


def retime_times(angles, fps: float, limits) -> np.ndarray:
    """``(T,)`` sample times [s] from 0, so that no joint exceeds its velocity limit."""
    return np.concatenate([[0.0], np.cumsum(segment_durations(angles, fps, limits))])

"""Joint speeds of a trajectory against the joints' velocity limits: a fact of the robot and the trajectory.

Retiming (:mod:`nlo_lab.inference.retime`) stretches a trajectory's segments until no
ratio is over 1; the metrics (:mod:`nlo_lab.metrics`) count the ratios over 1. Both read
them here, so that inference needs no metric and the metrics need no inference.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from nlo_lab.errors import SettingsError

__all__ = ["joint_speeds", "speed_ratios"]


def joint_speeds(angles: Any, times: Any) -> np.ndarray:
    """``(T-1, n)`` finite-difference joint speeds ``|Δq| / Δt`` [rad/s] on the time base ``times``."""
    q = np.asarray(angles, dtype=np.float64)
    t = np.asarray(times, dtype=np.float64)
    if q.ndim != 2 or t.shape != (q.shape[0],):
        raise SettingsError(f"times must be ({q.shape[0] if q.ndim else '?'},) to match the angles (T, n), got {t.shape} and {q.shape}")
    return np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]


def speed_ratios(angles: Any, times: Any, limits: Any) -> np.ndarray:
    """``(T-1, n)`` joint speed over its limit: > 1 is a violation (0 for unlimited joints).

    Args:
        angles: ``(T, n)`` [rad].
        times: ``(T,)`` sample times [s].
        limits: ``(n,)`` joint velocity limits [rad/s], each > 0 (``inf`` = no limit).
    """
    q = np.asarray(angles, dtype=np.float64)
    v = np.asarray(limits, dtype=np.float64).reshape(-1)
    if q.ndim != 2 or q.shape[1] != v.shape[0]:
        raise SettingsError(f"angles must be (T, {v.shape[0]}) to match the velocity limits, got {q.shape}")
    if not (v > 0).all():
        raise SettingsError("velocity limits must be > 0 (inf = no limit)")
    return joint_speeds(q, times) / v

"""The One-Euro filter: a causal low-pass filter whose cutoff rises with speed.

Casiez, Roussel & Vogel, "1€ Filter: A Simple Speed-based Low-pass Filter for Noisy Input in
Interactive Systems" (CHI 2012). Each sample is an exponential smoothing of the new value and
the last output; the smoothing factor follows from the time since the last sample and a cutoff
frequency, ``alpha = 1 / (1 + 1 / (2 pi cutoff dt))``. The cutoff is ``min_cutoff + beta *
speed``, where the speed is itself smoothed (cutoff ``d_cutoff``): a point at rest is smoothed
hard (jitter goes), a point that moves fast is hardly smoothed (little lag). Only the past and
the present enter an output, so the filter can run on a live stream; the offline reader's
Savitzky-Golay smoothing (:mod:`nlo_lab.human.conditioning`) needs the frames after the present.

Points are filtered as points: the speed that sets the cutoff is the norm over the last axis
(a 3-D point moving diagonally is as fast as one moving along an axis, whatever the camera's
orientation). Each point keeps its own state and its own time of last sample, so a point that
was missing for a while is filtered with the true gap.
"""

from __future__ import annotations

import math

import numpy as np

from nlo_lab.errors import SettingsError
from nlo_lab.settings import check_nonnegative, check_positive

__all__ = ["OneEuroFilter", "smoothing_factor"]


def smoothing_factor(cutoff: np.ndarray | float, dt: np.ndarray | float) -> np.ndarray:
    """``alpha`` of an exponential smoothing with ``cutoff`` [Hz] for samples ``dt`` [s] apart (1: no smoothing)."""
    tau = 1.0 / (2.0 * math.pi * np.asarray(cutoff, dtype=np.float64))
    return 1.0 / (1.0 + tau / np.asarray(dt, dtype=np.float64))


class OneEuroFilter:
    """One-Euro filter of a stream of point sets ``(..., D)`` (see the module docstring).

    Args:
        min_cutoff: cutoff [Hz] of a point at rest: lower removes more jitter, and lags more.
        beta: how fast the cutoff rises with speed [1 / unit of the points]: higher follows fast
            motion more closely, and lets more jitter through while it moves.
        d_cutoff: cutoff [Hz] of the speed estimate.

    Attributes:
        min_cutoff, beta, d_cutoff: as above; set them while the stream runs (the next sample uses them).
    """

    def __init__(self, min_cutoff: float = 1.0, beta: float = 0.0, d_cutoff: float = 1.0):
        self.min_cutoff = min_cutoff
        self.beta = beta
        self.d_cutoff = d_cutoff
        self._value: np.ndarray | None = None  # (..., D) last output
        self._speed: np.ndarray | None = None  # (...,) smoothed speed [unit / s]
        self._time: np.ndarray | None = None  # (...,) time of each point's last sample [s]; NaN: none yet

    def __setattr__(self, name: str, value) -> None:
        if name in ("min_cutoff", "d_cutoff"):
            value = check_positive(name, value)
        elif name == "beta":
            value = check_nonnegative(name, value)
        super().__setattr__(name, value)

    def reset(self, which: np.ndarray | None = None) -> None:
        """Forget the past of every point, or of the points where ``which (...)`` is True: their next sample passes unfiltered."""
        if which is None or self._time is None:
            self._value = self._speed = self._time = None
            return
        self._time[np.asarray(which, bool)] = np.nan

    def __call__(self, x: np.ndarray, t: float, valid: np.ndarray | None = None) -> np.ndarray:
        """Filter one sample.

        Args:
            x: ``(..., D)`` the points at time ``t``; always the same shape.
            t: the sample's time [s], later than any earlier sample's.
            valid: ``(...)`` bool, the points observed now (default: all); the others keep their state.

        Returns:
            ``(..., D)`` filtered points; NaN where not valid.
        """
        x = np.asarray(x, dtype=np.float64)
        shape = x.shape[:-1]
        valid = np.ones(shape, bool) if valid is None else np.asarray(valid, bool) & np.isfinite(x).all(axis=-1)
        value, speed_state, last = self._state(x.shape)
        t = float(t)
        known = valid & np.isfinite(last)
        dt = np.where(known, t - np.where(known, last, t), 1.0)
        if (dt[known] <= 0).any():
            raise SettingsError(f"the filter's samples must come in time order: t = {t} is not after the last sample")
        fresh = valid & ~known  # first sample (or after a reset): passes as it is
        value[fresh] = x[fresh]
        speed_state[fresh] = 0.0
        if known.any():
            prev = value[known]
            raw_speed = np.linalg.norm(x[known] - prev, axis=-1) / dt[known]
            a_d = smoothing_factor(self.d_cutoff, dt[known])
            speed = speed_state[known] + a_d * (raw_speed - speed_state[known])
            a = smoothing_factor(self.min_cutoff + self.beta * speed, dt[known])
            value[known] = prev + a[:, None] * (x[known] - prev)
            speed_state[known] = speed
        last[valid] = t
        return np.where(valid[..., None], value, np.nan)

    def _state(self, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The last outputs ``shape``, smoothed speeds and sample times (new, empty ones for a new shape)."""
        if self._value is None or self._speed is None or self._time is None or self._value.shape != shape:
            self._value, self._speed, self._time = np.full(shape, np.nan), np.zeros(shape[:-1]), np.full(shape[:-1], np.nan)
        return self._value, self._speed, self._time

"""What the live output may do from one frame to the next: joint limits always, velocity limits between frames.

Offline, a trajectory too fast for the robot is retimed (:mod:`nlo_lab.inference.retime`): its
frames get later times. Live, the times are the camera's and cannot move, so the output is
**rate limited** instead: each joint moves from its last output towards the optimiser's angle
(the target) by at most its velocity limit times the time since the last frame, and the result is
clipped into the joint limits. With both the last output and the target inside the limits, the
clipped step is the step itself, so the finite-difference speed of every joint between two
outputs is at most its limit (``nlo_lab.metrics.velocity_violations`` counts none) and no output
leaves the limits (``nlo_lab.metrics.limit_violations``), whatever the targets do: a jump, a NaN,
a person who leaves.

When nobody is seen the target is the robot's rest pose (``robot.neutral_q``), approached
exponentially (:func:`ease_toward`: a fraction ``1 - exp(-dt / tau)`` of the way per frame), and
rate limited like any target.
"""

from __future__ import annotations

import math

import numpy as np

from nlo_lab.errors import SettingsError

__all__ = ["SPEED_MARGIN", "MotionLimits", "ease_toward"]

SPEED_MARGIN = 1.0 - 1e-9  # steps are this fraction of the allowed one: rounding never makes a step too fast


def ease_toward(q: np.ndarray, rest: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """``q`` moved a fraction ``1 - exp(-dt / tau)`` of the way to ``rest`` (an exponential approach with time constant ``tau`` [s])."""
    return q + (rest - q) * (1.0 - math.exp(-max(dt, 0.0) / tau))


class MotionLimits:
    """A robot's joint and velocity limits, applied to successive outputs (see the module docstring).

    Args:
        lower, upper: ``(n,)`` joint limits [rad].
        velocity: ``(n,)`` velocity limits [rad/s] (``inf``: none), the robot spec's ``velocity_limits``.
        speed_fraction: move at most this fraction of each velocity limit (0 < f <= 1).
    """

    def __init__(self, lower, upper, velocity, speed_fraction: float = 1.0):
        self.lower = np.asarray(lower, dtype=np.float64).reshape(-1)
        self.upper = np.asarray(upper, dtype=np.float64).reshape(-1)
        self.velocity = np.asarray(velocity, dtype=np.float64).reshape(-1)
        if not (self.lower.shape == self.upper.shape == self.velocity.shape) or not (self.lower <= self.upper).all():
            raise SettingsError("joint limits and velocity limits must be (n,) each, lower <= upper")
        if not (self.velocity > 0).all():
            raise SettingsError("velocity limits must be > 0 (inf = no limit)")
        if not 0 < float(speed_fraction) <= 1:
            raise SettingsError(f"speed_fraction must be in (0, 1], got {speed_fraction!r}")
        self.speed_fraction = float(speed_fraction)

    @classmethod
    def of(cls, robot, speed_fraction: float = 1.0) -> MotionLimits:
        """The limits of a :class:`~nlo_lab.robot.Robot`."""
        f = lambda x: x.detach().cpu().double().numpy()  # noqa: E731
        return cls(f(robot.lower_limits), f(robot.upper_limits), f(robot.velocity_limits), speed_fraction)

    def clip(self, q: np.ndarray) -> np.ndarray:
        """``q`` inside the joint limits (NaN becomes the nearest limit's midpoint: never a NaN out)."""
        q = np.asarray(q, dtype=np.float64)
        q = np.where(np.isfinite(q), q, (self.lower + self.upper) / 2)
        return np.clip(q, self.lower, self.upper)

    def step(self, previous: np.ndarray, target: np.ndarray, dt: float) -> np.ndarray:
        """The next output: from ``previous`` towards ``target`` by at most each joint's velocity limit x ``dt`` [s], in the limits.

        ``previous`` must be inside the joint limits (every output of :meth:`step` is); a non-finite
        target entry keeps that joint where it was.
        """
        previous = np.asarray(previous, dtype=np.float64)
        target = np.asarray(target, dtype=np.float64)
        target = self.clip(np.where(np.isfinite(target), target, previous))
        finite = np.isfinite(self.velocity)
        most = np.where(finite, np.where(finite, self.velocity, 0.0) * self.speed_fraction * max(float(dt), 0.0) * SPEED_MARGIN, np.inf)
        return self.clip(previous + np.clip(target - previous, -most, most))

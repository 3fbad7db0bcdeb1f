"""The joint-space baseline: Adam on the angles themselves, the same objective as the
latent optimisation (:mod:`nlo_lab.inference.latent`), no network."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import torch

from nlo_lab.errors import SettingsError
from nlo_lab.inference.descent import OptimizeResult, descend, smoothness_term
from nlo_lab.inference.fast_paths import FastPaths, fast_paths
from nlo_lab.inference.settings import JointOptimizeSettings
from nlo_lab.objective import TERMS, LossWeights, Objective, Targets

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["optimize_joints"]


def optimize_joints(
    robot: Robot,
    targets: Targets,
    settings: JointOptimizeSettings | None = None,
    *,
    weights: LossWeights | None = None,
    q0: torch.Tensor | None = None,
    callback: Callable[[int, float], None] | None = None,
    fast: bool | FastPaths = False,
) -> OptimizeResult:
    """The joint-space baseline: Adam on the angles themselves, same objective.

    Limits by projection (``clamp``) or a soft penalty (``penalty``); see
    :class:`~nlo_lab.inference.JointOptimizeSettings`. ``fast``: the objective's forms, as
    :func:`~nlo_lab.inference.optimize_latent`'s. Returns an
    :class:`~nlo_lab.inference.OptimizeResult` with ``z=None``.
    """
    settings = settings or JointOptimizeSettings()
    weights = weights or LossWeights()
    start = time.perf_counter()
    lo, hi = robot.lower_limits, robot.upper_limits
    dtype = lo.dtype
    targets = targets.to(dtype=dtype)
    T = len(targets)
    if q0 is None:
        starts = {"neutral": lambda: robot.neutral_q, "midpoint": lambda: (lo + hi) / 2, "zeros": lambda: torch.zeros_like(lo).clamp(lo, hi)}
        base = starts[settings.init]().to(dtype=lo.dtype, device=lo.device)
        q0 = base.expand(T, -1)
    elif q0.shape != (T, lo.shape[0]):
        raise SettingsError(f"q0 must be {(T, lo.shape[0])}, got {tuple(q0.shape)}")

    loss_fn = Objective(robot, targets, weights, settings.collision_form, **fast_paths(fast, T, lo.device).objective_options())
    smooth = smoothness_term(robot, targets, weights)

    def evaluate(q):
        total, terms = loss_fn(q)
        if smooth is not None:
            total = total + smooth(q)
        if settings.limits == "penalty":
            violation = torch.relu(q - hi) + torch.relu(lo - q)
            total = total + settings.penalty * violation.pow(2).sum(-1)
        return total, q, terms

    def clamp(q):
        q.copy_(torch.maximum(torch.minimum(q, hi), lo))

    project = clamp if settings.limits == "clamp" else None
    _, q, loss, terms, history, steps = descend(
        q0.to(dtype), evaluate, project, settings.iterations, settings.patience, settings.lr, callback,
        per_sample=smooth is None,
    )
    terms = dict(zip(TERMS, terms.unbind(1), strict=True))
    return OptimizeResult(q, None, history, terms, loss, steps, time.perf_counter() - start, f"joints-{settings.init}")

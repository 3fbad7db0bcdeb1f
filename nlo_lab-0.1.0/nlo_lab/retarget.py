"""One call from a demonstration to a robot trajectory and its quality figures.

This is the glue the command line, the notebooks and ``make demo`` share:
targets from the demonstration, latent optimisation with the shipped model,
the trajectory, and the metric of DESIGN.md ("Metric").
"""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from nlo_lab.human import Demonstration
from nlo_lab.losses import LossWeights, targets_from_demonstration
from nlo_lab.metrics import limit_violations, self_collision_frames, tracking_errors
from nlo_lab.optimize import OptimizeResult, OptimizeSettings, optimize_latent
from nlo_lab.robots import Robot
from nlo_lab.threads import single_thread
from nlo_lab.train import load_pretrained
from nlo_lab.trajectory import RobotTrajectory

__all__ = ["RetargetResult", "retarget", "summary"]


@dataclass
class RetargetResult:
    """What :func:`retarget` returns.

    Attributes:
        trajectory: the robot's joint trajectory (T, n).
        optimization: the latent optimisation's result (loss history, terms, z).
        seconds: wall time of the retargeting itself (targets + optimisation) [s].
        summary: the JSON summary of the command line (see :func:`summary`).
    """

    trajectory: RobotTrajectory
    optimization: OptimizeResult
    seconds: float
    summary: dict[str, Any] = field(default_factory=dict)


def retarget(
    demo: Demonstration,
    robot: Robot,
    *,
    settings: OptimizeSettings | None = None,
    weights: LossWeights | None = None,
    model=None,
    progress: bool = False,
) -> RetargetResult:
    """Retarget a whole demonstration to ``robot`` by neural latent optimisation.

    Args:
        demo: the human demonstration.
        robot: a loaded robot (``nlo_lab.robots.load_robot``).
        settings: initialisation strategy, iteration budget, ... (defaults: encoder, 100).
        weights: loss weights (defaults of the paper).
        model: a trained model for this robot; the shipped checkpoint when omitted.
        progress: show a progress bar of the optimisation's iterations on stderr
            (the command line turns it on for a terminal: long clips take seconds).

    Returns:
        A :class:`RetargetResult` with the trajectory and the quality figures.
    """
    settings = settings or OptimizeSettings()
    weights = weights or LossWeights()
    model = model if model is not None else load_pretrained(robot)
    with single_thread():
        start = time.perf_counter()
        targets = targets_from_demonstration(demo, dtype=robot.lower_limits.dtype)
        with _progress_bar(progress, settings.iterations, f"retarget {len(demo)} frames to {robot.name}") as callback:
            result = optimize_latent(model, robot, targets, settings, weights=weights, callback=callback)
        seconds = time.perf_counter() - start
    angles = result.q.detach().cpu().numpy().astype(np.float64)
    trajectory = RobotTrajectory(robot=robot.name, joint_names=list(robot.joint_names), angles=angles, fps=demo.fps)
    out = RetargetResult(trajectory=trajectory, optimization=result, seconds=seconds)
    out.summary = summary(demo, robot, out)
    return out


@contextmanager
def _progress_bar(show: bool, iterations: int, desc: str):
    """A callback ``(iteration, mean_loss)`` that advances a tqdm bar, or None."""
    if not show:
        yield None
        return
    from tqdm.auto import tqdm

    bar = tqdm(total=iterations + 1, desc=desc, unit="it", file=sys.stderr, leave=False)

    def callback(iteration: int, loss: float) -> None:
        bar.update(1)
        bar.set_postfix(loss=f"{loss:.3g}", refresh=False)

    try:
        yield callback
    finally:
        bar.close()


def summary(demo: Demonstration, robot: Robot, result: RetargetResult) -> dict[str, Any]:
    """The command line's JSON object (DESIGN.md, "Command line")."""
    angles = torch.tensor(np.array(result.trajectory.angles), dtype=robot.lower_limits.dtype)  # a writable copy
    errors = tracking_errors(demo, robot, angles)
    return {
        "robot": robot.name,
        "input": demo.name,
        "frames": len(demo),
        "fps": demo.fps,
        "seconds": round(result.seconds, 4),
        "iterations": int(result.optimization.iterations),
        "frechet_m": float(errors["frechet_m"]),
        "frechet_wrist_m": float(errors["frechet_wrist_m"]),
        "frechet_elbow_m": float(errors["frechet_elbow_m"]),
        "self_collision_frames": int(self_collision_frames(robot, angles)),
        "limit_violations": int(limit_violations(robot, angles)),
        "final_loss": float(result.optimization.history[-1]) if len(result.optimization.history) else None,
    }

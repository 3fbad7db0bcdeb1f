"""One call from a demonstration to a robot trajectory and its quality figures.

This is the glue the command line, the notebooks and ``make demo`` share:
targets from the demonstration, latent optimisation with the shipped model,
the trajectory, and the metric of ``nlo_lab.metrics`` (Fréchet distance of wrists and elbows).
"""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.human import Demonstration
from nlo_lab.objective import LossWeights, Targets, targets_from_demonstration
from nlo_lab.metrics import (
    limit_violations,
    max_joint_speed_ratio,
    max_joint_step,
    self_collision_frames,
    tracking_errors,
    velocity_violations,
)
from nlo_lab.optimize import OptimizeResult, OptimizeSettings, initial_latent, optimize_latent
from nlo_lab.retime import retime_times
from nlo_lab.robot import Robot
from nlo_lab.threads import single_thread
from nlo_lab.model import load_pretrained
from nlo_lab.trajectory import RobotTrajectory

__all__ = ["CHUNK_FRAMES", "RetargetResult", "retarget", "summary"]

# Frames optimised together. Frames are independent (per-frame losses, per-frame Adam),
# so chunks only bound memory: the autograd graph of one step holds about 0.3 MB per
# frame, so 1000 frames take a few hundred MB however long the recording is
# (benchmarks/long_recording.py). The one coupling is the patience stop, which looks
# at the mean loss of the frames optimised together (here: of one chunk). With the
# smoothness term (LossWeights.smooth) frames are coupled to their neighbours; across a
# chunk boundary the previous chunk's last frame is a fixed anchor of the next chunk's
# first step (optimize_latent(anchor=...)), in its objective and its warm start.
CHUNK_FRAMES = 1000


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
    chunk_frames: int | None = CHUNK_FRAMES,
    retime: bool = True,
) -> RetargetResult:
    """Retarget a whole demonstration to ``robot`` by neural latent optimisation.

    Args:
        demo: the human demonstration.
        robot: a loaded robot (``nlo_lab.robot.load_robot``).
        settings: initialisation strategy, iteration budget, ... (defaults: encoder, 100).
        weights: loss weights (defaults of the paper).
        model: a trained model for this robot; the shipped checkpoint when omitted.
        progress: show a progress bar of the optimisation's iterations on stderr
            (the command line turns it on for a terminal: long clips take seconds).
        chunk_frames: optimise at most this many frames at once (bounded memory,
            see :data:`CHUNK_FRAMES`); None for the whole recording in one batch.
        retime: slow the trajectory down where a joint would exceed its velocity limit
            (:mod:`nlo_lab.retime`); the trajectory's ``time`` then says when each frame plays.

    Returns:
        A :class:`RetargetResult` with the trajectory and the quality figures.

    Raises:
        DemonstrationError: ``demo`` is not (or no longer) valid: NaN where its mask
            says valid, a wrist rotation that is not a rotation, fps out of range.
        SettingsError: the loss became NaN or infinite (e.g. absurd weights).
    """
    demo.validate()  # again: the arrays may have changed since the demonstration was built
    settings = settings or OptimizeSettings()
    weights = weights or LossWeights()
    if chunk_frames is not None and (isinstance(chunk_frames, bool) or not isinstance(chunk_frames, int) or chunk_frames < 1):
        raise SettingsError(f"chunk_frames must be a whole number >= 1 or None, got {chunk_frames!r}")
    model = model if model is not None else load_pretrained(robot)
    with single_thread():
        start = time.perf_counter()
        targets = targets_from_demonstration(demo, dtype=robot.lower_limits.dtype)
        size = len(targets) if chunk_frames is None else chunk_frames
        bounds = [(a, min(a + size, len(targets))) for a in range(0, len(targets), size)]
        desc = f"retarget {len(demo)} frames to {robot.name}"
        with _progress_bar(progress, (settings.iterations + 1) * len(bounds), desc) as callback:
            result = _optimize_chunks(model, robot, targets, settings, weights, bounds, callback)
        seconds = time.perf_counter() - start
    if not all(np.isfinite(result.history)) or not bool(torch.isfinite(result.loss).all()):
        raise SettingsError("the loss became NaN or infinite (are the loss weights absurdly large?)")
    angles = result.q.detach().cpu().numpy().astype(np.float64)
    times = retime_times(angles, demo.fps, robot.velocity_limits.double().numpy()) if retime else None
    trajectory = RobotTrajectory(robot=robot.name, joint_names=list(robot.joint_names), angles=angles, fps=demo.fps, time=times)
    out = RetargetResult(trajectory=trajectory, optimization=result, seconds=seconds)
    out.summary = summary(demo, robot, out)
    return out


def _optimize_chunks(model, robot, targets: Targets, settings, weights, bounds, callback) -> OptimizeResult:
    """:func:`optimize_latent` over frame ranges ``bounds``, joined into one result.

    ``history`` is the frame-weighted mean over chunks (a chunk that stopped early
    contributes its last value), ``iterations`` the most steps any chunk took. Each
    chunk after the first is anchored at the previous chunk's last angles (smoothness
    across the boundary).
    """
    if len(bounds) == 1:
        return optimize_latent(model, robot, targets, settings, weights=weights, callback=callback)
    # random starts are drawn for the whole recording at once: chunking leaves them unchanged
    z_all = None if settings.init in ("encoder", "zeros") else initial_latent(model, targets, settings)
    parts = []
    for a, b in bounds:
        part = targets.index(slice(a, b))
        z0 = initial_latent(model, part, settings) if z_all is None else z_all[a:b]
        anchor = parts[-1].q[-1] if parts else None
        parts.append(optimize_latent(model, robot, part, settings, weights=weights, z0=z0, callback=callback, anchor=anchor))
    n = max(len(r.history) for r in parts)
    T = len(targets)
    history = [sum(r.history[min(i, len(r.history) - 1)] * len(r.q) for r in parts) / T for i in range(n)]
    return OptimizeResult(
        q=torch.cat([r.q for r in parts]),
        z=torch.cat([r.z for r in parts]),
        history=history,
        terms={k: torch.cat([r.terms[k] for r in parts]) for k in parts[0].terms},
        loss=torch.cat([r.loss for r in parts]),
        iterations=max(r.iterations for r in parts),
        seconds=sum(r.seconds for r in parts),
        init=settings.init,
    )


@contextmanager
def _progress_bar(show: bool, total: int, desc: str):
    """A callback ``(iteration, mean_loss)`` that advances a tqdm bar, or None."""
    if not show:
        yield None
        return
    from tqdm.auto import tqdm

    bar = tqdm(total=total, desc=desc, unit="it", file=sys.stderr, leave=False)

    def callback(iteration: int, loss: float) -> None:
        bar.update(1)
        bar.set_postfix(loss=f"{loss:.3g}", refresh=False)

    try:
        yield callback
    finally:
        bar.close()


def summary(demo: Demonstration, robot: Robot, result: RetargetResult) -> dict[str, Any]:
    """The command line's JSON object (README.md, "Command line").

    Joint speed keys: ``velocity_violations`` (frame pairs x joints over the velocity limit)
    and ``max_joint_speed_ratio`` on the trajectory file's own time base;
    ``recording_speed_ratio`` the same ratio had the frames played at the recording's
    rate; ``slowdown`` the output's duration over the recording's (1 = not retimed);
    ``max_joint_step_rad`` the largest change of a joint between consecutive frames;
    ``depth``: ``"world"`` (measured 3-D) or ``"image"`` (reconstructed from an image-only recording).
    """
    traj = result.trajectory
    angles = torch.tensor(np.array(traj.angles), dtype=robot.lower_limits.dtype)  # a writable copy
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
        "velocity_violations": velocity_violations(robot, traj.angles, traj.times),
        "max_joint_speed_ratio": round(max_joint_speed_ratio(robot, traj.angles, traj.times), 4),
        "recording_speed_ratio": round(max_joint_speed_ratio(robot, traj.angles, fps=demo.fps), 4),
        "slowdown": round(traj.duration / demo.duration, 4),
        "max_joint_step_rad": round(max_joint_step(traj.angles), 4),
        "depth": str(demo.meta.get("depth", "world")),
        "final_loss": float(result.optimization.history[-1]) if len(result.optimization.history) else None,
    }

"""The pipeline: one call from a demonstration to a robot trajectory and its quality figures.

The pipeline is assembled in one place, :class:`RetargetConfig` (in the manner of
dex-retargeting's ``RetargetingConfig.build()``): the robot, the loss weights, the
optimisation settings and the model (the shipped checkpoint unless given) make a
:class:`Retargeter`, which turns a demonstration into the objective's targets and the
encoder's input, optimises the latents (in chunks of bounded memory), retimes the
angles to the robot's velocity limits and measures the result with the metric of
``nlo_lab.metrics`` (Fréchet distance of wrists and elbows). :func:`retarget` is
``RetargetConfig(...).build()(demo)``; the command line, the notebooks, the lab's panel
and the evaluation's latent methods all go through it.

It assembles inference (the optimisation, :mod:`nlo_lab.inference`) and the metrics
(:mod:`nlo_lab.metrics`) into one call, so it comes after both on the data's path
(docs/ARCHITECTURE.md, "The order"): inference imports no metric, and the metrics no
inference. :func:`summary` is the command line's JSON object.
"""

from __future__ import annotations

import os
import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from tqdm.auto import tqdm

from nlo_lab.errors import SettingsError
from nlo_lab.human import FINGERS, SIDES, Demonstration
from nlo_lab.inference.descent import OptimizeResult, join_results
from nlo_lab.inference.fast_paths import FastPaths, fast_paths
from nlo_lab.inference.hand_stage import finger_joints, hand_joint_mask, refine_hands
from nlo_lab.inference.inputs import RetargetInputs
from nlo_lab.inference.latent import initial_latent, optimize_latent
from nlo_lab.inference.retime import retime_times
from nlo_lab.inference.settings import OptimizeSettings
from nlo_lab.inference.trajectory import RobotTrajectory
from nlo_lab.metrics import (
    hand_summary,
    limit_violations,
    max_joint_speed_ratio,
    max_joint_step,
    self_collision_frames,
    tracking_errors,
    velocity_violations,
)
from nlo_lab.model import load_pretrained
from nlo_lab.objective import TERMS, LossWeights, Targets
from nlo_lab.robot import Robot
from nlo_lab.settings import COUNT_RANGE, HAND_SEARCH, check_bool, check_int, check_type
from nlo_lab.threads import single_thread

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.model import RetargetModel

__all__ = ["CHUNK_FRAMES", "RetargetConfig", "Retargeter", "RetargetResult", "has_hand_joints", "retarget", "summary"]

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


def has_hand_joints(robot: Robot) -> bool:
    """Does ``robot`` have finger joints below its wrists, the hand stage's (YuMi's hands; not NAO's or Pepper's)?"""
    return robot.has_fingers and bool(hand_joint_mask(robot).any())


def searchable_fingers(robot: Robot) -> tuple[str, ...]:
    """The fingers (``FINGERS`` order) that a joint of ``robot``'s hands moves alone on some side: what the hand
    stage's search can set (none on a robot without hand joints)."""
    if not has_hand_joints(robot):
        return ()
    own = {f for side in SIDES for f in robot.arm(side).fingers if finger_joints(robot, side, f)}
    return tuple(f for f in FINGERS if f in own)


def hand_search(robot: Robot, settings: OptimizeSettings) -> tuple[str, ...]:
    """The fingers the hand stage searches on ``robot``: ``settings.hand_search``, or when it is None (the default)
    those of ``HAND_SEARCH`` that ``robot``'s hands move alone (YuMi's Inspire hands: middle, ring and little;
    none on NAO or Pepper)."""
    if settings.hand_search is not None:
        return settings.hand_search
    own = searchable_fingers(robot)
    return tuple(f for f in HAND_SEARCH if f in own)


@dataclass(frozen=True)
class RetargetConfig:
    """Everything that decides a retargeting; :meth:`build` assembles the pipeline.

    Attributes:
        robot: a loaded robot (``nlo_lab.robot.load_robot``).
        settings: initialisation strategy, iteration budget, ... (default: encoder, 100).
        weights: loss weights (default: the paper's).
        model: a trained model for this robot; None: ``checkpoint``, else the shipped checkpoint
            (:func:`nlo_lab.model.load_pretrained`).
        chunk_frames: optimise at most this many frames at once (bounded memory,
            see :data:`CHUNK_FRAMES`); None for the whole recording in one batch.
        retime: slow the trajectory down where a joint would exceed its velocity limit
            (:mod:`nlo_lab.inference.retime`); the trajectory's ``time`` then says when each frame plays.
        progress: show a progress bar of the optimisation's iterations on stderr.
        fast: which evaluations the optimisation runs (same numbers either way): True (the
            default) the fastest for each chunk's batch size
            (:meth:`~nlo_lab.inference.FastPaths.for_frames`), False the readable forms (the
            paper's decoder, the term functions, autograd through FK), or a
            :class:`~nlo_lab.inference.FastPaths` for every chunk.
        checkpoint: a checkpoint file of this robot (``nlo-lab train --out``) to load when
            ``model`` is None: a robot drafted from its URDF has no shipped one.
    """

    robot: Robot
    settings: OptimizeSettings | None = None
    weights: LossWeights | None = None
    model: Any = None
    chunk_frames: int | None = CHUNK_FRAMES
    retime: bool = True
    progress: bool = False
    fast: bool | FastPaths = True
    checkpoint: str | os.PathLike | None = None

    def build(self) -> Retargeter:
        """Check the configuration, load the model if none was given, and return the retargeter.

        Raises:
            SettingsError: ``chunk_frames`` is not a whole number >= 1 or None; ``fast`` is
                not True, False or a FastPaths; ``settings.hand_search`` names fingers for a robot without
                finger joints, or a finger no joint of its hands moves alone (nothing to search);
                ``settings.hand_slowdown`` other than 1 for a robot without hand joints (nothing to slow).
            CheckpointError: no shipped checkpoint for this robot (``model`` and ``checkpoint``
                omitted), or a ``checkpoint`` that is missing, damaged or made for another robot.
        """
        check_type("robot", self.robot, Robot, "a Robot (nlo_lab.robot.load_robot)")
        if self.model is not None and self.checkpoint is not None:
            raise SettingsError("give a model or a checkpoint, not both")
        if self.settings is not None:
            check_type("settings", self.settings, OptimizeSettings)
        if self.weights is not None:
            check_type("weights", self.weights, LossWeights)
        if self.chunk_frames is not None:
            check_int("chunk_frames", self.chunk_frames, *COUNT_RANGE)
        check_bool("retime", self.retime)
        check_bool("progress", self.progress)
        fast_paths(self.fast, 1)  # checked here, before any work
        self._check_hand_search()
        model = self.model if self.model is not None else load_pretrained(self.robot, self.checkpoint)
        return Retargeter(self, model, self.settings or OptimizeSettings(), self.weights or LossWeights())

    def _check_hand_search(self) -> None:
        """A searched finger must have joints of its own on this robot, and a hand slowdown hand joints: else the
        setting would silently do nothing."""
        search = self.settings.hand_search if self.settings is not None else None
        search = search or ()  # None: the robot's default (hand_search), never refused
        slowdown = self.settings.hand_slowdown if self.settings is not None else 1.0
        if slowdown != 1.0 and not search and not has_hand_joints(self.robot):  # with a search: its message below
            raise SettingsError(f"hand_slowdown ({slowdown:g}): {self.robot.name} has no hand joints for the hand stage to "
                                "move (a robot with hands, such as yumi)")
        if not search:
            return
        if not has_hand_joints(self.robot):
            raise SettingsError(f"hand_search ({', '.join(search)}): {self.robot.name} has no finger joints to search "
                                "(the hand stage runs on a robot with hands, such as yumi)")
        own = searchable_fingers(self.robot)
        missing = [f for f in search if f not in own]
        if missing:
            raise SettingsError(f"hand_search: no joint of {self.robot.name}'s hands moves {', '.join(missing)} alone, so nothing "
                                f"would be searched (fingers with joints of their own: {', '.join(f for f in FINGERS if f in own) or 'none'})")


class Retargeter:
    """The assembled pipeline (made by :meth:`RetargetConfig.build`): call it on a demonstration.

    ``retargeter(demo)`` does what :func:`retarget` documents. Its steps are public for
    callers that need one of them: :meth:`inputs` (targets and encoder input of a
    demonstration), :meth:`start` (the start latents), :meth:`optimize` (the latent
    optimisation of some frames), :meth:`optimize_frame` (one frame, e.g. warm-started from
    its current latent), :meth:`fast_paths` (which evaluations run at a batch size).
    """

    def __init__(self, config: RetargetConfig, model: RetargetModel, settings: OptimizeSettings, weights: LossWeights):
        self.config, self.robot, self.model = config, config.robot, model
        self.settings, self.weights = settings, weights
        self.has_hand_joints = has_hand_joints(self.robot)
        self.hand_search = hand_search(self.robot, settings)  # the fingers its hand stage searches

    def inputs(self, demo: Demonstration) -> RetargetInputs:
        """The demonstration's targets (in the robot's dtype and device) and encoder input."""
        lo = self.robot.lower_limits
        return RetargetInputs.from_demonstration(demo, dtype=lo.dtype, device=lo.device)

    def start(self, inputs: RetargetInputs) -> torch.Tensor:
        """``(T, N_r, k)`` start latents for ``settings.init`` (:func:`~nlo_lab.inference.initial_latent`)."""
        return initial_latent(self.model, inputs.encoder, self.settings)

    def optimize(self, inputs: RetargetInputs, *, z0: torch.Tensor | None = None, callback=None, hands: bool = True) -> OptimizeResult:
        """Latent optimisation of ``inputs``' frames, at most ``chunk_frames`` at once, then the hand stage.

        Args:
            inputs: :meth:`inputs` of a demonstration, or some of its frames (``inputs.index``).
            z0: ``(T, N_r, k)`` start latents (a warm start); default :meth:`start`.
            callback: ``callback(iteration, mean_loss)`` after every evaluation of every chunk.
            hands: after each chunk's latent optimisation, the hand stage
                (:func:`~nlo_lab.inference.hand_stage.refine_hands`, ``settings.hand_iterations`` steps):
                the hand joints alone on the same objective. ``q`` then holds its hands (``z`` still
                decodes to the latent optimisation's), ``loss`` and ``terms`` are at ``q``, ``seconds``
                counts both, ``extra["hand_steps"]`` and ``extra["hand_seconds"]`` say how many steps it took
                (the most of any chunk) and how long (all chunks).

        The latent optimisation runs ``weights.latent_stage()`` (the hand stage's direction terms,
        ``tip_dir`` and ``finger_dir``, at 0); the hand stage runs ``weights``.

        Chunks after the first are anchored at the previous chunk's last angles (smoothness
        across the boundary); ``history`` is the frame-weighted mean over chunks (a chunk that
        stopped early contributes its last value), ``iterations`` the most steps any chunk took.
        Runs in :func:`~nlo_lab.threads.single_thread` (torch's and numpy's BLAS threads).
        """
        with single_thread():
            return self._optimize_chunks(inputs, z0, callback, hands)

    def _optimize_chunks(self, inputs: RetargetInputs, z0: torch.Tensor | None, callback, hands: bool) -> OptimizeResult:
        bounds = self._bounds(len(inputs))
        if len(bounds) == 1:
            return self._optimize(inputs.targets, hands, z0=z0, encoder_input=inputs.encoder, callback=callback)
        # random starts are drawn for the whole recording at once: chunking leaves them unchanged
        if z0 is None and self.settings.init not in ("encoder", "zeros"):
            z0 = self.start(inputs)
        parts: list[OptimizeResult] = []
        for a, b in bounds:
            part = inputs.index(slice(a, b))
            anchor = parts[-1].q[-1] if parts else None
            start = self.start(part) if z0 is None else z0[a:b]
            parts.append(self._optimize(part.targets, hands, z0=start, callback=callback, anchor=anchor))
        joined = join_results(parts, self.settings.init, sum(r.seconds for r in parts), frames_weighted=True)
        if all("hand_steps" in r.extra for r in parts):  # the hand stage ran on every chunk
            joined.extra["hand_steps"] = max(r.extra["hand_steps"] for r in parts)
            joined.extra["hand_seconds"] = sum(r.extra["hand_seconds"] for r in parts)
        return joined

    def optimize_frame(self, inputs: RetargetInputs, t: int, z0: torch.Tensor | None = None) -> OptimizeResult:
        """Frame ``t`` of ``inputs`` alone, from ``z0 (1, N_r, k)`` (e.g. its current latent: a warm
        start) or from ``settings.init`` (the lab's panel re-optimising the frame a slider shows, the
        live stream). The latent optimisation only, without the hand stage: it stays interactive."""
        return self.optimize(inputs.index(slice(t, t + 1)), z0=z0, hands=False)

    def fast_paths(self, frames: int) -> FastPaths:
        """The evaluations an optimisation of ``frames`` frames runs (the config's ``fast``):
        the one place the pipeline chooses them."""
        return fast_paths(self.config.fast, frames, self.robot.lower_limits.device)

    def _optimize(self, targets: Targets, hands: bool, **options) -> OptimizeResult:
        fast = self.fast_paths(len(targets))
        result = optimize_latent(self.model, self.robot, targets, self.settings, weights=self.weights.latent_stage(), fast=fast,
                                 **options)
        if not hands or self.settings.hand_iterations == 0 or len(targets) == 0 or not self.has_hand_joints:
            return result
        stage = refine_hands(self.robot, result.q, targets, self.weights, iterations=self.settings.hand_iterations,
                             patience=self.settings.patience, lr=self.settings.hand_lr,
                             collision_form=self.settings.collision_form, anchor=options.get("anchor"), fast=fast,
                             search=self.hand_search, grid=self.settings.hand_grid,
                             slowdown=self.settings.hand_slowdown)
        if result.z is not None:  # the latent term, as in the latent optimisation's loss
            latent = result.z.detach().pow(2).flatten(1).sum(1).to(stage.loss.dtype)
            stage.loss = stage.loss + self.weights.latent * latent
        result.q, result.loss = stage.q, stage.loss
        result.terms = dict(zip(TERMS, stage.terms.unbind(1), strict=True))
        result.seconds += stage.seconds
        result.extra["hand_steps"], result.extra["hand_seconds"] = stage.steps, stage.seconds
        return result

    def _bounds(self, frames: int) -> list[tuple[int, int]]:
        """The ``(first, end)`` frame ranges :meth:`optimize` optimises together (one when ``frames`` is 0)."""
        size = self.config.chunk_frames or max(frames, 1)
        return [(a, min(a + size, frames)) for a in range(0, frames, size)] or [(0, 0)]

    def chunks(self, frames: int) -> int:
        """How many chunks :meth:`optimize` splits ``frames`` frames into."""
        return len(self._bounds(frames))

    def __call__(self, demo: Demonstration) -> RetargetResult:
        check_type("demo", demo, Demonstration, "a Demonstration (nlo_lab.human.load_demonstration)")
        demo.validate()  # again: the arrays may have changed since the demonstration was built
        robot, settings = self.robot, self.settings
        with single_thread():
            start = time.perf_counter()
            inputs = self.inputs(demo)
            desc = f"retarget {len(demo)} frames to {robot.name}"
            with _progress_bar(self.config.progress, (settings.iterations + 1) * self.chunks(len(inputs)), desc) as callback:
                result = self.optimize(inputs, callback=callback)
            seconds = time.perf_counter() - start
        if not all(np.isfinite(result.history)) or not bool(torch.isfinite(result.loss).all()):
            raise SettingsError(f"the loss became NaN or infinite retargeting {demo.name or 'the demonstration'!r} to {robot.name} "
                                "(values beyond what float32 holds, from the demonstration or the loss weights)", path=demo.path)
        angles = result.q.detach().cpu().numpy().astype(np.float64)
        limits = robot.velocity_limits.double().numpy()
        times = retime_times(angles, demo.fps, limits) if self.config.retime else None
        trajectory = RobotTrajectory(robot=robot.name, joint_names=tuple(robot.joint_names), angles=angles, fps=demo.fps, time=times)
        out = RetargetResult(trajectory=trajectory, optimization=result, seconds=seconds)
        with single_thread():  # the metrics' FK too: with a thread per core, a busy machine made it 10x slower
            out.summary = summary(demo, robot, out, cull=self.fast_paths(len(demo)).cull_far_pairs)
        return out


def retarget(
    demo: Demonstration,
    robot: Robot,
    *,
    settings: OptimizeSettings | None = None,
    weights: LossWeights | None = None,
    model: RetargetModel | None = None,
    progress: bool = False,
    chunk_frames: int | None = CHUNK_FRAMES,
    retime: bool = True,
    fast: bool | FastPaths = True,
    checkpoint: str | os.PathLike | None = None,
) -> RetargetResult:
    """Retarget a whole demonstration to ``robot`` by neural latent optimisation.

    ``RetargetConfig(robot, settings, weights, model, chunk_frames, retime, progress, fast).build()(demo)``.

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
            (:mod:`nlo_lab.inference.retime`); the trajectory's ``time`` then says when each frame plays.
        fast: the evaluations the optimisation runs (see :class:`RetargetConfig`); False: the readable forms.
        checkpoint: a checkpoint file to load instead of the shipped one (a robot drafted from its URDF).

    Returns:
        A :class:`RetargetResult` with the trajectory and the quality figures.

    Raises:
        DemonstrationError: ``demo`` is not (or no longer) valid: NaN where its mask
            says valid, a wrist rotation that is not a rotation, fps out of range.
        SettingsError: the loss became NaN or infinite (e.g. absurd weights).
    """
    config = RetargetConfig(robot, settings, weights, model, chunk_frames, retime, progress, fast, checkpoint)
    return config.build()(demo)


@contextmanager
def _progress_bar(show: bool, total: int, desc: str):
    """A callback ``(iteration, mean_loss)`` that advances a tqdm bar, or None."""
    if not show:
        yield None
        return

    bar = tqdm(total=total, desc=desc, unit="it", file=sys.stderr, leave=False)

    def callback(iteration: int, loss: float) -> None:
        bar.update(1)
        bar.set_postfix(loss=f"{loss:.3g}", refresh=False)

    try:
        yield callback
    finally:
        bar.close()


def summary(demo: Demonstration, robot: Robot, result: RetargetResult, cull: bool = False) -> dict[str, Any]:
    """The command line's JSON object (README.md, "Command line").

    Joint speed keys: ``velocity_violations`` (frame pairs x joints over the velocity limit)
    and ``max_joint_speed_ratio`` on the trajectory file's own time base;
    ``recording_speed_ratio`` the same ratio had the frames played at the recording's
    rate; ``slowdown`` the output's duration over the recording's (1 = not retimed);
    ``max_joint_step_rad`` the largest change of a joint between consecutive frames;
    ``depth``: ``"world"`` (measured 3-D) or ``"image"`` (reconstructed from an image-only recording).
    Handshape keys (:func:`~nlo_lab.metrics.hand_summary`): ``hand_frames``, ``wrist_tip_deg``, ``thumb_tips_deg``,
    ``base_tip_deg``, ``pinch_r`` (None on a robot without five fingers).
    ``cull``: count the self-collision frames by the culled check (the same count, :func:`~nlo_lab.metrics.self_collision_frames`);
    the retargeting's own summary takes it with its fast paths.
    """
    traj = result.trajectory
    angles = traj.angles  # (T, n) float64; the metrics check and convert it themselves
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
        "self_collision_frames": int(self_collision_frames(robot, angles, cull=cull)),
        "limit_violations": int(limit_violations(robot, angles)),
        "velocity_violations": velocity_violations(robot, traj.angles, traj.times),
        "max_joint_speed_ratio": round(max_joint_speed_ratio(robot, traj.angles, traj.times), 4),
        "recording_speed_ratio": round(max_joint_speed_ratio(robot, traj.angles, fps=demo.fps), 4),
        "slowdown": round(traj.duration / demo.duration, 4),
        "max_joint_step_rad": round(max_joint_step(traj.angles), 4),
        "depth": str(demo.meta.get("depth", "world")),
        "final_loss": float(result.optimization.history[-1]) if len(result.optimization.history) else None,
        **hand_summary(robot, angles, demo),
    }

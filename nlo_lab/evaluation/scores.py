"""Evaluation of the method against the baselines on a corpus split (``nlo-lab evaluate``).

For every sequence and every method of :mod:`nlo_lab.evaluation.methods`: the tracking
error of docs/DESIGN.md, "Metric" (mean of wrist and elbow discrete Fréchet distances
after mapping the human into the robot frame), velocity and acceleration errors,
self-collision frames, joint-limit violations, the objective value and the wall
time. ``--json`` prints the contract object as the last line of stdout::

    {"methods": {NAME: {"frechet_m": mean, "per_sequence": {seq: frechet},
                        "collision_sequences": n, "limit_violations": n, "seconds": s,
                        "velocity_violations": n, "max_joint_speed_ratio": r, "slowdown": x,
                        "depth": "world"}}}

The joint-speed keys take each method's output as it is: on its own time base, which for
the latent methods in robot-ready mode (the default, ``--mode robot-ready``) is the retimed
one of ``nlo-lab retarget``, and otherwise frames 1/fps apart: ``velocity_violations`` summed
over the sequences, ``max_joint_speed_ratio`` and ``slowdown`` (how much longer the retimed
motion is, or would be) the largest over the sequences, ``depth`` the demonstrations'
(``"world"`` for the corpus). ``--mode paper`` evaluates the paper's objective instead (no
smoothness term, no retiming; :data:`~nlo_lab.evaluation.EVALUATION_MODES`).

Without ``--json`` a table like the paper's Table I (rows = sequences, columns =
methods, ``*`` = the sequence has at least one self-collision frame), made by
:mod:`nlo_lab.evaluation.tables`.

Command: ``nlo-lab evaluate --robot yumi [--split test] [--json] [--limit N] [--iters N] [--methods A,B]``.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from tqdm.auto import tqdm

from nlo_lab.corpus import sign_corpus
from nlo_lab.errors import SettingsError
from nlo_lab.evaluation.methods import LATENT_METHODS, METHODS, BaselineSettings, mean_objective, run_method
from nlo_lab.inference import retime_times
from nlo_lab.metrics import limit_violations, max_joint_speed_ratio, self_collision_frames, tracking_errors, velocity_violations
from nlo_lab.model import load_pretrained
from nlo_lab.training import supervised_network

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.model import RetargetModel
    from nlo_lab.robot import Robot

__all__ = ["SequenceScore", "Evaluation", "check_methods", "evaluate", "evaluate_split"]


@dataclass
class SequenceScore:
    """One method on one sequence.

    Attributes:
        frechet_m, frechet_wrist_m, frechet_elbow_m: tracking errors [m].
        velocity_error [m/s], acceleration_error [m/s²]: on wrists and elbows.
        collision_frames: frames with a penetrating capsule pair.
        limit_violations: (frame, joint) entries outside the limits.
        objective: mean ``L(D, K(q))`` over frames (no latent term).
        seconds: the method's wall time [s].
        frames: T.
        velocity_violations: (frame pair, joint) entries over the joint's velocity limit, on
            the method's output time base (retimed latent methods in robot-ready mode, else
            frames played at the recording's rate).
        max_joint_speed_ratio: largest joint speed over its limit, same time base.
        slowdown: how much longer retiming (``nlo_lab.inference.retime``) would make the motion.
        depth: ``"world"`` or ``"image"`` (the demonstration's ``meta["depth"]``).
    """

    frechet_m: float
    frechet_wrist_m: float
    frechet_elbow_m: float
    velocity_error: float
    acceleration_error: float
    collision_frames: int
    limit_violations: int
    objective: float
    seconds: float
    frames: int
    velocity_violations: int = 0
    max_joint_speed_ratio: float = float("nan")
    slowdown: float = float("nan")
    depth: str = "world"


@dataclass
class Evaluation:
    """Scores of every method on every sequence: ``scores[method][sequence]``.

    Attributes:
        robot: the robot's name.
        sequences: sequence names, in order.
        scores: ``{method: {sequence: SequenceScore}}``.
        info: extra facts (e.g. the supervised network's training time).
    """

    robot: str
    sequences: list[str]
    scores: dict[str, dict[str, SequenceScore]]
    info: dict = field(default_factory=dict)

    @property
    def methods(self) -> list[str]:
        return list(self.scores)

    def mean(self, method: str, key: str = "frechet_m") -> float:
        """Mean of one score over the sequences (NaNs skipped)."""
        v = np.array([getattr(s, key) for s in self.scores[method].values()], dtype=float)
        v = v[np.isfinite(v)]
        return float(v.mean()) if v.size else float("nan")

    def total(self, method: str, key: str) -> float:
        """Sum of one score over the sequences."""
        return float(sum(getattr(s, key) for s in self.scores[method].values()))

    def collision_sequences(self, method: str) -> int:
        """Sequences with at least one self-collision frame."""
        return sum(1 for s in self.scores[method].values() if s.collision_frames > 0)


def check_methods(methods: Sequence[str]) -> list[str]:
    """``methods`` as a list, each one of :data:`~nlo_lab.evaluation.METHODS` (at least one)."""
    methods = list(methods)
    unknown = [m for m in methods if m not in METHODS]
    if unknown or not methods:
        raise SettingsError(f"unknown or no methods {unknown or methods}; expected some of {', '.join(METHODS)}")
    return methods


def evaluate(
    robot: Robot,
    demos: Sequence,
    settings: BaselineSettings | None = None,
    *,
    methods: Sequence[str] = METHODS,
    model: RetargetModel | None = None,
    network=None,
    progress: bool = True,
    checkpoint=None,
) -> Evaluation:
    """Run ``methods`` on every demonstration and score them.

    Args:
        robot: a loaded robot.
        demos: demonstrations (names must be unique).
        settings: :class:`~nlo_lab.evaluation.BaselineSettings`.
        methods: method names (default all of :data:`~nlo_lab.evaluation.METHODS`).
        model: the model of the latent methods (default: the shipped checkpoint).
        network: the ``nn_supervised`` network (default: trained/cached on first use).
        progress: a tqdm bar on stderr.
        checkpoint: a checkpoint file for the latent methods instead of the shipped one
            (a robot drafted from its URDF); not with ``model``.

    Returns:
        An :class:`Evaluation`.
    """
    settings = settings or BaselineSettings()
    methods = check_methods(methods)
    names = [d.name or f"sequence_{i:02d}" for i, d in enumerate(demos)]
    if len(set(names)) != len(names):
        raise SettingsError(f"sequence names must be unique, got {names}")
    if not demos:
        raise SettingsError("no sequences to evaluate")
    info: dict = {}
    if model is not None and checkpoint is not None:
        raise SettingsError("give a model or a checkpoint, not both")
    if model is None and any(m in LATENT_METHODS for m in methods):
        model = load_pretrained(robot, checkpoint)
    if network is None and "nn_supervised" in methods:
        if progress:
            print("nn_supervised: labelling and training (cached after the first run) ...", file=sys.stderr)
        network = supervised_network(robot, settings.supervised)
    if network is not None:
        info["nn_label_seconds"] = network.info.get("label_seconds")
        info["nn_train_seconds"] = network.info.get("train_seconds")
    scores: dict[str, dict[str, SequenceScore]] = {m: {} for m in methods}

    bar = tqdm(total=len(demos) * len(methods), desc=f"evaluate {robot.name}", disable=not progress, file=sys.stderr, leave=False)
    for name, demo in zip(names, demos, strict=True):
        for method in methods:
            bar.set_postfix_str(f"{name} {method}")
            r = run_method(method, robot, demo, settings, model=model, network=network)
            err = tracking_errors(demo, robot, r.angles)
            scores[method][name] = SequenceScore(
                frechet_m=err["frechet_m"],
                frechet_wrist_m=err["frechet_wrist_m"],
                frechet_elbow_m=err["frechet_elbow_m"],
                velocity_error=err["velocity_error"],
                acceleration_error=err["acceleration_error"],
                collision_frames=self_collision_frames(robot, r.angles),
                limit_violations=limit_violations(robot, r.angles),
                objective=mean_objective(robot, demo, r.angles),
                seconds=r.seconds,
                frames=len(demo),
                velocity_violations=velocity_violations(robot, r.angles, r.times, fps=demo.fps),
                max_joint_speed_ratio=max_joint_speed_ratio(robot, r.angles, r.times, fps=demo.fps),
                slowdown=float(retime_times(r.angles, demo.fps, robot.velocity_limits.double().numpy())[-1] * demo.fps + 1) / len(demo),
                depth=str(demo.meta.get("depth", "world")),
            )
            bar.update(1)
    bar.close()
    return Evaluation(robot.name, names, scores, info)


def evaluate_split(robot: Robot, split: str = "test", *, limit: int | None = None, corpus_seed: int = 0, **kwargs) -> Evaluation:
    """:func:`evaluate` on the synthetic corpus split (the first ``limit`` sequences)."""
    demos = sign_corpus(split, seed=corpus_seed)
    if limit is not None:
        demos = demos[:limit]
    return evaluate(robot, demos, **kwargs)

"""Evaluation of the method against the baselines on a corpus split (``nlo-lab evaluate``).

For every sequence and every method of :mod:`nlo_lab.baselines`: the tracking
error of docs/DESIGN.md, "Metric" (mean of wrist and elbow discrete Fréchet distances
after mapping the human into the robot frame), velocity and acceleration errors,
self-collision frames, joint-limit violations, the objective value and the wall
time. ``--json`` prints the contract object as the last line of stdout::

    {"methods": {NAME: {"frechet_m": mean, "per_sequence": {seq: frechet},
                        "collision_sequences": n, "limit_violations": n, "seconds": s,
                        "velocity_violations": n, "max_joint_speed_ratio": r, "slowdown": x,
                        "depth": "world"}}}

The joint-speed keys take each method's output as it is, frames 1/fps apart
(no method retimes here; ``nlo-lab retarget`` does): ``velocity_violations`` summed over
the sequences, ``max_joint_speed_ratio`` and ``slowdown`` (what retiming would need) the
largest over the sequences, ``depth`` the demonstrations' (``"world"`` for the corpus).

Without ``--json`` a table like the paper's Table I (rows = sequences, columns =
methods, ``*`` = the sequence has at least one self-collision frame).

Command: ``nlo-lab evaluate --robot yumi [--split test] [--json] [--limit N]``
(or ``python -m nlo_lab.evaluate`` with extra ``--iters``/``--methods``/``--threads``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np

from nlo_lab.baselines import LATENT_METHODS, METHODS, BaselineSettings, mean_objective, run_method
from nlo_lab.errors import NloLabError, SettingsError
from nlo_lab.metrics import limit_violations, max_joint_speed_ratio, self_collision_frames, tracking_errors, velocity_violations
from nlo_lab.retime import retime_times

__all__ = [
    "JSON_KEYS",
    "SequenceScore",
    "Evaluation",
    "evaluate",
    "evaluate_split",
    "to_json",
    "format_table",
    "main",
]

JSON_KEYS = (
    "frechet_m", "per_sequence", "collision_sequences", "limit_violations", "seconds",
    "velocity_violations", "max_joint_speed_ratio", "slowdown", "depth",
)
COLLISION_MARK = "*"


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
        velocity_violations: (frame pair, joint) entries over the joint's velocity limit, the
            frames played at the recording's rate (the methods do not retime).
        max_joint_speed_ratio: largest joint speed over its limit, same time base.
        slowdown: how much longer retiming (``nlo_lab.retime``) would make the motion.
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


def _check_methods(methods: Sequence[str]) -> list[str]:
    methods = list(methods)
    unknown = [m for m in methods if m not in METHODS]
    if unknown or not methods:
        raise SettingsError(f"unknown or no methods {unknown or methods}; expected some of {', '.join(METHODS)}")
    return methods


def evaluate(
    robot,
    demos: Sequence,
    settings: BaselineSettings | None = None,
    *,
    methods: Sequence[str] = METHODS,
    model=None,
    network=None,
    progress: bool = True,
) -> Evaluation:
    """Run ``methods`` on every demonstration and score them.

    Args:
        robot: a loaded robot.
        demos: demonstrations (names must be unique).
        settings: :class:`~nlo_lab.baselines.BaselineSettings`.
        methods: method names (default all of :data:`~nlo_lab.baselines.METHODS`).
        model: the model of the latent methods (default: the shipped checkpoint).
        network: the ``nn_supervised`` network (default: trained/cached on first use).
        progress: a tqdm bar on stderr.

    Returns:
        An :class:`Evaluation`.
    """
    settings = settings or BaselineSettings()
    methods = _check_methods(methods)
    names = [d.name or f"sequence_{i:02d}" for i, d in enumerate(demos)]
    if len(set(names)) != len(names):
        raise SettingsError(f"sequence names must be unique, got {names}")
    if not demos:
        raise SettingsError("no sequences to evaluate")
    info: dict = {}
    if model is None and any(m in LATENT_METHODS for m in methods):
        from nlo_lab.train import load_pretrained

        model = load_pretrained(robot)
    if network is None and "nn_supervised" in methods:
        from nlo_lab.baselines import supervised_network

        if progress:
            print("nn_supervised: labelling and training (cached after the first run) ...", file=sys.stderr)
        network = supervised_network(robot, settings.supervised)
    if network is not None:
        info["nn_label_seconds"] = network.info.get("label_seconds")
        info["nn_train_seconds"] = network.info.get("train_seconds")
    scores: dict[str, dict[str, SequenceScore]] = {m: {} for m in methods}
    from tqdm.auto import tqdm

    bar = tqdm(total=len(demos) * len(methods), desc=f"evaluate {robot.name}", disable=not progress, file=sys.stderr, leave=False)
    for name, demo in zip(names, demos):
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
                velocity_violations=velocity_violations(robot, r.angles, fps=demo.fps),
                max_joint_speed_ratio=max_joint_speed_ratio(robot, r.angles, fps=demo.fps),
                slowdown=float(retime_times(r.angles, demo.fps, robot.velocity_limits.double().numpy())[-1] * demo.fps + 1) / len(demo),
                depth=str(demo.meta.get("depth", "world")),
            )
            bar.update(1)
    bar.close()
    return Evaluation(robot.name, names, scores, info)


def evaluate_split(robot, split: str = "test", *, limit: int | None = None, corpus_seed: int = 0, **kwargs) -> Evaluation:
    """:func:`evaluate` on the synthetic corpus split (the first ``limit`` sequences)."""
    from nlo_lab.human.corpus import sign_corpus

    demos = sign_corpus(split, seed=corpus_seed)
    if limit is not None:
        demos = demos[:limit]
    return evaluate(robot, demos, **kwargs)


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def to_json(ev: Evaluation) -> dict:
    """The command line's contract object (exactly :data:`JSON_KEYS` per method)."""
    return {
        "methods": {
            m: {
                "frechet_m": _num(ev.mean(m)),
                "per_sequence": {s: _num(ev.scores[m][s].frechet_m) for s in ev.sequences},
                "collision_sequences": ev.collision_sequences(m),
                "limit_violations": int(ev.total(m, "limit_violations")),
                "seconds": round(ev.total(m, "seconds"), 4),
                "velocity_violations": int(ev.total(m, "velocity_violations")),
                "max_joint_speed_ratio": _num(max(s.max_joint_speed_ratio for s in ev.scores[m].values())),
                "slowdown": _num(max(s.slowdown for s in ev.scores[m].values())),
                "depth": "/".join(sorted({s.depth for s in ev.scores[m].values()})),
            }
            for m in ev.methods
        }
    }


def format_table(ev: Evaluation, *, markdown: bool = False) -> str:
    """Table I: Fréchet distance [m] per sequence (rows) and method (columns).

    ``*`` marks a sequence where the method's motion has a self-collision frame;
    then the mean row, velocity/acceleration error means, sequences with
    collisions, limit violations and the summed wall time.
    """
    methods = ev.methods
    w = max(12, *(len(m) for m in methods))
    first = max(8, *(len(s) for s in ev.sequences), len("acc. err [m/s²]"))

    def cell(score: SequenceScore) -> str:
        mark = COLLISION_MARK if score.collision_frames > 0 else ""
        return f"{score.frechet_m:.4f}{mark}"

    rows = [[s] + [cell(ev.scores[m][s]) for m in methods] for s in ev.sequences]
    summary = [
        ["mean [m]"] + [f"{ev.mean(m):.4f}" for m in methods],
        ["vel. err [m/s]"] + [f"{ev.mean(m, 'velocity_error'):.3f}" for m in methods],
        ["acc. err [m/s²]"] + [f"{ev.mean(m, 'acceleration_error'):.2f}" for m in methods],
        ["objective"] + [f"{ev.mean(m, 'objective'):.2f}" for m in methods],
        ["collision seq."] + [str(ev.collision_sequences(m)) for m in methods],
        ["limit viol."] + [str(int(ev.total(m, "limit_violations"))) for m in methods],
        ["velocity viol."] + [str(int(ev.total(m, "velocity_violations"))) for m in methods],
        ["max speed/limit"] + [f"{max(s.max_joint_speed_ratio for s in ev.scores[m].values()):.2f}" for m in methods],
        ["max slowdown"] + [f"{max(s.slowdown for s in ev.scores[m].values()):.2f}" for m in methods],
        ["wall time [s]"] + [f"{ev.total(m, 'seconds'):.2f}" for m in methods],
    ]
    header = ["sequence"] + methods
    if markdown:
        lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        lines += ["| **" + r[0] + "** | " + " | ".join(r[1:]) + " |" for r in summary]
        return "\n".join(lines)
    fmt = lambda r: f"{r[0]:<{first}} " + " ".join(f"{c:>{w}}" for c in r[1:])  # noqa: E731
    rule = "-" * (first + (w + 1) * len(methods))
    lines = [f"Fréchet distance [m] on {ev.robot}, mean of wrist and elbow; {COLLISION_MARK} = self-collision in the sequence", fmt(header), rule]
    lines += [fmt(r) for r in rows] + [rule] + [fmt(r) for r in summary]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``nlo-lab evaluate --robot NAME [--split test] [--json] [--limit N]``; returns the exit status.

    Bad input raises an :class:`~nlo_lab.errors.NloLabError` (the command line turns it into exit 2).
    """
    p = argparse.ArgumentParser(prog="nlo-lab evaluate", description=__doc__.splitlines()[0])
    d = BaselineSettings()
    p.add_argument("--robot", required=True)
    p.add_argument("--split", default="test", choices=("train", "test"))
    p.add_argument("--json", action="store_true")
    p.add_argument("--limit", type=int, default=None)
    p.add_argument("--iters", type=int, default=d.iterations, help="iterations of the latent and joint-space methods")
    p.add_argument("--methods", default=",".join(METHODS), help="comma-separated subset of " + ",".join(METHODS))
    p.add_argument("--threads", type=int, default=None, help="torch threads")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    args = p.parse_args(argv)
    if args.limit is not None and args.limit < 1:
        raise SettingsError(f"--limit must be >= 1, got {args.limit}")
    import torch

    if args.threads:
        torch.set_num_threads(max(1, args.threads))
    from nlo_lab.robot import load_robot

    robot = load_robot(args.robot)
    methods = _check_methods([m.strip() for m in args.methods.split(",") if m.strip()])
    settings = replace(d, iterations=args.iters)
    start = time.perf_counter()
    ev = evaluate_split(robot, args.split, limit=args.limit, settings=settings, methods=methods, progress=not args.quiet)
    if args.json:
        print(json.dumps(to_json(ev)))
    else:
        print(format_table(ev))
        if ev.info.get("nn_label_seconds") is not None and ev.info.get("nn_train_seconds") is not None:
            print(
                f"nn_supervised: labels {ev.info['nn_label_seconds']:.1f} s + training {ev.info['nn_train_seconds']:.1f} s"
                " (once, then cached; not part of its wall time)"
            )
        print(f"{len(ev.sequences)} {args.split} sequences, {sum(s.frames for s in ev.scores[methods[0]].values())} frames, {time.perf_counter() - start:.1f} s in all")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except NloLabError as exc:
        print(f"nlo-lab evaluate: error: {exc}", file=sys.stderr)
        sys.exit(2)

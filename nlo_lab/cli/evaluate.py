"""``nlo-lab evaluate --robot R``: the method and its baselines on a corpus split (Table I)."""

from __future__ import annotations

import argparse
import json

from nlo_lab.cli.flags import ITERS_RANGE, LIMIT_RANGE, THREADS_RANGE, LazyChoices, ranged_int

__all__ = ["add_parser", "run"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("evaluate", help="compare the method with the baselines on a corpus split")
    p.add_argument("--robot", required=True, help="yumi, nao, pepper, or a robot spec .json")
    p.add_argument("--checkpoint", default=None, metavar="CKPT.pt",
                   help="a trained checkpoint of this robot for the latent methods (default: the shipped one)")
    p.add_argument("--split", default="test", choices=("train", "test"))
    p.add_argument("--json", action="store_true", help="print the results as one JSON object on the last line")
    p.add_argument("--limit", type=ranged_int(*LIMIT_RANGE), default=None,
                   help=f"evaluate only the first N sequences, {LIMIT_RANGE[0]}..{LIMIT_RANGE[1]}")
    p.add_argument("--iters", type=ranged_int(*ITERS_RANGE), default=None,
                   help=f"iterations of the latent and joint-space methods, {ITERS_RANGE[0]}..{ITERS_RANGE[1]} (default: each method's:"
                        " robot-ready latent methods 40 Rprop steps, paper mode 100 Adam steps, joint_space 100)")
    p.add_argument("--mode", default="robot-ready", choices=LazyChoices("nlo_lab.evaluation", "EVALUATION_MODES"), metavar="MODE",
                   help="%(choices)s: robot-ready = the shipped defaults (smoothness term, warm start, latent methods retimed); "
                        "paper = the paper's objective, frames independent, no retiming (default: robot-ready)")
    p.add_argument("--methods", default=None,
                   help="comma-separated subset of the methods (nlo_lab.evaluation.METHODS; default: all)")
    p.add_argument("--threads", type=ranged_int(*THREADS_RANGE), default=None,
                   help="torch threads (default: NLO_LAB_THREADS, else 1)")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no warnings")
    return p


def run(args) -> int:
    import dataclasses
    import time

    import torch

    from nlo_lab.evaluation import METHODS, BaselineSettings, check_methods, evaluate_split, format_table, to_json
    from nlo_lab.robot import load_robot

    if args.threads is not None:
        torch.set_num_threads(args.threads)
    methods = check_methods([m.strip() for m in args.methods.split(",") if m.strip()] if args.methods is not None else METHODS)
    settings = BaselineSettings(mode=args.mode)
    settings = settings if args.iters is None else dataclasses.replace(settings, iterations=args.iters)
    robot = load_robot(args.robot)
    start = time.perf_counter()
    ev = evaluate_split(robot, args.split, limit=args.limit, settings=settings, methods=methods, progress=not args.quiet,
                        checkpoint=args.checkpoint)
    if args.json:
        print(json.dumps(to_json(ev)))
        return 0
    print(format_table(ev))
    if ev.info.get("nn_label_seconds") is not None and ev.info.get("nn_train_seconds") is not None:
        print(
            f"nn_supervised: labels {ev.info['nn_label_seconds']:.1f} s + training {ev.info['nn_train_seconds']:.1f} s"
            " (once, then cached; not part of its wall time)"
        )
    frames = sum(s.frames for s in ev.scores[methods[0]].values())
    print(f"{len(ev.sequences)} {args.split} sequences, {frames} frames, {time.perf_counter() - start:.1f} s in all")
    return 0

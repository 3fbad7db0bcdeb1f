"""``nlo-lab train --robot R``: train a robot's networks on the synthetic corpus (paper Eq. 10, or ``--mode autodecoder``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from nlo_lab.cli.flags import (
    BATCH_RANGE,
    EPOCHS_RANGE,
    LATENT_RANGE,
    MAX_SEED,
    THREADS_RANGE,
    LazyChoices,
    positive_float,
    ranged_int,
)
from nlo_lab.errors import escape

__all__ = ["add_parser", "run"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("train", help="train the encoder and decoder of a robot on the synthetic corpus")
    p.add_argument("--robot", required=True, help="yumi, nao, pepper, or a robot spec .json")
    p.add_argument("--epochs", type=ranged_int(*EPOCHS_RANGE), default=None,
                   help=f"passes over the training frames, {EPOCHS_RANGE[0]}..{EPOCHS_RANGE[1]} (default: 30)")
    p.add_argument("--max-seconds", type=positive_float, default=None,
                   help="wall-clock budget [s]; training stops after the step that exceeds it (default: 500)")
    p.add_argument("--batch-size", type=ranged_int(*BATCH_RANGE), default=None, help="frames per step (default: 64)")
    p.add_argument("--lr", type=positive_float, default=None, help="Adam learning rate (default: 0.001)")
    p.add_argument("--kind", default=None, choices=LazyChoices("nlo_lab.model", "MODEL_KINDS"), metavar="KIND",
                   help="%(choices)s: graph is the paper's (default: graph)")
    p.add_argument("--latent-per-node", type=ranged_int(*LATENT_RANGE), default=None,
                   help=f"latent size per robot node, {LATENT_RANGE[0]}..{LATENT_RANGE[1]} (default: 4)")
    p.add_argument("--activation", default=None, choices=LazyChoices("nlo_lab.model", "ACTIVATIONS"), metavar="NAME",
                   help="message activation of every graph layer, the paper's Table II: %(choices)s (default: leaky_relu, the paper's)")
    p.add_argument("--mode", default=None, choices=LazyChoices("nlo_lab.training", "TRAIN_MODES"), metavar="MODE",
                   help="%(choices)s: encoder = encoder and decoder end to end (paper Eq. 10, the default); autodecoder = "
                        "the decoder and one latent code per training frame (the paper's auto-decoder; no encoder: "
                        "retarget it with --init train-stats, random or zeros)")
    p.add_argument("--max-steps", type=ranged_int(1, EPOCHS_RANGE[1] * BATCH_RANGE[1]), default=None,
                   help="stop after this many optimiser steps: a budget that does not depend on the machine's load (default: epochs decide)")
    p.add_argument("--starts", type=ranged_int(1, 16), default=None,
                   help="candidate starts: so many seeds train up to 1000 steps each, the lowest validation objective goes on "
                        "(default: 3 for a robot spec of your own, 1 for yumi, nao, pepper: their shipped checkpoints' recipe)")
    p.add_argument("--out", default=None, help="checkpoint path (default: ./NAME.pt; for a bundled robot in a checkout, "
                                               "assets/checkpoints/NAME.pt)")
    p.add_argument("--seed", type=ranged_int(0, MAX_SEED), default=0)
    p.add_argument("--threads", type=ranged_int(*THREADS_RANGE), default=None,
                   help="torch threads (default: NLO_LAB_THREADS, else 1)")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no warnings")
    return p


def run(args) -> int:
    import dataclasses

    import torch

    from nlo_lab.atomic_files import check_output_file
    from nlo_lab.model import checkpoint_path, save_checkpoint
    from nlo_lab.paths import is_bundled, is_editable_checkout
    from nlo_lab.robot import load_robot
    from nlo_lab.training import TrainSettings, train_model

    flags = {"epochs": args.epochs, "max_seconds": args.max_seconds, "batch_size": args.batch_size, "lr": args.lr,
             "kind": args.kind, "latent_per_node": args.latent_per_node, "activation": args.activation, "mode": args.mode,
             "max_steps": args.max_steps, "starts": args.starts}
    settings = dataclasses.replace(TrainSettings(seed=args.seed, progress=not args.quiet), **{k: v for k, v in flags.items() if v is not None})
    if args.threads is not None:
        torch.set_num_threads(args.threads)
    if args.out is not None:
        check_output_file(args.out, what="--out", parents=True)  # before any input is read (--out '' too)
    robot = load_robot(args.robot)
    # A checkout retrains a bundled robot's shipped file in place; an installed package is never written to,
    # nor the shipped files by a robot of one's own (a spec .json): that goes to ./NAME.pt.
    bundled = is_bundled(robot.spec.path)
    out = Path(args.out) if args.out is not None else checkpoint_path(robot.name) if bundled and is_editable_checkout() else Path(f"{robot.name}.pt")
    check_output_file(out, what="the checkpoint", parents=True)  # before training, not after it
    result = train_model(robot, settings)
    save_checkpoint(result.model, out, robot)
    best = min(result.starts, key=lambda s: s["val"]) if len(result.starts) > 1 else None
    chosen = f" (the best of {len(result.starts)} starts: seed {best['seed']})" if best else ""
    print(
        f"trained {escape(robot.name)}{chosen}: {result.steps} steps in {result.seconds:.1f} s, "
        f"best validation loss {result.val_loss:.4f}; wrote {escape(out)} ({out.stat().st_size / 1e6:.2f} MB)"
    )
    if not result.model.has_encoder:
        print("an auto-decoder has no encoder: start its latent optimisation from train-stats, random or zeros")
    return 0

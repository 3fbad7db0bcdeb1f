"""The command line's flags: their stated ranges, their types and the parser class.

The rules are the settings' own (:mod:`nlo_lab.settings`), so a flag and the setting it
fills accept the same values; the messages state the range, and a huge argument is never
echoed back whole. :class:`Parser` turns argparse's usage-and-exit into one
:class:`UsageError` line (exit status 2, :mod:`nlo_lab.cli.run_guard`).
"""

from __future__ import annotations

import argparse
import importlib
from typing import Any, NoReturn

from nlo_lab import settings
from nlo_lab.errors import NloLabError, SettingsError
from nlo_lab.settings import (
    HAND_SEARCH,
    HANDSHAPE_SEARCH,
    HANDSHAPE_SLOWDOWN,
    HANDSHAPE_WEIGHTS,
    LATENT_ITERATIONS,
    SLOWDOWN_RANGE,
    arg_type,
    check_int,
    check_positive,
    check_range,
)
from nlo_lab.threads import THREADS_RANGE

__all__ = [
    "MAX_SEED",
    "ITERS_RANGE",
    "EPOCHS_RANGE",
    "LIMIT_RANGE",
    "THREADS_RANGE",
    "BATCH_RANGE",
    "LATENT_RANGE",
    "WEIGHT_RANGE",
    "UsageError",
    "Parser",
    "ranged_int",
    "positive_float",
    "LazyChoices",
    "add_optimisation_flags",
    "add_hand_flags",
    "hand_settings",
    "check_hand_flags",
]

# Stated ranges of the numeric flags: a value outside is refused (exit 2, one line) before any work.
# They are the settings' own (nlo_lab.settings, nlo_lab.threads): a flag and the setting it fills agree.
MAX_SEED = settings.SEED_RANGE[1]  # numpy's and torch's generators both take it
ITERS_RANGE = settings.ITERATIONS_RANGE  # optimiser steps; 0 = the start point. The paper's longest budget is 600
EPOCHS_RANGE = settings.EPOCHS_RANGE  # passes over the training frames (30 by default)
LIMIT_RANGE = settings.COUNT_RANGE  # sequences of a split to evaluate
BATCH_RANGE = settings.BATCH_RANGE  # training frames per step
LATENT_RANGE = settings.LATENT_RANGE  # latent size per robot node
WEIGHT_RANGE = settings.WEIGHT_RANGE  # each loss weight: 1000x the largest default; beyond it float32 losses overflow to NaN
# THREADS_RANGE (nlo_lab.threads): Holistic instances of the pose estimation at most; torch threads of train/evaluate


class UsageError(NloLabError, ValueError):
    """A bad flag or argument on the command line."""


class Parser(argparse.ArgumentParser):
    """argparse prints usage plus a message and exits; we want one line and status 2.

    Subparsers (and their own subparsers) are of this class too.
    """

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{self.prog}: {message}")


def ranged_int(lo: int, hi: int):
    """argparse ``type=``: a whole number in ``[lo, hi]`` (the settings' rule, :func:`nlo_lab.settings.check_int`)."""

    def parse(text: str) -> int:
        if len(text) > 40:  # int() of a huge digit string is slow and its echo floods the line
            raise argparse.ArgumentTypeError(f"must be a whole number in [{lo}, {hi}], got {len(text)} characters")
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number in [{lo}, {hi}], got {text!r}") from None
        try:
            return check_int("value", value, lo, hi)
        except SettingsError:
            raise argparse.ArgumentTypeError(f"must be in [{lo}, {hi}], got {text}") from None

    return parse


def positive_float(text: str) -> float:
    """argparse ``type=``: a finite number > 0 (the settings' own check)."""
    if len(text) > 40:
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {len(text)} characters")
    return arg_type(check_positive, float)(text)


class LazyChoices:
    """The choices of a flag, taken from their home module on first use.

    The homes import torch; a bad flag or ``--help`` must not wait for that (argparse reads
    choices only to check a given value or to print them).
    """

    def __init__(self, module: str, name: str):
        self.module, self.name = module, name

    def _names(self) -> tuple:
        return tuple(getattr(importlib.import_module(self.module), self.name))

    def __iter__(self):
        return iter(self._names())

    def __contains__(self, value) -> bool:
        return value in self._names()


def add_optimisation_flags(parser: argparse.ArgumentParser, weights_example: str) -> None:
    """``--init``, ``--iters`` and ``--weights``: how the latent optimisation runs (``retarget`` and ``batch``).

    ``weights_example`` ends the help of ``--weights`` (``"ee=1000,ori=100,smooth=10"``).
    """
    parser.add_argument("--init", default="encoder", choices=LazyChoices("nlo_lab.inference", "INITS"), metavar="INIT",
                        help="initialisation of the latent code: %(choices)s (default: encoder)")
    parser.add_argument("--iters", type=ranged_int(*ITERS_RANGE), default=LATENT_ITERATIONS,
                        help=f"latent optimisation budget, {ITERS_RANGE[0]}..{ITERS_RANGE[1]} (default: {LATENT_ITERATIONS}:"
                             " Rprop steps on a recording, see docs/DESIGN.md)")
    parser.add_argument("--weights", default=None,
                        help=f"loss weights, each {WEIGHT_RANGE[0]:g}..{WEIGHT_RANGE[1]:g}, e.g. {weights_example}")


def finger_names(text: str) -> tuple[str, ...]:
    """``--hand-search``: finger names separated by commas (``nlo_lab.human.FINGERS``), or ``none`` (no search)."""
    from nlo_lab.human.demonstration import FINGERS  # numpy only

    if text.strip() == "none":
        return ()
    names = tuple(x.strip() for x in text.split(",") if x.strip())
    unknown = [x for x in names if x not in FINGERS]
    if unknown or not names:
        raise argparse.ArgumentTypeError(f"unknown fingers {unknown or text!r}; expected names from {', '.join(FINGERS)}")
    twice = sorted({x for x in names if names.count(x) > 1})
    if twice:
        raise argparse.ArgumentTypeError(f"{', '.join(twice)} named more than once in {text!r}")
    return names


def add_hand_flags(parser: argparse.ArgumentParser) -> None:
    """``--handshape``, ``--hand-search`` and ``--hand-slowdown``: the hand stage's finger search and speed clamp
    (``retarget`` and ``batch``)."""
    fingers = ",".join(HANDSHAPE_SEARCH)
    weights = ",".join(f"{k}={v:g}" for k, v in HANDSHAPE_WEIGHTS.items())
    parser.add_argument("--handshape", action="store_true",
                        help=f"the handshape preset: the hand stage first searches {fingers} along the clip, with {weights} "
                             f"and the hands' slowdown at {HANDSHAPE_SLOWDOWN:g} (--weights applies on top; see docs/RESULTS.md, Handshapes)")
    parser.add_argument("--hand-search", type=finger_names, default=None, metavar="FINGERS",
                        help=f"fingers whose joints the hand stage first searches along the clip, comma-separated, or none "
                             f"(default: those of {','.join(HAND_SEARCH)} the robot's hands move alone)")
    lo, hi = SLOWDOWN_RANGE
    parser.add_argument("--hand-slowdown", type=arg_type(check_range, float, lo=lo, hi=hi), default=None, metavar="X",
                        help=f"how much longer than the latent optimisation's the hand stage may make each segment of the "
                             f"retimed motion, {lo:g}..{hi:g} (default: 1, never slower; with --handshape: {HANDSHAPE_SLOWDOWN:g})")


def hand_settings(args) -> dict[str, Any]:
    """The hand stage's settings the flags give (``OptimizeSettings``' and ``retarget_many``'s keywords):
    ``hand_search``, the fingers ``--hand-search`` names (``none``: ``()``), else the preset's with ``--handshape``, else
    None (the robot's default: ``nlo_lab.pipeline.hand_search``);
    ``hand_slowdown``, ``--hand-slowdown``'s, else the preset's with ``--handshape``, else 1 (never slower)."""
    search = args.hand_search if args.hand_search is not None else (HANDSHAPE_SEARCH if args.handshape else None)
    slowdown = args.hand_slowdown if args.hand_slowdown is not None else (HANDSHAPE_SLOWDOWN if args.handshape else 1.0)
    return {"hand_search": search, "hand_slowdown": slowdown}


def check_hand_flags(args, robot, command: str) -> None:
    """``--handshape``, ``--hand-search`` and ``--hand-slowdown`` refused on a robot without hand joints, naming the
    flag given (the pipeline refuses the settings too, naming them: here the user reads what they typed)."""
    from nlo_lab.pipeline import has_hand_joints

    if has_hand_joints(robot):
        return
    settings = hand_settings(args)
    if settings["hand_search"]:
        flag = "--hand-search" if args.hand_search is not None else "--handshape"
        raise UsageError(f"nlo-lab {command}: {flag}: {robot.name} has no finger joints for the hand stage to search "
                         "(a robot with hands, such as yumi)")
    if args.hand_slowdown not in (None, 1.0):  # nothing to slow
        raise UsageError(f"nlo-lab {command}: --hand-slowdown: {robot.name} has no hand joints for the hand stage to move "
                         "(a robot with hands, such as yumi)")

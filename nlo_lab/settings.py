"""Validators shared by every settings object and the command line.

Each check takes the setting's ``name`` (used in the message), the value, and
returns the value in its canonical type, or raises :class:`SettingsError` with
one line that names the setting, the rule and the value given::

    check_int("steps", 0, minimum=1)      # SettingsError: steps must be an integer >= 1, got 0
    check_positive("lr", "fast")          # SettingsError: lr must be a number, got 'fast'

Dataclasses check their fields in ``__post_init__`` (:func:`validate_fields`);
the command line wraps the same checks as argparse types (:func:`arg_type`), so
a flag and the setting it fills accept the same values. A value of the wrong type (a
string where a number goes: ``LossWeights(ee="5")``) is a :class:`SettingsTypeError`
(also a ``TypeError``); a number out of its range a :class:`SettingsError` (a ``ValueError``).

Every budget and size has an upper bound, stated here once and shared by the settings
and the command line's flags (README, "Failures and faults").
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections.abc import Callable, Collection
from typing import Any

import numpy as np

from nlo_lab.errors import SettingsError, SettingsTypeError

__all__ = [
    "ITERATIONS_RANGE",
    "LATENT_ITERATIONS",
    "PATIENCE_RANGE",
    "EPOCHS_RANGE",
    "BATCH_RANGE",
    "SEED_RANGE",
    "LATENT_RANGE",
    "COUNT_RANGE",
    "WEIGHT_RANGE",
    "WORKERS_RANGE",
    "HAND_SEARCH",
    "HANDSHAPE_SEARCH",
    "HANDSHAPE_WEIGHTS",
    "HANDSHAPE_SLOWDOWN",
    "SLOWDOWN_RANGE",
    "SEARCH_GRID",
    "RATE_RANGE",
    "SECONDS_RANGE",
    "check_int",
    "check_positive",
    "check_nonnegative",
    "check_range",
    "check_choice",
    "check_type",
    "check_bool",
    "check_array",
    "validate_fields",
    "arg_type",
]


# Stated ranges of budgets and sizes (a value outside is refused before any work).
ITERATIONS_RANGE = (0, 10_000)  # Adam or IK steps; 0 = the start point. The paper's longest budget is 600
# The latent optimisation's default budget (nlo_lab.inference.OptimizeSettings, the command line, batch, the lab):
# 40 Rprop steps on a recording, measured against the paper's 100 Adam steps in nlo_lab.inference.settings.
LATENT_ITERATIONS = 40
PATIENCE_RANGE = (1, ITERATIONS_RANGE[1] + 1)  # evaluations without improvement (iterations + 1: never stop early)
EPOCHS_RANGE = (1, 10_000)  # passes over the training frames (30 by default)
BATCH_RANGE = (1, 1_000_000)  # frames per training step
SEED_RANGE = (0, 2**32 - 1)  # numpy's and torch's generators both take it
LATENT_RANGE = (1, 64)  # latent size per robot node
COUNT_RANGE = (1, 1_000_000)  # other counts: frames per chunk, validation frames, strides, sequences
WEIGHT_RANGE = (0.0, 1e6)  # a loss weight: 1000x the largest default; beyond it float32 losses overflow to NaN
RATE_RANGE = (1e-12, 1e3)  # step sizes, sigmas, damping, tolerances, clips
SECONDS_RANGE = (1e-3, 1e7)  # wall-clock budgets [s] (1e7 s: 116 days)
WORKERS_RANGE = (1, 1024)  # worker processes of a batch's local cluster
# the fingers the hand stage searches by default (OptimizeSettings.hand_search None: those of them a robot's hands move
# alone; nlo_lab.inference.hand_stage says why; the index is left out: searched, it opens and loses the pinch)
HAND_SEARCH = ("middle", "ring", "pinky")
# the handshape preset (`retarget --handshape`, `batch --handshape`): the hand stage's searched fingers and the weights
# that differ from LossWeights' defaults (LossWeights.handshape; nlo_lab.inference.hand_stage says why)
HANDSHAPE_SEARCH = HAND_SEARCH
HANDSHAPE_WEIGHTS = {"tip_dir": 8000.0, "thumb": 800.0, "finger_dir": 2000.0}
# ... and how much longer than the latent optimisation's the hand stage may make each retimed segment
# (OptimizeSettings.hand_slowdown): the preset's robot time stays below dex-retargeting's (docs/RESULTS.md, "Handshapes")
HANDSHAPE_SLOWDOWN = 1.7
SLOWDOWN_RANGE = (1.0, 10.0)  # the hand stage's slowdown: 1 = never slower than the latent optimisation's output
SEARCH_GRID = 16  # values per joint of the hand stage's finger search (OptimizeSettings.hand_grid): 8 missed the ring's open basin


def check_int(name: str, value: Any, minimum: int | None = None, maximum: int | None = None) -> int:
    """An integer (numpy integers too, never a bool) in ``[minimum, maximum]`` (either bound optional)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise SettingsTypeError(f"{name} must be an integer{_bounds(minimum, maximum)}, got {_show(value)}")
    if (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
        raise SettingsError(f"{name} must be an integer{_bounds(minimum, maximum)}, got {_show(value)}")
    return int(value)


def _bounds(minimum: int | None, maximum: int | None) -> str:
    if minimum is not None and maximum is not None:
        return f" in [{minimum}, {maximum}]"
    if minimum is not None:
        return f" >= {minimum}"
    return f" <= {maximum}" if maximum is not None else ""


def check_positive(name: str, value: Any) -> float:
    """A finite number > 0."""
    number = _number(name, value)
    if not (math.isfinite(number) and number > 0):
        raise SettingsError(f"{name} must be finite and > 0, got {_show(value)}")
    return number


def check_nonnegative(name: str, value: Any) -> float:
    """A finite number >= 0."""
    number = _number(name, value)
    if not (math.isfinite(number) and number >= 0):
        raise SettingsError(f"{name} must be finite and >= 0, got {_show(value)}")
    return number


def check_range(name: str, value: Any, lo: float, hi: float, unit: str = "") -> float:
    """A finite number in ``[lo, hi]``; ``unit`` (``"m"``) is named in the message."""
    number = _number(name, value)
    if not (math.isfinite(number) and lo <= number <= hi):
        raise SettingsError(f"{name} must be in [{lo:g}, {hi:g}]{' ' + unit if unit else ''}, got {_show(value)}")
    return number


def _show(value: Any) -> str:
    """``repr(value)`` for a message, cut short (a huge argument is never echoed whole)."""
    text = repr(value)
    return text if len(text) <= 80 else f"{text[:60]}... ({type(value).__name__})"


def _number(name: str, value: Any) -> float:
    """``float(value)`` of a real number (int, float, numpy or torch scalar); inf and NaN allowed (the caller's rule names them).

    Text is not a number here (``"5"``: a :class:`SettingsTypeError`); the command line converts its text first.
    """
    if isinstance(value, (bool, np.bool_, str, bytes)) or not hasattr(value, "__float__"):
        raise SettingsTypeError(f"{name} must be a number, got {_show(value)}")
    try:
        return float(value)
    except (TypeError, ValueError):  # an array of several numbers
        raise SettingsTypeError(f"{name} must be a number, got {_show(value)}") from None


def check_choice(name: str, value: Any, choices: Collection) -> Any:
    """One of ``choices``; the message lists them."""
    try:
        known = isinstance(value, (str, int, float)) and value in choices
    except (TypeError, ValueError):  # an unhashable value, an array
        known = False
    if not known:
        raise SettingsError(f"unknown {name} {_show(value)}; expected one of {tuple(choices)}")
    return value


def check_type(name: str, value: Any, types: type | tuple[type, ...], what: str | None = None) -> Any:
    """``value`` itself if it is an instance of ``types``; else a :class:`SettingsTypeError` (``what`` names the types)."""
    if not isinstance(value, types):
        if what is None:
            names = [t.__name__ for t in (types if isinstance(types, tuple) else (types,))]
            what = " or ".join(names)
        raise SettingsTypeError(f"{name} must be {what}, got {type(value).__name__}")
    return value


def check_array(name: str, value: Any) -> np.ndarray:
    """``value`` as a float64 array: an array, tensor, list or number of real numbers (NaN and inf pass: the caller's rule names them).

    Raises:
        SettingsTypeError: text, objects, complex numbers, ragged lists: anything that is no array of real numbers.
    """
    if hasattr(value, "detach") and hasattr(value, "cpu"):  # a torch tensor
        value = value.detach().cpu().numpy()
    if isinstance(value, (str, bytes)) or value is None:
        raise SettingsTypeError(f"{name} must be an array of numbers, got {_show(value)}")
    try:
        raw = np.asarray(value)
        if raw.dtype.kind not in "biuf":
            raise TypeError(raw.dtype)
        return raw.astype(np.float64, copy=False)
    except (TypeError, ValueError):
        raise SettingsTypeError(f"{name} must be an array of real numbers, got {_show(value)}") from None


def check_bool(name: str, value: Any) -> bool:
    """True or False (numpy's too), nothing else: a flag given 0 or "no" is a mistake."""
    if not isinstance(value, (bool, np.bool_)):
        raise SettingsTypeError(f"{name} must be True or False, got {_show(value)}")
    return bool(value)


def validate_fields(obj: Any, check: Callable[[str, Any], Any], prefix: str = "", names: Collection[str] | None = None) -> None:
    """Apply ``check(name, value)`` to the fields of the dataclass ``obj`` and store what it returns.

    For ``__post_init__`` of frozen dataclasses too. ``prefix`` goes before each
    field name in the message (``"loss weight "``); ``names`` limits the fields.
    """
    for f in dataclasses.fields(obj):
        if names is None or f.name in names:
            object.__setattr__(obj, f.name, check(f"{prefix}{f.name}", getattr(obj, f.name)))


def arg_type(check: Callable[..., Any], convert: Callable[[str], Any] = int, **bounds) -> Callable[[str], Any]:
    """An argparse ``type=`` that converts the text and applies ``check`` (same rules as the setting).

    ``arg_type(check_int, minimum=0)`` accepts ``"3"`` and rejects ``"-1"``
    and ``"x"`` with argparse's usual one-line error (exit status 2).
    """

    def parse(text: str):
        try:
            value = convert(text)
        except ValueError:
            kind = "a whole number" if convert is int else "a number"
            raise argparse.ArgumentTypeError(f"expected {kind}, got {text!r}") from None
        try:
            return check("value", value, **bounds)
        except SettingsError as e:
            raise argparse.ArgumentTypeError(str(e).replace("value ", "", 1)) from None

    parse.__name__ = check.__name__.removeprefix("check_")  # argparse names the type in its messages
    return parse

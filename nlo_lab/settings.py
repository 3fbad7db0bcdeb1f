"""Validators shared by every settings object and the command line.

Each check takes the setting's ``name`` (used in the message), the value, and
returns the value in its canonical type, or raises :class:`SettingsError` with
one line that names the setting, the rule and the value given::

    check_int("steps", 0, minimum=1)      # SettingsError: steps must be an integer >= 1, got 0
    check_positive("lr", "fast")          # SettingsError: lr must be a number, got 'fast'

Dataclasses check their fields in ``__post_init__`` (:func:`validate_fields`);
the command line wraps the same checks as argparse types (:func:`arg_type`), so
a flag and the setting it fills accept the same values.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections.abc import Callable, Collection
from typing import Any

import numpy as np

from nlo_lab.errors import SettingsError

__all__ = [
    "check_int",
    "check_positive",
    "check_nonnegative",
    "check_range",
    "check_choice",
    "validate_fields",
    "arg_type",
]


def check_int(name: str, value: Any, minimum: int | None = None, maximum: int | None = None) -> int:
    """An integer (numpy integers too, never a bool) in ``[minimum, maximum]`` (either bound optional)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise SettingsError(f"{name} must be an integer{_bounds(minimum, maximum)}, got {value!r}")
    if (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
        raise SettingsError(f"{name} must be an integer{_bounds(minimum, maximum)}, got {value!r}")
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
        raise SettingsError(f"{name} must be finite and > 0, got {value!r}")
    return number


def check_nonnegative(name: str, value: Any) -> float:
    """A finite number >= 0."""
    number = _number(name, value)
    if not (math.isfinite(number) and number >= 0):
        raise SettingsError(f"{name} must be finite and >= 0, got {value!r}")
    return number


def check_range(name: str, value: Any, lo: float, hi: float, unit: str = "") -> float:
    """A finite number in ``[lo, hi]``; ``unit`` (``"m"``) is named in the message."""
    number = _number(name, value)
    if not (math.isfinite(number) and lo <= number <= hi):
        raise SettingsError(f"{name} must be in [{lo}, {hi}]{' ' + unit if unit else ''}, got {value!r}")
    return number


def _number(name: str, value: Any) -> float:
    """``float(value)``, inf and NaN allowed (the caller's rule names them)."""
    if isinstance(value, (bool, np.bool_)):
        raise SettingsError(f"{name} must be a number, got {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise SettingsError(f"{name} must be a number, got {value!r}") from None


def check_choice(name: str, value: Any, choices: Collection) -> Any:
    """One of ``choices``; the message lists them."""
    if value not in choices:
        raise SettingsError(f"unknown {name} {value!r}; expected one of {tuple(choices)}")
    return value


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

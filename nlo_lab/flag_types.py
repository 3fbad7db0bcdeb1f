"""The types of the command line's flags: argparse ``type=`` and ``choices=`` objects.

The rules are the settings' own (:mod:`nlo_lab.settings`), so a flag and the setting it
fills accept the same values; the messages state the range, and a huge argument is never
echoed back whole.
"""

from __future__ import annotations

import argparse
import importlib

from nlo_lab.errors import SettingsError
from nlo_lab.settings import arg_type, check_int, check_positive

__all__ = ["ranged_int", "positive_float", "LazyChoices"]


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

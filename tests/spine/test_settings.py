"""nlo_lab.settings: the shared validators (one line naming the setting, the rule and the value)."""

from __future__ import annotations

import argparse
import dataclasses
import math
import re

import numpy as np
import pytest

from nlo_lab.errors import SettingsError, SettingsTypeError
from nlo_lab.settings import arg_type, check_choice, check_int, check_nonnegative, check_positive, check_range, validate_fields


def test_check_int():
    assert check_int("steps", 3, minimum=1) == 3
    assert type(check_int("steps", np.int64(3))) is int
    assert check_int("n", 5, minimum=0, maximum=5) == 5
    for bad, rule in [(0, ">= 1"), (True, ">= 1"), (2.0, ">= 1"), ("3", ">= 1")]:
        with pytest.raises(SettingsError, match=f"^steps must be an integer {rule}, got {bad!r}$"):
            check_int("steps", bad, minimum=1)
    with pytest.raises(SettingsError, match=r"n must be an integer in \[0, 5\], got 6"):
        check_int("n", 6, minimum=0, maximum=5)


@pytest.mark.parametrize("check, zero_ok", [(check_positive, False), (check_nonnegative, True)])
def test_positive_and_nonnegative(check, zero_ok):
    assert check("lr", 0.5) == 0.5 and check("lr", 2) == 2.0 and check("lr", np.float32(0.5)) == 0.5
    if zero_ok:
        assert check("w", 0) == 0.0
    else:
        with pytest.raises(SettingsError, match="lr must be finite and > 0, got 0"):
            check("lr", 0)
    for bad in (-1.0, math.inf, math.nan):
        with pytest.raises(SettingsError, match="must be finite and"):
            check("lr", bad)
    for bad in ("fast", "0.5", None, False, [1.0], 1j):  # text is no number here: the command line converts its text first
        with pytest.raises(SettingsTypeError, match=re.escape(f"lr must be a number, got {bad!r}")):
            check("lr", bad)


def test_check_range_and_choice():
    assert check_range("width", 0.3, 0.2, 0.5, "m") == 0.3
    with pytest.raises(SettingsError, match=r"width must be in \[0.2, 0.5\] m, got 0.6"):
        check_range("width", 0.6, 0.2, 0.5, "m")
    assert check_choice("init", "zero", ("zero", "encoder")) == "zero"
    with pytest.raises(SettingsError, match=r"unknown init 'one'; expected one of \('zero', 'encoder'\)"):
        check_choice("init", "one", ("zero", "encoder"))


def test_validate_fields_checks_and_stores_canonical_values():
    @dataclasses.dataclass(frozen=True)
    class Weights:
        a: float = 1
        b: float = 0

        def __post_init__(self):
            validate_fields(self, check_nonnegative, prefix="loss weight ")

    w = Weights(a=2, b=np.float32(0.5))
    assert (w.a, w.b) == (2.0, 0.5) and type(w.a) is float and type(w.b) is float
    with pytest.raises(SettingsTypeError, match="loss weight a must be a number, got '2'"):
        Weights(a="2")
    with pytest.raises(SettingsError, match="loss weight b must be finite and >= 0, got -1"):
        Weights(b=-1)


def test_arg_type_applies_the_same_rule_as_the_setting():
    parser = argparse.ArgumentParser(exit_on_error=False)
    parser.add_argument("--frames", type=arg_type(check_int, minimum=0))
    parser.add_argument("--lr", type=arg_type(check_positive, convert=float))
    ns = parser.parse_args(["--frames", "3", "--lr", "0.1"])
    assert (ns.frames, ns.lr) == (3, 0.1)
    for argv, message in [
        (["--frames", "-1"], "must be an integer >= 0, got -1"),
        (["--frames", "x"], "expected a whole number, got 'x'"),
        (["--lr", "0"], "must be finite and > 0, got 0.0"),
        (["--lr", "fast"], "expected a number, got 'fast'"),
    ]:
        with pytest.raises(argparse.ArgumentError, match=message):
            parser.parse_args(argv)

"""pyproject's list of modules mypy still excuses names modules that exist.

A module moved or renamed leaves its old name on the list, which excuses nothing, and the
moved module's errors then break `make lint` (the readers' move to human/readers did)."""

from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib", reason="tomllib is in the standard library from Python 3.11")

ROOT = Path(__file__).resolve().parents[2]


def test_every_excused_module_exists():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    excused = [name for override in config["tool"]["mypy"]["overrides"] for name in override["module"]]
    assert excused, "the list of excused modules was not found in pyproject.toml"
    missing = [name for name in excused
               if not (ROOT / (name.replace(".", "/") + ".py")).is_file()
               and not (ROOT / name.replace(".", "/") / "__init__.py").is_file()]
    assert not missing, f"pyproject.toml's [tool.mypy] overrides name modules that do not exist: {missing}"

"""Where the package's bundled files live, in a checkout and in an installed wheel.

The repository keeps ``assets/``, ``notebooks/`` and ``docs/`` at its top level, beside the
package. The wheel carries the same folders inside the package
(``nlo_lab/assets``, ``nlo_lab/notebooks``, ``nlo_lab/docs``: the documents and
``RESULTS.md``'s figures; ``pyproject.toml`` maps them in at build time). An editable install (``pip install -e .``, what ``make setup`` does)
uses the checkout in place. This module looks inside the package first, then
beside it, so both kinds of install find the same files.

Bundled files are read-only: ``nlo-lab lab`` copies the notebooks to a folder
the user owns (:func:`user_notebooks_dir`) and never edits the installed ones.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = [
    "PACKAGE_DIR",
    "ASSETS",
    "ROBOTS_DIR",
    "CHECKPOINTS_DIR",
    "RECORDINGS_DIR",
    "NOTEBOOKS_DIR",
    "DOCS_DIR",
    "BUNDLED_ROBOTS",
    "is_editable_checkout",
    "is_bundled",
    "repair_hint",
    "user_notebooks_dir",
]

PACKAGE_DIR = Path(__file__).resolve().parent


def _bundled_folder(name: str) -> Path:
    """``nlo_lab/NAME`` in a wheel install, else ``NAME`` beside the package (a checkout)."""
    inside = PACKAGE_DIR / name
    return inside if inside.is_dir() else PACKAGE_DIR.parent / name


ASSETS = _bundled_folder("assets")
ROBOTS_DIR = ASSETS / "robots"
CHECKPOINTS_DIR = ASSETS / "checkpoints"
RECORDINGS_DIR = ASSETS / "recordings"
NOTEBOOKS_DIR = _bundled_folder("notebooks")
DOCS_DIR = _bundled_folder("docs")  # PAPER.md (the paper against this code), RESULTS.md (the measurements), DESIGN.md, ...
BUNDLED_ROBOTS = ("yumi", "nao", "pepper")  # a spec, a URDF and a checkpoint each ship with the package (the paper's robot first)


def is_editable_checkout() -> bool:
    """True when the assets are the repository's own (an editable install or a plain checkout)."""
    return ASSETS.parent != PACKAGE_DIR


def is_bundled(path: str | os.PathLike) -> bool:
    """True for a file inside the package's bundled assets or notebooks."""
    p = Path(path).resolve()
    return any(p.is_relative_to(folder.resolve()) for folder in (ASSETS, NOTEBOOKS_DIR))


def repair_hint(path: str | os.PathLike) -> str:
    """How to restore a missing or damaged bundled file (appended to the error that names it)."""
    if is_editable_checkout():
        rel = Path(path).resolve().relative_to(ASSETS.parent.resolve()) if is_bundled(path) else Path(path)
        return f"it ships with nlo_lab; restore it with `git checkout -- {rel}` in the repository"
    return "it ships with nlo_lab, so the installation is damaged; repair it with `pip install --force-reinstall --no-deps nlo_lab`"


def user_notebooks_dir() -> Path:
    """The default folder of the user's copy of the notebooks (``nlo-lab lab``).

    ``$NLO_LAB_NOTEBOOKS`` if set, else ``~/nlo_lab_notebooks``: a folder in
    the home directory, where a learner finds the edited notebooks again.
    """
    env = os.environ.get("NLO_LAB_NOTEBOOKS")
    return Path(env).expanduser() if env else Path.home() / "nlo_lab_notebooks"

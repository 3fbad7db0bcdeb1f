"""``nlo-lab lab``: the learner's own, writable copy of the notebooks, opened in JupyterLab.

The notebooks ship inside the package (:data:`nlo_lab.paths.NOTEBOOKS_DIR`),
which may sit in a read-only ``site-packages``. :func:`copy_notebooks` copies
them into a folder the user owns; a notebook already there is the learner's
work and is never overwritten, but :func:`other_version_copies` names those copied
from another version of the package (the stamp ``metadata.nlo_lab.revision``, a
digest of each notebook's source, differs or is missing), so that ``nlo-lab lab``
can tell the learner to take the new ones. JupyterLab then opens that folder.
"""

from __future__ import annotations

import importlib.util
import json
import os
import sys
from pathlib import Path

from nlo_lab.atomic_files import atomic_write_bytes
from nlo_lab.errors import InstallationError, OutputError
from nlo_lab.paths import NOTEBOOKS_DIR, repair_hint

__all__ = ["bundled_notebooks", "copy_notebooks", "notebook_revision", "other_version_copies", "lab_command"]


def bundled_notebooks() -> list[Path]:
    """The shipped notebooks (``NN_*.ipynb``) and their README, in order."""
    files = sorted(NOTEBOOKS_DIR.glob("[0-9][0-9]_*.ipynb"))
    if not files:
        raise InstallationError(f"no notebooks found in {NOTEBOOKS_DIR}; {repair_hint(NOTEBOOKS_DIR)}")
    readme = NOTEBOOKS_DIR / "README.md"
    return files + ([readme] if readme.is_file() else [])


def copy_notebooks(dest: str | os.PathLike) -> tuple[list[Path], list[Path]]:
    """Copy the shipped notebooks into ``dest``, keeping any copy already there.

    Args:
        dest: the user's folder (created if missing).

    Returns:
        ``(copied, kept)``: the files written now, and those left as they were
        because the folder already had them (the learner's edits).

    Raises:
        NloLabError: ``dest`` is a file, or cannot be created or written.
    """
    dest = Path(dest).expanduser()
    sources = bundled_notebooks()
    if dest.resolve() == NOTEBOOKS_DIR.resolve():
        return [], [dest / s.name for s in sources]  # the checkout's own folder: nothing to copy
    if dest.exists() and not dest.is_dir():
        raise OutputError(f"notebook folder {dest} exists and is not a folder")
    copied, kept = [], []
    try:
        dest.mkdir(parents=True, exist_ok=True)
        for src in sources:
            target = dest / src.name
            if target.exists():
                kept.append(target)
                continue
            atomic_write_bytes(target, src.read_bytes())  # never half a notebook
            copied.append(target)
    except OSError as exc:
        raise OutputError(f"cannot write the notebooks to {dest}: {exc.strerror or exc}") from None
    return copied, kept


def notebook_revision(path: Path) -> str | None:
    """A notebook's stamp (``metadata.nlo_lab.revision``), or None: no stamp, or not a notebook we can read."""
    try:
        stamp = json.loads(Path(path).read_text(encoding="utf-8"))["metadata"]["nlo_lab"]["revision"]
    except (OSError, ValueError, KeyError, TypeError):  # unreadable, not JSON, no stamp: not ours to judge
        return None
    return stamp if isinstance(stamp, str) else None


def other_version_copies(kept: list[Path]) -> list[Path]:
    """The kept notebooks that another version of nlo_lab copied: their stamp differs from the shipped one's.

    A copy without a stamp predates the stamps (an earlier version); a file that is not a
    notebook (or not JSON) is left out. Nothing is written.
    """
    out = []
    for path in kept:
        shipped = NOTEBOOKS_DIR / path.name
        if path.suffix != ".ipynb" or not shipped.is_file():
            continue
        try:
            json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if notebook_revision(path) != notebook_revision(shipped):
            out.append(path)
    return out


def lab_command(folder: Path, port: int) -> list[str]:
    """The JupyterLab command line on ``folder``, bound to loopback only.

    Raises:
        NloLabError: JupyterLab is not installed (it is the ``lab`` extra).
    """
    if importlib.util.find_spec("jupyterlab") is None:
        raise InstallationError("JupyterLab is not installed in this environment; install it with `pip install \"nlo_lab[lab]\"`")
    return [sys.executable, "-m", "jupyter", "lab", f"--notebook-dir={folder}", "--ip=127.0.0.1", f"--port={port}"]

"""``nlo-lab lab``: the learner's own, writable copy of the notebooks, opened in JupyterLab.

The notebooks ship inside the package (:data:`nlo_lab.paths.NOTEBOOKS_DIR`),
which may sit in a read-only ``site-packages``. :func:`copy_notebooks` copies
them into a folder the user owns; a notebook already there is the learner's
work and is never overwritten, but :func:`other_version_copies` names those copied
from another version of the package (the stamp ``metadata.nlo_lab.revision``, a
digest of each notebook's source, differs or is missing), so that ``nlo-lab lab``
can tell the learner to take the new ones. JupyterLab then opens that folder.

Inside a Jupyter that already runs (a JupyterHub's single-user server, Binder, a
notebook cell's ``!nlo-lab lab``: :func:`running_jupyter`) a second server would
be a mistake: the notebooks are copied and :func:`open_hint` says where they are
and how to open them in the Jupyter at hand. As root, JupyterLab refuses to start
without ``--allow-root``: :func:`root_refusal` says so in one line before anything runs.
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

__all__ = ["bundled_notebooks", "copy_notebooks", "notebook_revision", "other_version_copies", "lab_command",
           "running_jupyter", "open_hint", "root_refusal"]


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


def lab_command(folder: Path, port: int, allow_root: bool = False) -> list[str]:
    """The JupyterLab command line on ``folder``, bound to loopback only (``allow_root``: JupyterLab's ``--allow-root``).

    Raises:
        NloLabError: JupyterLab is not installed (it is the ``lab`` extra).
    """
    if importlib.util.find_spec("jupyterlab") is None:
        raise InstallationError("JupyterLab is not installed in this environment; install it with `pip install \"nlo_lab[lab]\"`")
    command = [sys.executable, "-m", "jupyter", "lab", f"--notebook-dir={folder}", "--ip=127.0.0.1", f"--port={port}"]
    return command + (["--allow-root"] if allow_root else [])


def running_jupyter(environ: dict[str, str] | None = None) -> str | None:
    """The Jupyter this process runs inside, or None.

    ``"JupyterHub"`` when a ``JUPYTERHUB_*`` variable is set (a hub's single-user server and
    its terminals and kernels; Binder is a JupyterHub too), ``"Jupyter"`` inside a kernel of a
    running Jupyter server (``JPY_SESSION_NAME`` or ``JPY_PARENT_PID``: ``!nlo-lab lab`` in a cell).
    """
    env = os.environ if environ is None else environ
    if any(key.startswith("JUPYTERHUB_") and env[key] for key in env):
        return "JupyterHub"
    if env.get("JPY_SESSION_NAME") or env.get("JPY_PARENT_PID"):
        return "Jupyter"
    return None


def open_hint(folder: Path, first: str, environ: dict[str, str] | None = None) -> list[str]:
    """At most three lines: where the copy is and how to open ``first`` (a notebook's name) in the running Jupyter.

    The file browser shows the folder relative to the server's root (the home folder on a hub:
    ``JUPYTER_SERVER_ROOT`` when set); on a hub, ``JUPYTERHUB_SERVICE_PREFIX`` (``/user/NAME/``)
    gives the address of the notebook after the hub's own.
    """
    env = os.environ if environ is None else environ
    folder = Path(folder).expanduser().resolve()
    root = Path(env.get("JUPYTER_SERVER_ROOT") or Path.home()).expanduser().resolve()
    try:
        shown = folder.relative_to(root).as_posix()
    except ValueError:  # outside the server's root: its file browser cannot reach it
        return [f"the notebooks are in {folder}, outside the running Jupyter's folder {root}:",
                f"copy them below {root} (nlo-lab lab --dir {root / 'nlo_lab_notebooks'}) to open them there"]
    lines = [f"a Jupyter is running here, so none is started: open {shown}/{first} in its file browser"]
    prefix = env.get("JUPYTERHUB_SERVICE_PREFIX")
    if prefix:
        lines.append(f"or at {prefix.rstrip('/')}/lab/tree/{shown}/{first} after your hub's address")
    return lines


def root_refusal(uid: int | None = None) -> str | None:
    """Why ``nlo-lab lab`` stops as root (JupyterLab refuses to run as root unless told), or None."""
    uid = os.geteuid() if uid is None and hasattr(os, "geteuid") else uid
    if uid != 0:
        return None
    return ("nlo-lab lab: running as root, and JupyterLab refuses to start as root; run it as your own user, "
            "or pass --allow-root if you mean it (--copy-only copies the notebooks without starting anything)")

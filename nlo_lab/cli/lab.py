"""``nlo-lab lab``: copy the notebooks into the learner's folder (never over their files) and open JupyterLab there.

Inside a Jupyter that already runs (JupyterHub's ``JUPYTERHUB_*`` variables, a notebook cell) or with
``--copy-only`` it only copies and says in a few lines where the notebooks are and how to open them:
no second server. As root it stops before any work with one line naming ``--allow-root``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from nlo_lab.cli.flags import UsageError, ranged_int
from nlo_lab.errors import escape

__all__ = ["add_parser", "run"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("lab", help="copy the notebooks to a folder of yours and open JupyterLab there")
    p.add_argument("--port", type=ranged_int(1, 65535), default=8888)
    p.add_argument("--dir", default=None, help="your notebook folder (default: $NLO_LAB_NOTEBOOKS or ~/nlo_lab_notebooks)")
    p.add_argument("--copy-only", action="store_true",
                   help="copy the notebooks and print the folder; do not start JupyterLab (what happens inside a running Jupyter)")
    p.add_argument("--allow-root", action="store_true", help="start JupyterLab even as root (JupyterLab's own --allow-root)")
    return p


def run(args) -> int:
    from nlo_lab.lab import copy_notebooks, lab_command, open_hint, other_version_copies, root_refusal, running_jupyter
    from nlo_lab.paths import user_notebooks_dir

    if args.dir is not None and not args.dir.strip():  # not "the default": a script's empty variable is a mistake
        raise UsageError(f"nlo-lab lab: --dir must be a folder path, got {args.dir!r}")
    folder = Path(args.dir).expanduser() if args.dir is not None else user_notebooks_dir()
    inside = running_jupyter()
    serve = not (args.copy_only or inside)
    if serve and not args.allow_root and root_refusal():
        raise UsageError(root_refusal())  # before anything is copied or started
    copied, kept = copy_notebooks(folder)
    note = f" (kept your {len(kept)} existing files)" if kept else ""
    print(f"notebooks: {folder}: copied {len(copied)} files{note}", file=sys.stderr)
    older = other_version_copies(kept)
    if older:  # told, never touched: the learner's edits are theirs
        print(f"notebooks: {len(older)} of your copies come from another version of nlo_lab: "
              f"{', '.join(escape(p.name) for p in older)}", file=sys.stderr)
        print("notebooks: to take this version's, rename or move them and run `nlo-lab lab` again", file=sys.stderr)
    if inside:  # a second server would be a mistake: say how to open them in this one
        first = min((p.name for p in (copied + kept) if p.suffix == ".ipynb"), default="")
        for line in open_hint(folder, first):
            print(f"notebooks: {line}", file=sys.stderr)
    if not serve:
        print(folder)
        return 0
    command = lab_command(folder, args.port, allow_root=args.allow_root)
    os.execv(sys.executable, command)
    return 0  # not reached

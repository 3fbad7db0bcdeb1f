"""``nlo-lab lab``: copy the notebooks into the learner's folder (never over their files) and open JupyterLab there."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from nlo_lab.cli.flags import ranged_int
from nlo_lab.errors import escape

__all__ = ["add_parser", "run"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("lab", help="copy the notebooks to a folder of yours and open JupyterLab there")
    p.add_argument("--port", type=ranged_int(1, 65535), default=8888)
    p.add_argument("--dir", default=None, help="your notebook folder (default: $NLO_LAB_NOTEBOOKS or ~/nlo_lab_notebooks)")
    p.add_argument("--copy-only", action="store_true", help="copy the notebooks and print the folder; do not start JupyterLab")
    return p


def run(args) -> int:
    from nlo_lab.lab import copy_notebooks, lab_command, other_version_copies
    from nlo_lab.paths import user_notebooks_dir

    folder = Path(args.dir).expanduser() if args.dir else user_notebooks_dir()
    copied, kept = copy_notebooks(folder)
    note = f" (kept your {len(kept)} existing files)" if kept else ""
    print(f"notebooks: {folder}: copied {len(copied)} files{note}", file=sys.stderr)
    older = other_version_copies(kept)
    if older:  # told, never touched: the learner's edits are theirs
        print(f"notebooks: {len(older)} of your copies come from another version of nlo_lab: "
              f"{', '.join(escape(p.name) for p in older)}", file=sys.stderr)
        print("notebooks: to take this version's, rename or move them and run `nlo-lab lab` again", file=sys.stderr)
    if args.copy_only:
        print(folder)
        return 0
    command = lab_command(folder, args.port)
    os.execv(sys.executable, command)
    return 0  # not reached

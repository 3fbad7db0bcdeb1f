"""Where the package's bundled files live.

``assets/`` sits beside the package in the source tree (DESIGN's layout); an
editable install (``pip install -e .``, what the Makefile and Binder do) uses it
in place.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["ASSETS", "ROBOTS_DIR", "CHECKPOINTS_DIR", "NOTEBOOKS_DIR"]

ROOT = Path(__file__).resolve().parent.parent
ASSETS = ROOT / "assets"
ROBOTS_DIR = ASSETS / "robots"
CHECKPOINTS_DIR = ASSETS / "checkpoints"
NOTEBOOKS_DIR = ROOT / "notebooks"

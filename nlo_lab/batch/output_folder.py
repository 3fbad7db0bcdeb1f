"""The folder a retargeting writes: ``trajectory.npz``, ``trajectory.csv``, ``viewer.html``, ``summary.json``.

``nlo-lab retarget --out DIR`` and ``nlo-lab batch`` (one folder per input) both write it with
:func:`write_output_folder`: the files are written into a temporary folder beside the target
and swapped in whole (:func:`nlo_lab.atomic_files.output_set`), so a reader, or a run killed
half-way, never finds a folder with some files new and some old or missing.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from nlo_lab.atomic_files import atomic_write_bytes, output_set

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["OUTPUT_FILES", "SUMMARY_FILE", "VIEWER_FILE", "finite_or_null", "write_output_folder", "read_summary"]

OUTPUT_FILES = ("trajectory.npz", "trajectory.csv", "viewer.html")  # the set `retarget --out` writes
VIEWER_FILE = "viewer.html"
SUMMARY_FILE = "summary.json"  # batch adds it: the summary and what made the folder


def finite_or_null(summary: dict) -> dict:
    """NaN and infinity are not JSON: a figure that is not finite becomes None (``null``)."""
    return {k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in summary.items()}


def write_output_folder(out_dir, result, demo, robot: Robot, *, viewer: bool = True, summary: dict | None = None,
                        stale: tuple[str, ...] = (), before_swap: Callable[[], None] | None = None) -> Path:
    """Write a retargeting's files into ``out_dir``, all or nothing.

    Args:
        out_dir: the folder (created with its parents; other plain files in it are kept).
        result: a :class:`~nlo_lab.pipeline.RetargetResult`.
        demo: the demonstration it was made from (the viewer shows it beside the robot).
        robot: the robot.
        viewer: write ``viewer.html`` (the robot's motion beside the human's, played on the
            trajectory's retimed time base).
        summary: also write this object as ``summary.json`` (figures that are not finite as null).
        stale: files of an earlier set that go when this one does not write them (``batch`` passes
            ``viewer.html`` and ``summary.json``: a folder's files all come from one run).
        before_swap: called when every file is written, before the swap (raise to abandon it).

    Returns:
        The folder.

    Raises:
        OutputError: the place cannot take the folder (see :func:`nlo_lab.atomic_files.check_output_place`).
    """
    names = ("trajectory.npz", "trajectory.csv") + ((VIEWER_FILE,) if viewer else ()) + ((SUMMARY_FILE,) if summary else ())
    with output_set(out_dir, names, replaces=stale) as tmp:
        result.trajectory.save_npz(tmp / "trajectory.npz")
        result.trajectory.save_csv(tmp / "trajectory.csv")
        if viewer:
            # lazy: meshcat: only when the viewer page is asked for
            from nlo_lab.viz import export_html

            export_html(tmp / VIEWER_FILE, robot, result.trajectory.angles, demo=demo, fps=demo.fps, single_precision=True,
                        times=result.trajectory.times)
        if summary:
            text = json.dumps(finite_or_null(summary), indent=1, allow_nan=False, default=str)
            atomic_write_bytes(tmp / SUMMARY_FILE, (text + "\n").encode("utf-8"))
        if before_swap is not None:
            before_swap()
    return Path(out_dir)


def read_summary(folder) -> dict | None:
    """``folder/summary.json`` as a dict, or None when it is absent or unreadable."""
    try:
        data = json.loads((Path(folder) / SUMMARY_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None

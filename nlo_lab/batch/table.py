"""``results.csv``: one row per input, written atomically and refreshed as results arrive.

Columns (:data:`COLUMNS`): ``input`` (the file), ``status`` (``ok``, ``failed`` or
``skipped``), ``error`` (one line naming the file; empty unless failed), ``frames``,
``seconds`` (the workers' time for the input: reading, pose estimation, retargeting,
writing; a skipped row keeps the run's that made its folder), ``output`` (the input's folder
relative to the output folder), then the summary's quality figures (:data:`QUALITY`),
``warnings`` (the reader's warnings, ``; ``-separated), and ``input_sha256`` and ``settings``
(the fingerprint of :class:`~nlo_lab.batch.BatchSettings`), which decide a resumed run.
"""

from __future__ import annotations

import csv
import io
import math
import time
from pathlib import Path

from nlo_lab.atomic_files import atomic_write_bytes

__all__ = ["COLUMNS", "QUALITY", "HANDS", "STATUSES", "ResultsTable", "read_rows", "row_from_summary", "failed_row"]

STATUSES = ("ok", "failed", "skipped")
QUALITY = (
    "frechet_m", "frechet_wrist_m", "frechet_elbow_m", "self_collision_frames", "limit_violations",
    "velocity_violations", "max_joint_speed_ratio", "recording_speed_ratio", "slowdown", "max_joint_step_rad",
    "depth", "iterations", "final_loss", "retarget_seconds", "pose_seconds",
)
# the handshape measures (nlo_lab.metrics.HAND_KEYS, spelt out: importing the metrics imports torch, which a run with
# nothing left to do never does), after the columns an earlier version wrote; empty on a robot without five fingers
HANDS = ("hand_frames", "wrist_tip_deg", "thumb_tips_deg", "base_tip_deg", "pinch_r")
COLUMNS = ("input", "status", "error", "frames", "seconds", "output", *QUALITY, "warnings", "input_sha256", "settings", *HANDS)
_INTS = {"frames", "self_collision_frames", "limit_violations", "velocity_violations", "iterations", "hand_frames"}
_TEXT = {"input", "status", "error", "output", "depth", "warnings", "input_sha256", "settings"}


def row_from_summary(summary: dict, status: str = "ok") -> dict:
    """A row from an input's ``summary.json`` (what its folder says about the run that made it)."""
    made = summary.get("batch", {})
    row = {c: summary.get(c) for c in (*QUALITY, *HANDS)}
    row["retarget_seconds"] = summary.get("seconds")
    row.update(input=made.get("input"), status=status, error="", frames=summary.get("frames"), seconds=made.get("seconds"),
               output=made.get("output"), warnings="; ".join(made.get("warnings", [])),
               input_sha256=made.get("input_sha256"), settings=made.get("settings"))
    return {c: row.get(c) for c in COLUMNS}


def failed_row(path, output: str, error: str, *, input_sha256=None, settings=None, seconds=None) -> dict:
    """The row of an input that failed: its one-line error, no figures."""
    row = dict.fromkeys(COLUMNS)
    row.update(input=str(path), status="failed", error=error, output=output, input_sha256=input_sha256,
               settings=settings, seconds=seconds, warnings="")
    return row


def _cell(value) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return ""
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _parse(column: str, text: str):
    if text == "" and column not in ("error", "warnings"):
        return None
    if column in _TEXT:
        return text
    try:
        return int(text) if column in _INTS else float(text)
    except ValueError:
        return None


def read_rows(path) -> dict[str, dict]:
    """The rows of an earlier ``results.csv`` by ``output``; {} when it is absent or not ours."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return {}
    reader = csv.DictReader(io.StringIO(text))
    if not reader.fieldnames or not {"input", "status", "output"} <= set(reader.fieldnames):
        return {}
    rows = {}
    try:
        for raw in reader:
            row = {c: _parse(c, raw.get(c) or "") for c in COLUMNS}
            if row["output"] and row["status"] in STATUSES:
                rows[row["output"]] = row
    except csv.Error:
        return {}
    return rows


class ResultsTable:
    """The rows of this run, in the inputs' order, written to ``path`` atomically.

    :meth:`set` records a row; the file is rewritten at most every ``interval`` seconds
    (a corpus of thousands of inputs would otherwise rewrite a large file per result) and
    by :meth:`flush`. The file only ever holds rows of finished inputs: an interrupted run
    leaves a true table, and a run refused before any input was decided (an unknown robot,
    a setting the robot cannot take) leaves none where there was none.
    """

    def __init__(self, path, order: list[str], interval: float = 1.0):
        self.path, self.interval = Path(path), interval
        self.rows: dict[str, dict] = {}
        self._order = {name: i for i, name in enumerate(order)}
        self._written = -math.inf
        self._dirty = False

    def set(self, row: dict) -> None:
        self.rows[row["output"]] = row
        self._dirty = True
        if time.monotonic() - self._written >= self.interval:
            self.flush()

    def ordered(self) -> list[dict]:
        return sorted(self.rows.values(), key=lambda r: self._order.get(r["output"], len(self._order)))

    def flush(self) -> None:
        if not self._dirty and self.path.exists():
            return
        if not self.rows and not self.path.exists():  # nothing decided: no header-only file
            return
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(COLUMNS)
        for row in self.ordered():
            writer.writerow([_cell(row.get(c)) for c in COLUMNS])
        atomic_write_bytes(self.path, buf.getvalue().encode("utf-8"))
        self._written, self._dirty = time.monotonic(), False

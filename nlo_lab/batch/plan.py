"""What a run has to do: which inputs are done already, which failed on unchanged content, which to run.

An input is **skipped** when its folder's ``summary.json`` says it was made from the same
content (SHA-256) with the same settings (:meth:`~nlo_lab.batch.BatchSettings.fingerprint`)
and the folder holds every file this run would write. An input whose earlier row in
``results.csv`` says ``failed`` on the same content and settings keeps that row and is not run
again (a corrupt file does not heal), unless ``retry_failed``. Everything else runs. A file
that cannot be read to hash it (gone, no permission) fails here, without a worker.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from nlo_lab.batch.inputs import RESULTS_FILE, BatchInput, file_sha256
from nlo_lab.batch.output_folder import SUMMARY_FILE, VIEWER_FILE, read_summary
from nlo_lab.batch.settings import BatchSettings
from nlo_lab.batch.table import failed_row, read_rows, row_from_summary
from nlo_lab.batch.tasks import Job, failure_text

__all__ = ["Plan", "plan_run"]


@dataclass
class Plan:
    """Rows decided without running (skipped, failed before, unreadable) and the jobs to run."""

    rows: list[dict] = field(default_factory=list)
    jobs: list[Job] = field(default_factory=list)


def _complete(folder: Path, viewer: bool) -> bool:
    names = ("trajectory.npz", "trajectory.csv", SUMMARY_FILE) + ((VIEWER_FILE,) if viewer else ())
    return all((folder / n).is_file() for n in names)


def plan_run(items: list[BatchInput], out: Path, settings: BatchSettings, *, resume: bool = True,
             retry_failed: bool = False) -> Plan:
    """Decide each input's fate (see the module docstring)."""
    fingerprint, key = settings.fingerprint(), settings.key()
    earlier = read_rows(out / RESULTS_FILE) if resume else {}
    plan = Plan()
    for item in items:
        folder = out / item.name
        try:
            sha = file_sha256(item.path)
        except OSError as exc:
            plan.rows.append(failed_row(item.path, item.name, failure_text(exc, item.path), settings=fingerprint))
            continue
        if resume:
            summary = read_summary(folder)
            made = summary.get("batch", {}) if summary else {}
            if made.get("input_sha256") == sha and made.get("settings") == fingerprint and _complete(folder, settings.viewer):
                row = row_from_summary(summary, status="skipped")
                row.update(input=str(item.path), output=item.name)
                plan.rows.append(row)
                continue
            row = earlier.get(item.name)
            if (not retry_failed and row and row["status"] == "failed" and row["input_sha256"] == sha
                    and row["settings"] == fingerprint):
                plan.rows.append({**row, "input": str(item.path)})
                continue
        plan.jobs.append(Job(item, str(folder.resolve()), sha, settings, fingerprint, key))
    return plan

"""What a resumed run decides without a cluster: skipped, failed kept, ``--retry-failed``, changed content or settings."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from nlo_lab.batch import BatchSettings, file_sha256, find_inputs
from nlo_lab.batch.plan import plan_run
from nlo_lab.batch.table import ResultsTable, failed_row
from nlo_lab.paths import RECORDINGS_DIR

POSE = RECORDINGS_DIR / "holistic_both_hands_47f.pose"
SETTINGS = BatchSettings("nao", iterations=3)


def _done(out: Path, name: str, source: Path, settings: BatchSettings, files=("trajectory.npz", "trajectory.csv")) -> None:
    """An output folder as a finished run leaves it: its files and a summary naming the content and settings."""
    folder = out / name
    folder.mkdir(parents=True)
    for f in files:
        (folder / f).write_bytes(b"made earlier")
    made = {"input": str(source), "output": name, "input_sha256": file_sha256(source), "settings": settings.fingerprint(),
            "seconds": 1.5, "warnings": []}
    (folder / "summary.json").write_text(json.dumps({"frames": 47, "frechet_m": 0.1, "seconds": 1.2, "batch": made}))


def _corpus(tmp_path: Path) -> tuple[Path, Path]:
    corpus, out = tmp_path / "corpus", tmp_path / "out"
    corpus.mkdir(parents=True)
    for name in ("done", "incomplete", "new"):
        shutil.copy(POSE, corpus / f"{name}.pose")
    (corpus / "corrupt.pose").write_bytes(b"not a pose file")
    _done(out, "done", corpus / "done.pose", SETTINGS)
    _done(out, "incomplete", corpus / "incomplete.pose", SETTINGS, files=("trajectory.npz",))  # its .csv never came
    table = ResultsTable(out / "results.csv", ["corrupt"])
    table.set(failed_row(corpus / "corrupt.pose", "corrupt", f"{corpus / 'corrupt.pose'}: not a .pose file",
                         input_sha256=file_sha256(corpus / "corrupt.pose"), settings=SETTINGS.fingerprint()))
    table.flush()
    return corpus, out


def _fates(plan) -> dict[str, str]:
    fates = {row["output"]: row["status"] for row in plan.rows}
    fates.update({job.item.name: "run" for job in plan.jobs})
    return fates


def test_a_resumed_run_skips_the_done_keeps_the_failed_and_runs_the_rest(tmp_path):
    corpus, out = _corpus(tmp_path)
    plan = plan_run(find_inputs([corpus], out), out, SETTINGS)
    assert _fates(plan) == {"done": "skipped", "corrupt": "failed", "incomplete": "run", "new": "run"}
    kept = next(r for r in plan.rows if r["output"] == "corrupt")
    assert kept["error"] == f"{corpus / 'corrupt.pose'}: not a .pose file"  # the earlier run's error, not run again
    skipped = next(r for r in plan.rows if r["output"] == "done")
    assert skipped["frames"] == 47 and skipped["seconds"] == 1.5 and skipped["input"] == str(corpus / "done.pose")


def test_retry_failed_runs_the_failed_input_again(tmp_path):
    corpus, out = _corpus(tmp_path)
    plan = plan_run(find_inputs([corpus], out), out, SETTINGS, retry_failed=True)
    assert _fates(plan) == {"done": "skipped", "corrupt": "run", "incomplete": "run", "new": "run"}


def test_no_resume_runs_everything(tmp_path):
    corpus, out = _corpus(tmp_path)
    plan = plan_run(find_inputs([corpus], out), out, SETTINGS, resume=False)
    assert _fates(plan) == dict.fromkeys(("corrupt", "done", "incomplete", "new"), "run")


def test_changed_content_or_settings_run_again(tmp_path):
    corpus, out = _corpus(tmp_path)
    (corpus / "corrupt.pose").write_bytes(POSE.read_bytes())  # the corrupt file was replaced: it may heal now
    (corpus / "done.pose").write_bytes(POSE.read_bytes() + b"\0")  # the recording changed
    plan = plan_run(find_inputs([corpus], out), out, SETTINGS)
    assert _fates(plan) == {"done": "run", "corrupt": "run", "incomplete": "run", "new": "run"}

    corpus, out = _corpus(tmp_path / "again")
    plan = plan_run(find_inputs([corpus], out), out, BatchSettings("nao", iterations=4))  # another budget
    assert _fates(plan) == dict.fromkeys(("corrupt", "done", "incomplete", "new"), "run")
    assert all(job.fingerprint == BatchSettings("nao", iterations=4).fingerprint() for job in plan.jobs)


def test_a_viewer_asked_for_now_runs_a_folder_made_without_one(tmp_path):
    corpus, out = _corpus(tmp_path)
    plan = plan_run(find_inputs([corpus / "done.pose"], out), out, BatchSettings("nao", iterations=3, viewer=True))
    assert _fates(plan) == {"done": "run"}


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root reads a file without permissions")
def test_an_input_that_cannot_be_read_fails_without_a_worker(tmp_path):
    corpus, out = _corpus(tmp_path)
    (corpus / "new.pose").chmod(0)
    try:
        plan = plan_run(find_inputs([corpus / "new.pose"], out), out, SETTINGS)
    finally:
        (corpus / "new.pose").chmod(0o644)
    assert _fates(plan) == {"new": "failed"}
    assert plan.rows[0]["error"] == f"Permission denied: {corpus / 'new.pose'}"

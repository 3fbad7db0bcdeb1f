"""retarget_many on a real LocalCluster: good and bad inputs, the outputs, the table, resuming, what listens.

Kept short for CI: one worker, a few iterations, the bundled 47-frame recording.
"""

from __future__ import annotations

import csv
import os
import shutil
import sys
import types
from pathlib import Path

import numpy as np
import psutil
import pytest

from nlo_lab.batch import COLUMNS, retarget_many
from nlo_lab.batch import engine as batch_engine
from nlo_lab.inference import RobotTrajectory
from nlo_lab.paths import RECORDINGS_DIR

POSE = RECORDINGS_DIR / "holistic_both_hands_47f.pose"
ITERS = 3


def _corpus(root: Path) -> Path:
    folder = root / "corpus"
    (folder / "sub").mkdir(parents=True)
    (folder / "bad").mkdir()
    shutil.copy(POSE, folder / "a.pose")
    shutil.copy(POSE, folder / "sub" / "b.pose")
    (folder / "bad" / "corrupt.pose").write_bytes(b"this is not a pose file")
    (folder / "bad" / "empty.npz").write_bytes(b"")
    (folder / "notes.md").write_text("not an input")
    return folder


def _listening(pid: int) -> list[str]:
    """Addresses the process ``pid`` and its children listen on."""
    out = []
    for proc in [psutil.Process(pid), *psutil.Process(pid).children(recursive=True)]:
        try:
            out += [c.laddr.ip for c in proc.net_connections(kind="inet") if c.status == psutil.CONN_LISTEN]
        except psutil.Error:
            pass
    return out


def _hidden(folder: Path) -> list[Path]:
    return [p for p in folder.rglob(".*") if p.name != ".nlo-lab-batch.lock"]


@pytest.mark.slow
def test_a_corpus_with_bad_files_on_a_local_cluster_then_resumed(tmp_path, monkeypatch):
    corpus, out = _corpus(tmp_path), tmp_path / "out"
    listening: list[str] = []
    seen: list[dict] = []

    def on_row(row):
        if not listening:
            listening.extend(_listening(os.getpid()))
        seen.append(row)

    environ = dict(os.environ)
    rows = retarget_many([corpus], "nao", out, workers=1, iterations=ITERS, on_row=on_row)
    assert dict(os.environ) == environ  # dask's nanny wrote its workers' variables here; they are gone again
    assert isinstance(rows, list)  # no pandas in this environment
    assert [r["output"] for r in rows] == ["a", "bad/corrupt", "bad/empty", "sub/b"]
    assert sorted(r["output"] for r in seen) == sorted(r["output"] for r in rows)
    by = {r["output"]: r for r in rows}
    assert [by[k]["status"] for k in ("a", "sub/b", "bad/corrupt", "bad/empty")] == ["ok", "ok", "failed", "failed"]

    # the security rule: the scheduler and the workers listen on the loopback only
    assert listening and set(listening) == {"127.0.0.1"}, listening

    # failures: one line naming the file; no folder
    for name in ("bad/corrupt", "bad/empty"):
        error = by[name]["error"]
        assert str(corpus / f"{name}.{'pose' if 'corrupt' in name else 'npz'}") in error and "\n" not in error
        assert not (out / name).exists()
    assert "internal error" not in by["bad/corrupt"]["error"] + by["bad/empty"]["error"]

    # good outputs: complete, and what the row says
    for name in ("a", "sub/b"):
        folder = out / name
        assert sorted(os.listdir(folder)) == ["summary.json", "trajectory.csv", "trajectory.npz"]
        traj = RobotTrajectory.load(folder / "trajectory.npz")
        assert traj.robot == "nao" and traj.angles.shape[0] == 47 == by[name]["frames"]
        assert np.isfinite(traj.angles).all()
        assert by[name]["iterations"] <= ITERS and by[name]["frechet_m"] > 0 and by[name]["seconds"] > 0
        assert by[name]["limit_violations"] == 0 and by[name]["input_sha256"] and by[name]["settings"]
    a = RobotTrajectory.load(out / "a" / "trajectory.npz").angles
    np.testing.assert_array_equal(a, RobotTrajectory.load(out / "sub" / "b" / "trajectory.npz").angles)
    assert _hidden(out) == []  # no temporary folder left behind

    # results.csv holds the same rows
    with open(out / "results.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    assert tuple(table[0]) == COLUMNS
    assert [(r["output"], r["status"], r["error"]) for r in table] == [(r["output"], r["status"], r["error"]) for r in rows]

    # resumed: nothing to run, so no cluster at all; done inputs are skipped, failed ones keep their row
    def no_cluster(*args, **kwargs):
        raise AssertionError("a cluster was started with nothing to run")

    monkeypatch.setattr(batch_engine, "_cluster", no_cluster)
    again = retarget_many([corpus], "nao", out, iterations=ITERS)
    by2 = {r["output"]: r for r in again}
    assert [by2[k]["status"] for k in ("a", "sub/b", "bad/corrupt", "bad/empty")] == ["skipped", "skipped", "failed", "failed"]
    assert by2["bad/corrupt"]["error"] == by["bad/corrupt"]["error"]
    assert by2["a"]["frechet_m"] == by["a"]["frechet_m"] and by2["a"]["seconds"] == by["a"]["seconds"]

    # a changed input and changed settings run again (the cluster is asked for)
    shutil.copy(POSE, corpus / "bad" / "corrupt.pose")  # the corrupt file was replaced by a good one
    with pytest.raises(AssertionError, match="a cluster was started"):
        retarget_many([corpus], "nao", out, iterations=ITERS)
    with pytest.raises(AssertionError, match="a cluster was started"):
        retarget_many([corpus / "a.pose"], "nao", out, iterations=ITERS + 1)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator")
def test_the_allocator_thresholds_dask_freezes_are_raised_again():
    import subprocess

    code = "from nlo_lab.batch.tasks import undo_malloc_trim; print(undo_malloc_trim())"
    env = {k: v for k, v in os.environ.items() if k != "MALLOC_TRIM_THRESHOLD_"}
    assert subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True).stdout.strip() == "False"
    env["MALLOC_TRIM_THRESHOLD_"] = "65536"  # what dask's nanny sets
    assert subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True).stdout.strip() == "True"


@pytest.mark.slow
def test_an_unknown_robot_is_refused_when_the_first_worker_loads_it(tmp_path):
    from nlo_lab.errors import UnknownRobotError

    (tmp_path / "in").mkdir()
    shutil.copy(POSE, tmp_path / "in" / "a.pose")
    with pytest.raises(UnknownRobotError, match="unknown robot 'nobody'"):
        retarget_many([tmp_path / "in"], "nobody", tmp_path / "out", workers=1)
    # nothing ran: no folder and no table (not even a header), only the run's lock
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [".nlo-lab-batch.lock"]


@pytest.mark.slow
def test_a_refused_run_keeps_the_table_an_earlier_run_wrote(tmp_path):
    from nlo_lab.errors import UnknownRobotError

    (tmp_path / "in").mkdir()
    shutil.copy(POSE, tmp_path / "in" / "a.pose")
    (tmp_path / "out").mkdir()
    earlier = ",".join(COLUMNS) + "\n" + ",".join(["a.pose", "failed", "boom"] + [""] * (len(COLUMNS) - 3)) + "\n"
    (tmp_path / "out" / "results.csv").write_text(earlier)
    with pytest.raises(UnknownRobotError, match="unknown robot 'nobody'"):
        retarget_many([tmp_path / "in"], "nobody", tmp_path / "out", workers=1)
    assert (tmp_path / "out" / "results.csv").read_text() == earlier


def test_the_table_is_a_dataframe_when_pandas_is_there(tmp_path, monkeypatch):
    made = {}

    class DataFrame:
        def __init__(self, rows, columns):
            made.update(rows=rows, columns=columns)

    monkeypatch.setitem(sys.modules, "pandas", types.SimpleNamespace(DataFrame=DataFrame))
    manifest = tmp_path / "list.txt"
    manifest.write_text("gone.pose\n")  # fails before any task: its file cannot be read
    frame = retarget_many([manifest], "nao", tmp_path / "out")
    assert isinstance(frame, DataFrame) and made["columns"] == list(COLUMNS)
    assert [(r["status"], r["error"]) for r in made["rows"]] == [("failed", f"file not found: {tmp_path / 'gone.pose'}")]


def _worker_processes() -> list[psutil.Process]:
    """The LocalCluster's worker processes: this process's children that dask spawned."""
    return [p for p in psutil.Process().children(recursive=True) if "spawn_main" in " ".join(p.cmdline())]


@pytest.mark.slow
def test_results_equal_whatever_the_workers_and_a_killed_worker_changes_nothing(tmp_path):
    corpus = tmp_path / "corpus"
    corpus.mkdir()
    sources = [POSE, *sorted(Path(__file__).resolve().parents[3].joinpath("shared", "data", "pose").glob("*.pose"))]
    for i in range(8):
        shutil.copy(sources[i % len(sources)], corpus / f"take_{i}.pose")
    one = retarget_many([corpus], "yumi", tmp_path / "one", workers=1, iterations=20)
    killed = []

    def kill_one(row):
        if not killed:
            victim = _worker_processes()[0]
            victim.kill()  # SIGKILL, mid-run: its task runs again on a worker the nanny starts anew
            killed.append(victim.pid)

    two = retarget_many([corpus], "yumi", tmp_path / "two", workers=2, iterations=20, on_row=kill_one)
    assert killed and [r["status"] for r in one] == [r["status"] for r in two] == ["ok"] * 8
    for a, b in zip(one, two, strict=True):
        ta = RobotTrajectory.load(tmp_path / "one" / a["output"] / "trajectory.npz")
        tb = RobotTrajectory.load(tmp_path / "two" / b["output"] / "trajectory.npz")
        np.testing.assert_array_equal(ta.angles, tb.angles)
        np.testing.assert_array_equal(ta.times, tb.times)
        assert a["frechet_m"] == b["frechet_m"] and a["input_sha256"] == b["input_sha256"]
    assert _hidden(tmp_path / "two") == []


@pytest.mark.slow
def test_our_local_cluster_has_single_threaded_workers_on_the_loopback():
    from urllib.parse import urlsplit

    with batch_engine._cluster(None, None, 2) as client:
        info = client.scheduler_info()
        assert urlsplit(info["address"]).hostname == "127.0.0.1"
        assert len(info["workers"]) == 2 and {w["nthreads"] for w in info["workers"].values()} == {1}
        assert {urlsplit(a).hostname for a in info["workers"]} == {"127.0.0.1"}
        # torch, its BLAS and our own thread setting: one thread in every worker process
        threads = client.run(lambda: (__import__("torch").get_num_threads(), __import__("os").environ.get("NLO_LAB_THREADS")))
        assert sorted(threads.values()) == [(1, "1"), (1, "1")]
        # each worker freezes its objects when it closes, so that its process ends at once (nlo_lab.batch.quick_exit)
        plugins = client.run(lambda dask_worker: sorted(dask_worker.plugins))
        assert all("nlo-lab-quick-exit" in names for names in plugins.values()), plugins


def test_a_closing_worker_hands_its_objects_to_gc_freeze():
    import gc

    from nlo_lab.batch.quick_exit import QuickExit

    assert gc.get_freeze_count() == 0
    try:
        QuickExit().teardown(worker=None)
        assert gc.get_freeze_count() > 1000  # this process's objects, torch's among them
    finally:
        gc.unfreeze()


def test_each_worker_builds_the_retargeter_once_per_settings(monkeypatch):
    from nlo_lab.batch import BatchSettings, tasks

    built = []
    monkeypatch.setattr(tasks, "_CACHE", {})
    monkeypatch.setattr(BatchSettings, "build", lambda self: built.append(self) or object())
    a, b = BatchSettings("nao", iterations=3), BatchSettings("nao", iterations=3)
    assert tasks.cached_retargeter(a) is tasks.cached_retargeter(b) and len(built) == 1  # equal settings: one model
    assert tasks.warm_up(a) == __import__("nlo_lab").__version__ and len(built) == 1
    tasks.cached_retargeter(BatchSettings("nao", iterations=4))
    assert len(built) == 2
    for i in range(10):  # a notebook trying many settings keeps a few models, not all
        tasks.cached_retargeter(BatchSettings("nao", iterations=10 + i))
    assert len(tasks._CACHE) == tasks._CACHE_SIZE


def test_videos_go_first_then_the_largest_files(tmp_path):
    """dask starts tasks of equal priority in the order they came: the longest inputs must come first, so that no
    worker waits at the end of the run for one long input."""
    from nlo_lab.batch import BatchSettings
    from nlo_lab.batch.inputs import BatchInput
    from nlo_lab.batch.tasks import Job

    sizes = {"small.pose": 10, "large.pose": 1000, "clip.mp4": 5, "medium.npz": 100, "gone.pose": None}
    jobs = []
    for name, size in sizes.items():
        path = tmp_path / name
        if size is not None:
            path.write_bytes(b"x" * size)
        jobs.append(Job(BatchInput(path, path.stem), str(tmp_path / path.stem), "0" * 64, BatchSettings("yumi"), "f" * 16, {}))
    order = [job.item.path.name for job in batch_engine._longest_first(jobs)]
    assert order == ["clip.mp4", "large.pose", "medium.npz", "small.pose", "gone.pose"]

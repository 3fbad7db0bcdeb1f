"""``nlo-lab batch`` as a user runs it (a fresh process each): exit statuses, rows, outputs, stderr, resume, faults."""

from __future__ import annotations

import csv
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import psutil
import pytest

from nlo_lab.paths import RECORDINGS_DIR

POSE = RECORDINGS_DIR / "holistic_both_hands_47f.pose"


def batch(*args, cwd=None, timeout=600) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "nlo_lab.cli", "batch", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout)


def table(out: Path) -> dict[str, dict]:
    with open(out / "results.csv", newline="") as fh:
        return {row["output"]: row for row in csv.DictReader(fh)}


def errors(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("nlo-lab: error: ")]


def assert_one_line_error(proc, *needles) -> None:
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("nlo-lab: error: ") and "Traceback" not in proc.stderr, proc.stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])


def complete(folder: Path) -> bool:
    return sorted(os.listdir(folder)) == ["summary.json", "trajectory.csv", "trajectory.npz"]


def no_temporary_folders(out: Path) -> bool:
    return not [p for p in out.rglob(".*") if p.name != ".nlo-lab-batch.lock"]


def test_a_folder_with_good_and_bad_files_exits_1_with_the_right_rows(tmp_path):
    corpus, out = tmp_path / "corpus", tmp_path / "out"
    (corpus / "session").mkdir(parents=True)
    shutil.copy(POSE, corpus / "good.pose")
    shutil.copy(POSE, corpus / "session" / "also good.pose")
    (corpus / "session" / "broken.pose").write_bytes(POSE.read_bytes()[:300])  # a truncated recording
    (corpus / "nan.npz").write_bytes(b"PK\x03\x04 not really a zip")
    proc = batch(corpus, "--robot", "nao", "--out", out, "--iters", 2, "--workers", 1, "--quiet")
    assert proc.returncode == 1, proc.stderr
    rows = table(out)
    assert {k: r["status"] for k, r in rows.items()} == {"good": "ok", "nan": "failed", "session/also good": "ok",
                                                        "session/broken": "failed"}
    assert list(rows) == ["good", "nan", "session/also good", "session/broken"]  # the inputs' order
    for name in ("nan", "session/broken"):
        assert rows[name]["error"] and rows[name]["input"] in rows[name]["error"] and not (out / name).exists()
        assert rows[name]["frames"] == "" and rows[name]["frechet_m"] == ""
    for name in ("good", "session/also good"):
        assert complete(out / name) and rows[name]["error"] == "" and rows[name]["frames"] == "47"
        assert float(rows[name]["frechet_m"]) > 0 and rows[name]["depth"] == "world"
    # one line each on stderr, naming the file; the summary on stdout
    lines = errors(proc.stderr)
    assert len(lines) == 2 and "Traceback" not in proc.stderr
    assert sorted(lines) == sorted(f"nlo-lab: error: {rows[n]['error']}" for n in ("nan", "session/broken"))
    assert proc.stdout.strip() == f"batch: 2 ok, 0 skipped, 2 failed of 4 inputs in {proc.stdout.split(' in ')[1].split(' s;')[0]} s; " \
                                  f"wrote {out}/results.csv"
    assert no_temporary_folders(out)
    # each folder holds what `nlo-lab retarget --out` writes for the same input and flags
    single = subprocess.run([sys.executable, "-m", "nlo_lab.cli", "retarget", str(corpus / "good.pose"), "--robot", "nao",
                             "--iters", "2", "--out", str(tmp_path / "single")], capture_output=True, text=True, timeout=600)
    assert single.returncode == 0, single.stderr
    assert (out / "good" / "trajectory.csv").read_bytes() == (tmp_path / "single" / "trajectory.csv").read_bytes()
    with np.load(out / "good" / "trajectory.npz") as a, np.load(tmp_path / "single" / "trajectory.npz") as b:
        assert sorted(a.files) == sorted(b.files) and all(np.array_equal(a[k], b[k]) for k in a.files)

    # again: nothing runs (no cluster, not even torch imported); a failure on unchanged content keeps its row
    code = ("import sys; from nlo_lab.cli import main; status = main(sys.argv[1:]); "
            "print('torch imported' if 'torch' in sys.modules or 'distributed' in sys.modules else 'neither'); sys.exit(status)")
    again = subprocess.run([sys.executable, "-c", code, "batch", str(corpus), "--robot", "nao", "--out", str(out), "--iters", "2",
                            "--quiet"], capture_output=True, text=True)
    assert again.returncode == 1 and len(errors(again.stderr)) == 2
    assert again.stdout.splitlines()[-1] == "neither"
    assert {k: r["status"] for k, r in table(out).items()} == {"good": "skipped", "nan": "failed", "session/also good": "skipped",
                                                               "session/broken": "failed"}
    assert again.stdout.startswith("batch: 0 ok, 2 skipped, 2 failed of 4 inputs")
    # the broken files removed: every input ok or skipped, exit 0
    (corpus / "nan.npz").unlink()
    (corpus / "session" / "broken.pose").unlink()
    assert batch(corpus, "--robot", "nao", "--out", out, "--iters", 2, "--quiet").returncode == 0


def test_a_manifest_with_relative_paths(tmp_path):
    (tmp_path / "data" / "a").mkdir(parents=True)
    shutil.copy(POSE, tmp_path / "data" / "a" / "one.pose")
    (tmp_path / "lists").mkdir()
    (tmp_path / "lists" / "corpus.txt").write_text("# my corpus\n../data/a/one.pose\n../data/missing.pose\n")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    proc = batch("../lists/corpus.txt", "--robot", "nao", "--out", "../out", "--iters", 2, "--workers", 1, "--viewer", cwd=elsewhere)
    assert proc.returncode == 1, proc.stderr
    rows = table(tmp_path / "out")
    assert {k: r["status"] for k, r in rows.items()} == {"a/one": "ok", "missing": "failed"}
    assert rows["missing"]["error"] == f"file not found: {Path('..') / 'lists' / '..' / 'data' / 'missing.pose'}"
    folder = tmp_path / "out" / "a" / "one"
    assert sorted(os.listdir(folder)) == ["summary.json", "trajectory.csv", "trajectory.npz", "viewer.html"]  # --viewer
    assert "<html" in (folder / "viewer.html").read_text(encoding="utf-8")[:2000].lower()
    # not --quiet, into a pipe (a log): the failure's line, then the progress as plain lines (done, failed, rate)
    lines = proc.stderr.splitlines()
    assert lines[0] == f"nlo-lab: error: {rows['missing']['error']}" and "Traceback" not in proc.stderr
    assert lines[1] == "nlo-lab: batch: 1 inputs to run, 1 settled without running"
    assert re.fullmatch(r"nlo-lab: batch: 1/1 done, 0 failed, \d+\.\d\d inputs/s in \d+ s", lines[-1]), lines


def test_a_scheduler_address_where_nothing_listens(tmp_path):
    with socket.socket() as s:  # a free port: bound, then closed, so nothing listens there
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    shutil.copy(POSE, tmp_path / "a.pose")
    start = time.monotonic()
    proc = batch(tmp_path / "a.pose", "--robot", "nao", "--out", tmp_path / "out", "--scheduler", f"tcp://127.0.0.1:{port}")
    assert_one_line_error(proc, f"no dask scheduler at tcp://127.0.0.1:{port}", "refused")
    assert time.monotonic() - start < 30  # at once, not after dask's connect timeout
    assert_one_line_error(batch(tmp_path / "a.pose", "--robot", "nao", "--out", tmp_path / "out", "--scheduler", "tcp://nowhere"),
                          "expected tcp://HOST:PORT")


def test_a_scheduler_address_where_something_else_listens(tmp_path):
    shutil.copy(POSE, tmp_path / "a.pose")
    with socket.socket() as server:  # accepts, then says nothing (dask's own client would wait for ever)
        server.bind(("127.0.0.1", 0))
        server.listen()
        address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
        start = time.monotonic()
        proc = batch(tmp_path / "a.pose", "--robot", "nao", "--out", tmp_path / "out", "--scheduler", address, timeout=120)
    assert_one_line_error(proc, f"{address} does not answer as a dask scheduler", "is it the address `dask scheduler` printed?")
    assert time.monotonic() - start < 60


@pytest.mark.parametrize("args, needle", [
    (["{corpus}", "--robot", "nao", "--out", "{out}", "--scheduler", "tcp://127.0.0.1:1", "--workers", "2"], "--workers sizes the local"),
    (["{corpus}", "--robot", "nao", "--out", "{out}", "--weights", "ee=1e9"], "weight ee=1000000000.0 must be in [0, 1e+06]"),
    (["{corpus}", "--robot", "nao", "--out", "{out}", "--weights", "ee"], "--weights: expected KEY=VALUE"),
    (["{corpus}/nope.pose", "--robot", "nao", "--out", "{out}"], "input not found"),
    (["{corpus}/empty", "--robot", "nao", "--out", "{out}"], "no inputs in folder"),
    (["{corpus}", "--robot", "nao", "--out", "{corpus}/a.pose"], "exists and is not a folder"),
    (["{corpus}", "--robot", "nao", "--out", "{out}", "--workers", "0"], "--workers: must be in [1, 1024]"),
    (["{corpus}", "--robot", "nao"], "the following arguments are required: --out"),
    (["{corpus}", "--robot", "nao", "--out", "{out}", "--hand-search", "ring,toe"], "unknown fingers ['toe']"),
    (["{corpus}", "--robot", "nao", "--out", "{out}", "--hand-search", "pinky,pinky"], "pinky named more than once"),
    (["{corpus}", "--robot", "nobody", "--out", "{out}", "--workers", "1"], "unknown robot 'nobody'"),
    (["{corpus}", "--robot", "nao", "--out", "{out}", "--handshape", "--workers", "1"],
     "--handshape: nao has no finger joints for the hand stage to search"),
    (["{corpus}", "--robot", "nao", "--out", "{out}", "--hand-search", "ring", "--workers", "1"],
     "--hand-search: nao has no finger joints for the hand stage to search"),
    (["{corpus}", "--robot", "nao", "--out", "{out}", "--hand-slowdown", "2", "--workers", "1"],
     "--hand-slowdown: nao has no hand joints for the hand stage to move"),
    (["{corpus}", "--robot", "nao", "--out", "{out}", "--hand-slowdown", "0.5"], "--hand-slowdown: must be in [1, 10]"),
])
def test_usage_errors_are_one_line_and_exit_2(tmp_path, args, needle):
    corpus = tmp_path / "corpus"
    (corpus / "empty").mkdir(parents=True)
    shutil.copy(POSE, corpus / "a.pose")
    proc = batch(*(a.format(corpus=corpus, out=tmp_path / "out") for a in args))
    assert_one_line_error(proc, needle)
    assert not (tmp_path / "out" / "a").exists()
    assert not (tmp_path / "out" / "results.csv").exists()  # refused before any input was decided: no table at all


def _children(pid: int) -> list[int]:
    try:
        return [p.pid for p in psutil.Process(pid).children(recursive=True)]
    except psutil.Error:
        return []


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["SIGTERM", "SIGKILL"])
def test_resume_after_an_interrupted_run(tmp_path, sig):
    corpus, out = tmp_path / "corpus", tmp_path / "out"
    corpus.mkdir()
    for i in range(6):
        shutil.copy(POSE, corpus / f"take_{i}.pose")
    cmd = [sys.executable, "-m", "nlo_lab.cli", "batch", str(corpus), "--robot", "yumi", "--out", str(out), "--workers", "1",
           "--iters", "100"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and not ((out / "results.csv").is_file() and table(out)):
        time.sleep(0.2)
    children = _children(proc.pid)
    assert children and proc.poll() is None, "the run ended before it could be interrupted"
    proc.send_signal(sig)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == (128 + sig if sig == signal.SIGTERM else -sig), stderr
    if sig == signal.SIGTERM:  # a handled signal: the folders being written finished or dropped, the table written
        assert stderr.splitlines()[-1] == "nlo-lab: interrupted by SIGTERM"
    done = table(out)  # a true table: what it lists is complete (a killed run's table may lag behind its folders)
    assert 1 <= len(done) < 6 and all(r["status"] == "ok" for r in done.values())
    assert all(complete(out / name) for name in done)
    folders = [p for p in out.iterdir() if p.is_dir() and not p.name.startswith(".")]
    assert all(complete(f) for f in folders)  # whole folders or none (SIGKILL may leave a hidden temporary one)
    if sig == signal.SIGTERM:
        assert no_temporary_folders(out)
    deadline = time.monotonic() + 30  # the workers end with the run that started them, however it ended
    while time.monotonic() < deadline and [pid for pid in children if _alive(pid)]:
        time.sleep(0.5)
    assert not [pid for pid in children if _alive(pid)]

    resumed = batch(corpus, "--robot", "yumi", "--out", out, "--workers", "1", "--iters", 100, "--quiet")
    assert resumed.returncode == 0, resumed.stderr
    rows = table(out)
    assert len(rows) == 6 and all(complete(out / name) for name in rows)
    assert all(int(r["hand_frames"]) > 0 and float(r["wrist_tip_deg"]) > 0 for r in rows.values())  # YuMi's hands scored
    skipped = {name for name, r in rows.items() if r["status"] == "skipped"}
    assert set(done) <= skipped and {r["status"] for n, r in rows.items() if n not in skipped} == {"ok"}
    assert no_temporary_folders(out)  # what the killed run left half-written is gone


def _alive(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.Error:
        return False

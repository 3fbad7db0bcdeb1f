"""``nlo-lab batch --scheduler``: a cluster the user started, used as it is; a video's pose estimation in segments.

The "user's cluster" is a LocalCluster this test starts (two worker processes on the loopback), reached
by its address only, as ``dask scheduler`` + ``dask worker`` would be (benchmarks/batch.py runs those very
commands, with a ``kill -9``).
"""

from __future__ import annotations

import csv
import logging
import shutil
import subprocess
import sys

import pytest

from nlo_lab.paths import RECORDINGS_DIR

pytest.importorskip("mediapipe", reason="the video extra (mediapipe) is not installed")
distributed = pytest.importorskip("distributed", reason="the batch extra (dask.distributed) is not installed")

VIDEO = RECORDINGS_DIR / "signer_webcam_58f.mp4"
POSE = RECORDINGS_DIR / "holistic_both_hands_47f.pose"


@pytest.mark.slow
def test_a_cluster_given_by_address_runs_a_video_in_segments_and_is_left_as_it_was(tmp_path):
    corpus, out = tmp_path / "corpus", tmp_path / "out"
    corpus.mkdir()
    shutil.copy(VIDEO, corpus / "signer.mp4")
    shutil.copy(POSE, corpus / "both_hands.pose")
    data = VIDEO.read_bytes()
    (corpus / "cut.mp4").write_bytes(data[: len(data) // 2])  # its header still announces 58 frames

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None,
                                  silence_logs=logging.ERROR) as cluster, distributed.Client(cluster) as client:
        workers = sorted(client.scheduler_info()["workers"])
        with distributed.get_task_stream(client) as stream:
            proc = subprocess.run([sys.executable, "-m", "nlo_lab.cli", "batch", str(corpus), "--robot", "nao", "--out", str(out),
                                   "--iters", "3", "--scheduler", cluster.scheduler_address, "--quiet"],
                                  capture_output=True, text=True, timeout=900)

        # the user's cluster: not shut down, not resized, still serving
        assert sorted(client.scheduler_info()["workers"]) == workers and cluster.status.name == "running"
        assert client.submit(pow, 2, 10, pure=False).result(timeout=60) == 1024

    assert proc.returncode == 1, proc.stderr  # the cut video failed
    with open(out / "results.csv", newline="") as fh:
        rows = {row["output"]: row for row in csv.DictReader(fh)}
    assert {k: r["status"] for k, r in rows.items()} == {"both_hands": "ok", "cut": "failed", "signer": "ok"}
    assert rows["signer"]["frames"] == "58" and float(rows["signer"]["pose_seconds"]) > 0
    assert sorted((out / "signer").iterdir()) == [out / "signer" / n for n in ("summary.json", "trajectory.csv", "trajectory.npz")]
    error = rows["cut"]["error"]
    assert str(corpus / "cut.mp4") in error and "truncated or damaged video" in error and "\n" not in error
    assert [line for line in proc.stderr.splitlines() if line.startswith("nlo-lab: error: ")] == [f"nlo-lab: error: {error}"]

    # each video's pose estimation ran as one task per 30-frame segment (any worker may take each)
    segments = sorted(t["key"].split("-", 4)[4] for t in stream.data if str(t["key"]).startswith("nlo-lab-segment-"))
    assert sorted(s.split("-", 1)[1] for s in segments) == ["0-cut", "0-signer", "30-cut", "30-signer"], segments
    ran_on = {t["worker"] for t in stream.data if str(t["key"]).startswith("nlo-lab-")}
    assert ran_on <= set(workers)

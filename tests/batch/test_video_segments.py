"""A video's pose estimation cut into ranges estimated apart (as ``nlo-lab batch`` spreads them over workers):
the same landmarks, frame for frame, as the whole video read in one go; damaged videos named."""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest

pytest.importorskip("mediapipe", reason="the video extra (mediapipe) is not installed")
pytest.importorskip("cv2", reason="the video extra (opencv) is not installed")

from nlo_lab.errors import DemonstrationError  # noqa: E402
from nlo_lab.human import estimate_pose  # noqa: E402
from nlo_lab.human.readers.video import SEGMENT_FRAMES, estimate_segment, join_segments, segment_bounds  # noqa: E402
from nlo_lab.paths import RECORDINGS_DIR  # noqa: E402

SAMPLE = RECORDINGS_DIR / "signer_webcam_58f.mp4"


@pytest.mark.slow
def test_ranges_estimated_apart_join_to_the_landmarks_of_the_whole_video():
    assert SEGMENT_FRAMES == 30
    bounds = segment_bounds(SAMPLE)
    assert bounds == [(0, 30), (30, None)]  # the last range runs to the video's end
    parts = {a: estimate_segment(SAMPLE, a, b) for a, b in reversed(bounds)}  # any order, separate instances
    assert [len(parts[0]), len(parts[30])] == [30, 28]
    joined = join_segments(SAMPLE, [parts[a] for a, _ in bounds])
    whole = estimate_pose(SAMPLE, threads=1)
    assert len(joined) == len(whole) == 58
    for name in ("data", "mask"):
        np.testing.assert_array_equal(np.ma.getmaskarray(joined.pose.body.data) if name == "mask" else joined.pose.body.data.data,
                                      np.ma.getmaskarray(whole.pose.body.data) if name == "mask" else whole.pose.body.data.data)
    np.testing.assert_array_equal(joined.pose.body.confidence, whole.pose.body.confidence)
    assert joined.seconds == pytest.approx(parts[0].seconds + parts[30].seconds)
    assert joined.to_bytes() == whole.to_bytes()  # the same .pose file, so the same demonstration

    with pytest.raises(DemonstrationError, match="ranges do not join: frame 30 expected, got 0"):
        join_segments(SAMPLE, [parts[0], parts[0]])
    with pytest.raises(DemonstrationError, match="no frame decodes"):
        join_segments(SAMPLE, [])


def test_a_truncated_video_fails_in_the_range_that_misses_frames(tmp_path):
    data = SAMPLE.read_bytes()
    cut = tmp_path / "truncated.mp4"
    cut.write_bytes(data[: len(data) // 2])
    assert segment_bounds(cut) == [(0, 30), (30, None)]  # the header still announces 58 frames
    with pytest.raises(DemonstrationError, match=r"truncated or damaged video: \d+ of the 58 frames its header announces decode"):
        for a, b in segment_bounds(cut):
            estimate_segment(cut, a, b)
    not_a_video = tmp_path / "x.mp4"
    not_a_video.write_bytes(b"hello")
    with pytest.raises(DemonstrationError, match="not a video"):
        segment_bounds(not_a_video)


def _threads_at_work(run) -> tuple[list[float], object]:
    """CPU seconds of each thread that ``run()`` started and that worked (at least a quarter of the CPU the new
    threads took), sampled every 5 ms while it runs; and run's value."""
    psutil = pytest.importorskip("psutil")
    me = psutil.Process()
    before = {t.id for t in me.threads()}
    seen: dict[int, float] = {}
    done = threading.Event()

    def watch():
        while not done.is_set():
            seen.update((t.id, t.user_time + t.system_time) for t in me.threads() if t.id not in before)
            time.sleep(0.005)

    watcher = threading.Thread(target=watch)
    watcher.start()
    try:
        value = run()
    finally:
        done.set()
        watcher.join()
    seen.pop(watcher.native_id, None)
    total = sum(seen.values())
    return sorted(c for c in seen.values() if c >= total / 4), value


@pytest.mark.slow
def test_each_holistic_instance_runs_on_one_thread_with_the_landmarks_of_mediapipes_default(monkeypatch):
    """MediaPipe would run a Holistic graph on min(cores, nodes) threads (two here); a segment estimated apart
    (a batch worker's) asks for one (holistic_loader): one thread does its work, and the landmarks are those of
    MediaPipe's own pool."""
    from pose_format.utils import holistic

    estimate_segment(SAMPLE, 0, 30)  # loads the models, imports everything
    workers, ours = _threads_at_work(lambda: estimate_segment(SAMPLE, 0, 30))
    assert len(workers) == 1, f"CPU seconds of the threads at work: {workers}"

    monkeypatch.setattr(holistic, "mp_holistic", holistic.mp_holistic._module)  # MediaPipe's Holistic as it is
    monkeypatch.setattr("nlo_lab.human.readers.video.holistic_loader", lambda path: holistic.load_holistic)
    monkeypatch.setattr("nlo_lab.human.readers.video.holistic_config", lambda graph_threads: {"model_complexity": 1})
    pooled, theirs = _threads_at_work(lambda: estimate_segment(SAMPLE, 0, 30))
    if (os.cpu_count() or 1) > 1:
        assert len(pooled) > 1, f"MediaPipe's default pool: {pooled}"  # what the test guards against
    np.testing.assert_array_equal(ours.pose.body.data.data, theirs.pose.body.data.data)
    np.testing.assert_array_equal(np.ma.getmaskarray(ours.pose.body.data), np.ma.getmaskarray(theirs.pose.body.data))
    np.testing.assert_array_equal(ours.pose.body.confidence, theirs.pose.body.confidence)


@pytest.mark.slow
def test_the_instances_share_the_cores_allowed(monkeypatch):
    """estimate_pose gives each Holistic instance the cores allowed over the instances: one each when there are
    as many segments as cores, more when there are fewer segments; ``threads=1``: one."""
    import nlo_lab.human.readers.video as video

    asked = []
    real = video._holistic

    def recording(load_holistic, segment, info, graph_threads=1):
        asked.append(graph_threads)
        return real(load_holistic, segment, info, graph_threads)

    monkeypatch.setattr(video, "_holistic", recording)
    monkeypatch.setattr(video, "_available_cores", lambda: 4)
    monkeypatch.delenv("NLO_LAB_THREADS", raising=False)
    for threads, expected in ((None, [2, 2]), (1, [1, 1]), (3, [1, 1])):  # the sample: 2 segments
        asked.clear()
        video.estimate_pose(SAMPLE, threads=threads)
        assert asked == expected, (threads, asked)

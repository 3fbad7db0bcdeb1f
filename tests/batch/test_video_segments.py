"""A video's pose estimation cut into ranges estimated apart (as ``nlo-lab batch`` spreads them over workers):
the same landmarks, frame for frame, as the whole video read in one go; damaged videos named."""

from __future__ import annotations

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

"""Videos: video -> MediaPipe Holistic (pose-format) -> Demonstration -> robot; bad input; the command line.

Pose estimation costs about 0.1 s a frame here, so the sample runs once per module and the
other cases use clips of a few frames cut from it.
"""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.slow  # MediaPipe's pose estimation: about 0.1 s a frame
pytest.importorskip("mediapipe", reason="the video extra (mediapipe) is not installed")
cv2 = pytest.importorskip("cv2", reason="the video extra (opencv) is not installed")


from nlo_lab.cli import main  # noqa: E402
from nlo_lab.errors import DemonstrationError, SettingsError  # noqa: E402
from nlo_lab.human import load_demonstration  # noqa: E402
from nlo_lab.human.readers.video import (  # noqa: E402
    VIDEO_SUFFIXES,
    VideoWarning,
    estimate_pose,
    load_video,
    pose_to_demonstration,
    pose_workers,
    read_video_frames,
    video_info,
)
from nlo_lab.paths import ASSETS  # noqa: E402

SAMPLE = ASSETS / "recordings" / "signer_webcam_58f.mp4"
SAMPLE_FRAMES = 58
NO_HANDS_FRAMES = 12  # MediaPipe sees no hand in the sample's first 13 frames (the right hand appears at 13)
FOURCC = {".mp4": "mp4v", ".mov": "mp4v", ".avi": "MJPG", ".webm": "VP80"}
ARRAYS = ("arm_positions", "arm_mask", "wrist_rotations", "wrist_mask", "finger_positions", "finger_mask")


def write_clip(path: Path, frames) -> Path:
    """Frames (BGR uint8) as a video in the container of ``path``'s extension."""
    h, w = frames[0].shape[:2]
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*FOURCC[path.suffix]), 25.0, (w, h))
    for f in frames:
        out.write(f)
    out.release()
    assert path.stat().st_size > 0, path
    return path


def sample_frames(n: int) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(SAMPLE))
    frames = [cap.read()[1] for _ in range(n)]
    cap.release()
    return frames


def same_demonstration(a, b) -> None:
    assert a.fps == pytest.approx(b.fps)
    for name in ARRAYS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    """The sample video read once, its landmarks kept as a ``.pose``."""
    pose_file = tmp_path_factory.mktemp("video") / "sample.pose"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        demo = load_video(SAMPLE, threads=1, save_pose=pose_file)
    return demo, pose_file, caught


# ----------------------------------------------------------------------------- the sample end to end
def test_sample_is_shipped_with_its_licence():
    assert SAMPLE.is_file()
    licence = (SAMPLE.parent / "LICENSE.txt").read_text()
    assert "MIT License" in licence and "Amit Moryossef" in licence
    info = video_info(SAMPLE)
    assert info["frames"] == SAMPLE_FRAMES and (info["width"], info["height"]) == (540, 720)


def test_sample_frames_in_equal_frames_out(sample):
    demo, _, _ = sample
    assert len(demo) == SAMPLE_FRAMES == len(read_video_frames(SAMPLE, max_side=64))
    assert demo.fps == pytest.approx(video_info(SAMPLE)["fps"], rel=1e-6)
    assert demo.meta["format"] == "video" and demo.meta["source"] == SAMPLE.name
    assert demo.meta["pose_seconds"] > 0 and demo.meta["pose_workers"] == 1
    assert demo.meta["arm_source"] == "POSE_WORLD_LANDMARKS"  # world landmarks on
    assert demo.arm_mask.all()  # MediaPipe places the whole body in every frame
    assert demo.finger_mask[:, 1].any()  # the right hand is seen ...
    assert not demo.finger_mask[:, 0].any()  # ... the left never: masked (NaN), never zeros
    assert np.isnan(demo.finger_positions[:, 0]).all()


def test_sample_warns_that_the_left_hand_is_never_seen(sample):
    _, _, caught = sample
    messages = [str(w.message) for w in caught if issubclass(w.category, VideoWarning)]
    assert messages == [f"{SAMPLE.name}: the left hand is never seen; its fingers and wrist orientation are masked"]


def test_saved_pose_reads_back_to_the_same_demonstration(sample):
    demo, pose_file, _ = sample
    again = load_demonstration(pose_file)
    same_demonstration(demo, again)
    assert again.meta["format"] == "pose"


def test_sample_retargets_feasibly(sample):
    from nlo_lab.inference import OptimizeSettings
    from nlo_lab.metrics import limit_violations, max_joint_step, self_collision_frames, velocity_violations
    from nlo_lab.pipeline import retarget
    from nlo_lab.robot import load_robot

    demo, _, _ = sample
    robot = load_robot("yumi")
    result = retarget(demo, robot, settings=OptimizeSettings(iterations=30))
    angles = result.trajectory.angles
    assert angles.shape == (SAMPLE_FRAMES, robot.n_joints) and np.isfinite(angles).all()
    assert limit_violations(robot, angles) == 0
    assert self_collision_frames(robot, angles) == 0
    # playable: every joint within its velocity limit on the file's own time base
    times = result.trajectory.time
    assert times is not None and times.shape == (SAMPLE_FRAMES,)
    assert velocity_violations(robot, angles, times) == 0
    assert result.summary["velocity_violations"] == 0
    assert max_joint_step(angles) <= 0.5
    assert result.summary["frames"] == SAMPLE_FRAMES
    assert result.summary["frechet_m"] < 0.15  # it follows the arms (0.06 m measured with 100 iterations)


# ----------------------------------------------------------------------------- containers and threads
@pytest.mark.parametrize("suffix", [s for s in VIDEO_SUFFIXES if s != ".mp4"])
def test_every_container_reads(tmp_path, suffix):
    clip = write_clip(tmp_path / f"clip{suffix}", sample_frames(4))
    with pytest.warns(VideoWarning, match="neither hand"):  # the first frames show no hand
        demo = load_demonstration(clip)
    assert len(demo) == 4 and demo.fps == pytest.approx(25.0)
    assert demo.name == "clip"


def test_pose_workers_never_more_than_asked_available_or_useful(monkeypatch):
    from nlo_lab.human.readers import video as pose_estimation

    monkeypatch.delenv("NLO_LAB_THREADS", raising=False)
    cores = len(os.sched_getaffinity(0))
    assert pose_workers() == cores  # the default: every core this process may use
    assert pose_workers(1) == 1
    assert pose_workers(64) == min(64, cores)
    monkeypatch.setattr(pose_estimation, "_available_cores", lambda: 8)
    assert pose_workers() == 8
    assert pose_workers(3) == 3  # never more than asked
    monkeypatch.setenv("NLO_LAB_THREADS", "2")
    assert pose_workers() == 2  # the environment asks too
    assert pose_workers(5) == 5  # an explicit argument wins over the environment
    monkeypatch.delenv("NLO_LAB_THREADS")
    assert pose_workers(frames=SAMPLE_FRAMES) == 2  # 58 frames are two segments: a third worker has nothing to do
    assert pose_workers(frames=pose_estimation.SEGMENT_FRAMES) == 1
    assert pose_workers(frames=5 * pose_estimation.SEGMENT_FRAMES + 1) == 6
    monkeypatch.setattr(pose_estimation, "_available_cores", lambda: 1)
    assert pose_workers(8) == 1  # never more than the cores available
    with pytest.raises(SettingsError, match="threads"):
        pose_workers(0)


def test_the_result_does_not_depend_on_the_number_of_workers(sample, monkeypatch):
    """Two workers (forced, even on one core) give the one-worker landmarks and demonstration, frame by frame."""
    from nlo_lab.human.readers import video as pose_estimation

    demo1, pose_file, _ = sample
    monkeypatch.setattr(pose_estimation, "_available_cores", lambda: 4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", VideoWarning)
        video = estimate_pose(SAMPLE, threads=4)
        demo2 = pose_to_demonstration(video)
    assert video.workers == 2  # capped by the sample's two segments
    assert video.to_bytes() == pose_file.read_bytes()  # the very .pose one worker wrote (the fixture), byte for byte
    same_demonstration(demo1, demo2)


def test_a_short_clip_gets_one_worker_and_every_frame(tmp_path):
    clip = write_clip(tmp_path / "clip.mp4", sample_frames(6))
    video = estimate_pose(clip, threads=2)
    assert len(video) == 6 and video.workers == 1  # one segment: a second worker would have nothing to do


def test_segment_frames_sets_where_tracking_restarts(sample, monkeypatch):
    """``segment_frames=`` (benchmarks/video.py's one-segment run): the sample as one segment is tracked from frame 0
    like the default cut up to the default's first restart, then keeps tracking where the default starts anew."""
    from pose_format import Pose

    from nlo_lab.human.readers import video as pose_estimation

    _, pose_file, _ = sample  # the default cut (segments of SEGMENT_FRAMES), one worker
    monkeypatch.setattr(pose_estimation, "_available_cores", lambda: 4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", VideoWarning)
        whole = estimate_pose(SAMPLE, threads=4, segment_frames=SAMPLE_FRAMES)
    assert whole.workers == 1 and len(whole) == SAMPLE_FRAMES  # one segment: one Holistic instance
    cut = pose_estimation.SEGMENT_FRAMES
    default = Pose.read(pose_file.read_bytes()).body
    ours = Pose.read(whole.to_bytes()).body  # as written to a .pose (float32), like the fixture's
    np.testing.assert_array_equal(ours.confidence[:cut], default.confidence[:cut])  # the same instance's history ...
    np.testing.assert_array_equal(np.ma.getdata(ours.data)[:cut], np.ma.getdata(default.data)[:cut])
    assert not np.array_equal(np.ma.getdata(ours.data)[cut:], np.ma.getdata(default.data)[cut:])  # ... until the default restarts
    for bad in (0, -3, 2.5, True, "30"):
        with pytest.raises(SettingsError, match="segment_frames"):
            estimate_pose(SAMPLE, segment_frames=bad)
    assert pose_workers(8, frames=SAMPLE_FRAMES, segment_frames=10) == 4  # 6 segments of 10, capped by the 4 cores
    assert pose_workers(8, frames=SAMPLE_FRAMES, segment_frames=SAMPLE_FRAMES) == 1


# ----------------------------------------------------------------------------- bad input
@pytest.fixture()
def bad_files(tmp_path):
    data = SAMPLE.read_bytes()
    files = {
        "truncated": (tmp_path / "truncated.mp4", data[: len(data) // 2], "truncated or damaged video: 23 of the 58"),
        "unreadable": (tmp_path / "cut_header.mp4", data[:1000], "unreadable or damaged video"),
        "not_a_video": (tmp_path / "notes.mp4", b"these are my notes, not a video\n" * 20, "not a video"),
        "empty": (tmp_path / "empty.webm", b"", "the file is empty"),
        "random": (tmp_path / "noise.avi", np.random.default_rng(0).bytes(5000), "not a video"),
    }
    for path, payload, _ in files.values():
        path.write_bytes(payload)
    return files


@pytest.mark.parametrize("case", ["truncated", "unreadable", "not_a_video", "empty", "random"])
def test_bad_video_is_one_clear_error(bad_files, case):
    path, _, needle = bad_files[case]
    with pytest.raises(DemonstrationError) as err:
        load_demonstration(path)
    assert needle in str(err.value) and str(path) in str(err.value)


def test_missing_video_names_the_file(tmp_path):
    with pytest.raises(DemonstrationError, match="no such file"):
        load_demonstration(tmp_path / "nothing.mov")


@pytest.fixture(scope="module")
def nobody(tmp_path_factory):
    """A video of an empty room: a gradient with noise, no person."""
    rng = np.random.default_rng(1)
    base = np.linspace(40, 200, 320, dtype=np.float64)[None, :, None] * np.ones((240, 1, 3))
    frames = [np.clip(base + rng.normal(0, 8, base.shape), 0, 255).astype(np.uint8) for _ in range(5)]
    return write_clip(tmp_path_factory.mktemp("nobody") / "empty_room.mp4", frames)


def test_no_person_is_an_error(nobody):
    with pytest.raises(DemonstrationError, match="no person found in any of the 5 frames"):
        load_demonstration(nobody)


@pytest.fixture(scope="module")
def no_hands(tmp_path_factory):
    return write_clip(tmp_path_factory.mktemp("nohands") / "no_hands.mp4", sample_frames(NO_HANDS_FRAMES))


def test_hands_never_seen_warn_and_mask_the_fingers(no_hands):
    with pytest.warns(VideoWarning, match="neither hand is seen in any frame"):
        demo = load_demonstration(no_hands)
    assert len(demo) == NO_HANDS_FRAMES
    assert not demo.finger_mask.any() and not demo.wrist_mask.any()
    assert np.isnan(demo.finger_positions).all()
    assert demo.arm_mask.all()


# ----------------------------------------------------------------------------- the command line
def test_cli_video_json_save_pose_and_warning(no_hands, tmp_path, capsys):
    pose_file, out_dir = tmp_path / "kept.pose", tmp_path / "out"
    code = main(["retarget", str(no_hands), "--robot", "nao", "--iters", "5", "--json", "--threads", "1",
                 "--save-pose", str(pose_file), "--out", str(out_dir)])
    out, err = capsys.readouterr()
    assert code == 0, err
    summary = json.loads(out)
    assert summary["frames"] == NO_HANDS_FRAMES and summary["pose_seconds"] > 0
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("nlo-lab: warning: "), err
    assert f"{no_hands.name}: neither hand is seen in any frame; the fingers and wrist orientations are masked" in lines[0]
    assert sorted(p.name for p in out_dir.iterdir()) == ["trajectory.csv", "trajectory.npz", "viewer.html"]
    with pytest.warns(VideoWarning):
        from_video = load_demonstration(no_hands)
    same_demonstration(from_video, load_demonstration(pose_file))


def test_cli_pose_input_has_no_pose_seconds(capsys):
    code = main(["retarget", "demo:introduction_06", "--robot", "nao", "--iters", "0", "--json"])
    out, _ = capsys.readouterr()
    assert code == 0 and "pose_seconds" not in json.loads(out)


@pytest.mark.parametrize("case", ["truncated", "unreadable", "not_a_video", "empty", "random"])
def test_cli_bad_video_exit_2_nothing_written(bad_files, case, tmp_path, capsys, assert_one_line_error):
    path, _, needle = bad_files[case]
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main(["retarget", str(path), "--robot", "nao", "--out", str(tmp_path / "o"),
                 "--save-pose", str(tmp_path / "kept.pose")])
    _, err = capsys.readouterr()
    assert_one_line_error(code, err, needle, path.name)
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_cli_no_person_exit_2_nothing_written(nobody, tmp_path, capsys, assert_one_line_error):
    code = main(["retarget", str(nobody), "--robot", "nao", "--out", str(tmp_path / "o"),
                 "--save-pose", str(tmp_path / "kept.pose")])
    _, err = capsys.readouterr()
    assert_one_line_error(code, err, "no person found", nobody.name)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv, needle", [
    (["demo:introduction_06", "--save-pose", "x.pose"], "needs a video"),
    ([str(SAMPLE), "--save-pose", "x.json"], "must end in .pose"),
    ([str(SAMPLE), "--save-pose", "no/such/folder/x.pose"], "does not exist"),
    ([str(SAMPLE), "--threads", "0"], "must be in [1, 256]"),
])
def test_cli_video_flags_checked_before_the_work(argv, needle, capsys, assert_one_line_error):
    code = main(["retarget", *argv, "--robot", "nao"])
    _, err = capsys.readouterr()
    assert_one_line_error(code, err, argv[1], needle)


def test_progress_bar_counts_the_frames(tmp_path, capsys):
    clip = write_clip(tmp_path / "clip.mp4", sample_frames(3))
    estimate_pose(clip, progress=True)
    err = capsys.readouterr().err
    assert "pose estimation clip.mp4" in err and "3/3" in err
    estimate_pose(clip, progress=False)
    assert capsys.readouterr().err == ""

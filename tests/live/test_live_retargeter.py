"""LiveRetargeter: always a frame, limits on every frame (a jump, nobody), easing to rest, warm starts, its checks."""

from __future__ import annotations

import numpy as np
import pytest

from nlo_lab.errors import SettingsError
from nlo_lab.metrics import limit_violations, velocity_violations

IMAGE = np.zeros((48, 64, 3), np.uint8)  # the replayed landmarks stand for what MediaPipe would find in it


def _run(live, n: int, times) -> list:
    return [live.step(IMAGE, t) for t in times[:n]]


def test_joint_names_are_the_robots_each_once(make_live, recorded):
    live = make_live(recorded[0])
    assert live.joint_names == tuple(live.robot.joint_names)
    assert len(set(live.joint_names)) == len(live.joint_names) == live.robot.n_joints
    frame = live.step(IMAGE, 0.0)
    assert frame.joint_names == live.joint_names and frame.angles.shape == (live.robot.n_joints,)
    assert np.array_equal(frame.angles, live.rest)  # the first output is the rest pose: no step from an unknown pose


def test_a_stream_with_a_jump_holds_the_limits_on_every_frame(make_live, recorded):
    frames, times = recorded
    # the person teleports: frames 0-14, then 40-46 (another pose at once), then 15-30 again
    order = list(range(15)) + list(range(40, 47)) + list(range(15, 31))
    live = make_live([frames[i] for i in order])
    t = np.cumsum(np.full(len(order), 1 / 25))
    out = [live.step(IMAGE, ti) for ti in t]
    q = np.stack([f.angles for f in out])
    assert all(f.found and f.state == "tracking" for f in out)
    assert limit_violations(live.robot, q) == 0
    assert velocity_violations(live.robot, q, t) == 0
    assert any(f.limited for f in out[15:18])  # the jump was limited, not followed at once
    targets = np.stack([f.target for f in out])
    assert velocity_violations(live.robot, targets, t) > 0  # the control: the optimiser's own angles break the limits


def test_nobody_holds_then_eases_to_rest(make_live, recorded, nobody):
    frames, _ = recorded
    live = make_live(frames[:20] + [nobody] * 60)
    t = np.arange(80) / 25.0
    out = [live.step(IMAGE, ti) for ti in t]
    states = [f.state for f in out]
    assert states[:20] == ["tracking"] * 20
    assert all(not f.found and f.demonstration is None and f.target is None for f in out[20:])
    assert states[20:27] == ["holding"] * 7 and set(states[28:]) == {"resting"}  # 0.3 s held at 25 fps, then resting
    assert np.array_equal(out[22].angles, out[21].angles) or out[19].limited  # held: the last target stays the goal
    gap = [np.abs(f.angles - live.rest).max() for f in out[27:]]
    assert gap[-1] < 0.05 * gap[0] and all(b <= a + 1e-12 for a, b in zip(gap, gap[1:], strict=False))  # eases, never away
    q = np.stack([f.angles for f in out])
    assert limit_violations(live.robot, q) == 0 and velocity_violations(live.robot, q, t) == 0


def test_warm_start_from_the_last_frame(make_live, recorded):
    frames, times = recorded
    live = make_live(frames)
    first = live.step(IMAGE, 0.0)
    warm = live.step(IMAGE, 0.04)
    cold = make_live(frames[1:]).step(IMAGE, 0.0)  # frame 1 from the encoder alone
    assert first.loss is not None and warm.loss is not None
    assert not np.allclose(warm.target, cold.target)  # a warm start is another start


def test_settings_act_on_the_next_frame(make_live, recorded):
    frames, _ = recorded
    live = make_live(frames)
    live.step(IMAGE, 0.0)
    live.set_weights(ee=0.0, elbow=0.0, ori=0.0, finger=0.0, tip=0.0, thumb=0.0, pinch=0.0)
    assert live.weights.ee == 0.0 and live.weights.collision == 1000.0
    live.set_filter(min_cutoff=5.0)
    assert live.filter.min_cutoff == 5.0
    live.set_iterations(5)
    assert live.step(IMAGE, 0.04).found


def test_bad_calls_are_clear_errors(make_live, recorded):
    live = make_live(recorded[0])
    for image, needle in ((np.zeros((4, 4)), "(H, W, 3) uint8"), (np.zeros((4, 4, 3)), "uint8"), ("frame", "uint8"),
                          (np.zeros((5000, 4, 3), np.uint8), "4096")):
        with pytest.raises(SettingsError, match=needle.replace("(", r"\(").replace(")", r"\)")):
            live.step(image, 0.0)
    live.step(IMAGE, 1.0)
    for t, needle in ((1.0, "time order"), (0.5, "time order"), (float("nan"), "finite"), ("soon", "seconds")):
        with pytest.raises(SettingsError, match=needle):
            live.step(IMAGE, t)
    with pytest.raises(SettingsError, match="iterations"):
        type(live)(live.robot, iterations=0)


@pytest.mark.slow
def test_mediapipe_on_the_sample_video_and_a_frame_with_nobody(listening_sockets):
    pytest.importorskip("mediapipe", reason="the video extra (mediapipe) is not installed")
    before = listening_sockets()
    from pathlib import Path

    from nlo_lab.human import read_video_frames
    from nlo_lab.live import LiveRetargeter

    video = Path(__file__).resolve().parents[2] / "assets" / "recordings" / "signer_webcam_58f.mp4"
    images = read_video_frames(video, max_side=480)
    with LiveRetargeter("yumi", iterations=10) as live:
        out = [live.step(img, i / 30) for i, img in enumerate(images[:24])]
        assert all(f.found for f in out[2:]), [f.found for f in out]
        assert out[-1].timings["mediapipe"] > 0 and set(out[-1].timings) == {"mediapipe", "filter", "optimization"}
        assert out[-1].landmarks.world.shape == (33, 3) and any("right" in f.landmarks.hands for f in out)
        blank = np.full_like(images[0], 128)
        empty = [live.step(blank, 1.0 + i / 30) for i in range(15)]
        assert not any(f.found for f in empty) and empty[-1].state == "resting"
        q = np.stack([f.angles for f in out + empty])
        t = np.array([f.t for f in out + empty])
        assert limit_violations(live.robot, q) == 0 and velocity_violations(live.robot, q, t) == 0
        assert listening_sockets() == before  # MediaPipe and the optimiser open no port

"""CameraView in the kernel (no browser): every frame answered once, a malformed one said and the stream goes on,
a frame with nobody, a slow kernel drops frames, recording only when asked, read-only figures."""

from __future__ import annotations

import time

import numpy as np
import pytest
import traitlets

from nlo_lab.errors import SettingsError
from nlo_lab.live import CameraView, encode_frame
from nlo_lab.metrics import limit_violations, velocity_violations

IMAGE = np.zeros((48, 64, 3), np.uint8)


@pytest.fixture
def view(make_live, recorded, monkeypatch):
    """A YuMi camera view whose landmarks are the shipped recording's (replayed), recording what it sends the page."""
    camera = CameraView(make_live(recorded[0] * 3))
    camera.answers = []
    monkeypatch.setattr(camera, "send", lambda content, buffers=None: camera.answers.append(content))
    return camera


def _frame(view, seq: int, t: float, data: bytes | None = None):
    view._on_page_message(view, {"type": "frame", "seq": seq, "t": t}, [data if data is not None else encode_frame(IMAGE, 480, 0.8)])


def test_frames_flow_and_the_robot_moves(view):
    before = view.scene.messages_sent
    for i in range(1, 11):
        _frame(view, i, 10.0 + i / 25)
    assert (view.frames_received, view.frames_processed, view.frames_rejected, view.error) == (10, 10, 0, "")
    assert [a["seq"] for a in view.answers] == list(range(1, 11)) and all(a["type"] == "done" for a in view.answers)
    assert view.found and view.last_frame.state == "tracking" and len(view.answers[-1]["points"]) >= 6
    assert view.scene.messages_sent - before == 9  # one view update per frame (the first is the rest pose it shows already)
    assert view.fps > 0 and view.latency_ms > 0 and set(view.latency_split) == {"decode", "mediapipe", "filter", "optimization", "view"}
    assert not np.allclose(view.last_frame.angles, view.retargeter.rest)


def test_a_malformed_frame_is_one_clear_error_and_the_stream_goes_on(view):
    _frame(view, 1, 1.00)
    _frame(view, 2, 1.04, data=b"GIF89a not a jpeg")
    view._on_page_message(view, {"type": "frame", "seq": 3, "t": "later"}, [b""])
    _frame(view, 4, 1.12)
    assert (view.frames_received, view.frames_processed, view.frames_rejected) == (4, 2, 2)
    assert [bool(a.get("error")) for a in view.answers] == [False, True, True, False]  # every message answered once
    assert view.error == "frame 3 from the page: t must be a finite time in seconds, got 'later'"
    assert view.answers[1]["error"].startswith("frame 2 from the page: not a JPEG image")
    assert "\n" not in view.error


def test_a_frame_with_nobody(view, make_live, nobody, monkeypatch):
    empty = CameraView(make_live([nobody]))
    monkeypatch.setattr(empty, "send", lambda content, buffers=None: None)
    for i in range(20):
        _frame(empty, i + 1, i / 25)
    assert empty.frames_processed == 20 and not empty.found and empty.error == ""
    assert empty.last_frame.state == "resting" and np.array_equal(empty.last_frame.angles, empty.retargeter.rest)


def test_a_new_camera_session_continues_the_stream_clock(view):
    _frame(view, 1, 500.0)
    _frame(view, 2, 500.04)
    view._on_page_message(view, {"type": "started"}, [])
    _frame(view, 1, 3.0)  # a reloaded page: its clock starts again
    assert view.frames_processed == 3 and view.error == ""
    times = [row["t"] for row in view.history]
    assert times[2] > times[1] and np.isclose(times[1] - times[0], 0.04)


def test_a_slow_kernel_drops_frames_it_never_queues(view):
    """A camera at 30 fps and a kernel that takes 0.1 s a frame: in real time, the stream keeps the present and drops
    the rest (what the page does: one frame in flight)."""
    step = view.retargeter.step

    def slow(image, t):
        time.sleep(0.1)
        return step(image, t)

    view.retargeter.step = slow
    images = np.zeros((45, 48, 64, 3), np.uint8)
    result = view.play_video((images, np.arange(45) / 30.0), realtime=True)
    assert result["processed"] + result["dropped"] == 45
    assert result["dropped"] > 20 and result["processed"] <= 17, result  # 1.5 s at 0.1 s a frame: about 15 processed
    t = np.array([row["t"] for row in view.history])
    assert np.median(np.diff(t)) > 0.09  # the frames retargeted are the camera's newest when the kernel was free


def test_the_limits_hold_across_the_whole_stream(view):
    rows = []
    for i in range(1, 40):
        _frame(view, i, i / 25)
        rows.append(view.last_frame)
    q, t = np.stack([f.angles for f in rows]), np.array([f.t for f in rows])
    assert limit_violations(view.retargeter.robot, q) == 0 and velocity_violations(view.retargeter.robot, q, t) == 0


def test_recording_only_when_asked(view, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _frame(view, 1, 1.0)
    with pytest.raises(SettingsError, match="call record"):
        view.stop()
    view.record(tmp_path / "session", name="me")
    assert view.recording
    for i in range(2, 12):
        _frame(view, i, 1.0 + i / 25)
    rec = view.stop()
    assert not view.recording and len(rec) == 10
    assert sorted(p.name for p in (tmp_path / "session").iterdir()) == ["me.csv", "me.npz", "me.pose"]
    from nlo_lab.human import load_demonstration
    from nlo_lab.inference import RobotTrajectory

    demo = load_demonstration(tmp_path / "session" / "me.pose")  # the .pose reader of notebooks 08 and 09
    trajectory = RobotTrajectory.load(tmp_path / "session" / "me.npz")
    assert len(demo) == 10 and np.isclose(demo.fps, 25.0, rtol=1e-3)
    assert trajectory.robot == "yumi" and np.allclose(trajectory.angles, np.stack(rec.angles))
    assert np.allclose(trajectory.times, np.array(rec.times) - rec.times[0])
    # without a folder nothing is written: the recording is returned, in memory
    view.record()
    _frame(view, 20, 3.0)
    assert len(view.stop()) == 1
    view.record()
    with pytest.raises(SettingsError, match="nothing was recorded"):
        view.stop()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["session"]


def test_the_view_listens_on_no_port(make_live, recorded, listening_sockets, monkeypatch, tmp_path):
    before = listening_sockets()
    view = CameraView(make_live(recorded[0]))
    monkeypatch.setattr(view, "send", lambda content, buffers=None: None)
    view.record(tmp_path)
    for i in range(1, 6):
        _frame(view, i, 1.0 + i / 25)
    view.stop()
    assert view.frames_processed == 5 and listening_sockets() == before  # frames come over the comm: no server, no port


def test_the_figures_are_read_only(view):
    for name in ("frames_received", "frames_processed", "fps", "latency_ms", "found", "error"):
        with pytest.raises(traitlets.TraitError, match="read-only"):
            setattr(view, name, getattr(view, name))


def test_bad_settings(make_live, recorded):
    live = make_live(recorded[0])
    for kwargs, needle in (({"frame_size": 50}, "frame_size"), ({"jpeg_quality": 1.5}, "jpeg_quality"),
                           ({"iterations": 5}, "this one is given")):
        with pytest.raises(SettingsError, match=needle):
            CameraView(live, **kwargs)


def test_the_sliders_act_on_the_running_stream(view):
    from nlo_lab.live import LiveControls

    controls = LiveControls(view.retargeter)
    _frame(view, 1, 1.0)
    controls.sliders["ee"].value = controls.sliders["ee"].min  # the left end: the term off
    controls.sliders["tip"].value = 10.0
    controls.sliders["iterations"].value = 7
    controls.sliders["min_cutoff"].value = 5.0
    controls.sliders["beta"].value = 3.0
    live = view.retargeter
    assert (live.weights.ee, live.weights.tip, live.iterations) == (0.0, 10.0, 7)
    assert (live.filter.min_cutoff, live.filter.beta) == (5.0, 3.0)
    _frame(view, 2, 1.04)
    assert view.frames_processed == 2 and view.error == ""


def test_the_latency_plot_draws_the_split(view):
    import matplotlib

    matplotlib.use("Agg")
    from nlo_lab.live import plot_latency

    for i in range(1, 6):
        _frame(view, i, i / 25)
    fig = plot_latency(view.history)
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert {"decode", "mediapipe", "filter", "optimization", "view"} <= set(labels)
    assert len(fig.axes[0].patches) == 5 * 5

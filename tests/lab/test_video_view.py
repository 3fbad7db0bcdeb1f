"""nlo_lab.lab.video_view: video frames, skeleton and robot driven by one slider; the upload helper."""

from __future__ import annotations

import numpy as np
import pytest

from nlo_lab.corpus import sign_corpus
from nlo_lab.errors import NloLabError
from nlo_lab.lab import VideoView, jpeg_bytes, save_upload
from nlo_lab.robot import load_robot

T = 6


@pytest.fixture(scope="module")
def parts():
    demo = sign_corpus("test")[0].slice(0, T)
    robot = load_robot("nao")
    rng = np.random.default_rng(0)
    angles = robot.neutral_q.numpy()[None] + 0.1 * rng.standard_normal((T, robot.n_joints))
    frames = (np.arange(T, dtype=np.uint8)[:, None, None, None] * 40 + rng.integers(0, 20, (T, 24, 16, 3))).astype(np.uint8)
    return demo, robot, angles, frames


def test_one_slider_drives_video_and_scene(parts):
    demo, robot, angles, frames = parts
    view = VideoView(frames, robot, angles, demo, view="auto", fps=10)
    shown = []
    set_frame = view.scene.set_frame
    view.scene.set_frame = lambda t: (shown.append(t), set_frame(t))
    assert view.image.value == jpeg_bytes(frames[0]) and view.play.interval == 100
    view.frame = 4
    assert view.image.value == jpeg_bytes(frames[4]) and shown == [4] and view.play.value == 4
    view.play.value = 2  # the Play button moves the slider, which moves both
    assert view.frame == 2 and view.image.value == jpeg_bytes(frames[2]) and shown == [4, 2]
    assert view.time.value == "0.20 s"
    with pytest.raises(NloLabError, match="outside"):
        view.frame = T


def test_frames_must_match(parts):
    demo, robot, angles, frames = parts
    with pytest.raises(NloLabError, match="same number of frames"):
        VideoView(frames[:-1], robot, angles, demo, view=None)
    with pytest.raises(NloLabError, match="uint8"):
        VideoView(frames.astype(np.float32), robot, angles, demo, view=None)


def test_save_upload(tmp_path):
    assert save_upload((), tmp_path) is None
    value = ({"name": "../../me signing.MP4", "content": memoryview(b"\x00\x00\x00\x18ftypmp42 data")},)
    path = save_upload(value, tmp_path / "in")
    assert path == tmp_path / "in" / "me signing.MP4" and path.read_bytes().startswith(b"\x00\x00\x00\x18ftyp")
    with pytest.raises(NloLabError, match="not a video"):
        save_upload(({"name": "notes.txt", "content": b"x"},), tmp_path)

"""What the live tests share: a recorded stream of landmarks and a landmark finder that replays it."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

from nlo_lab.live import FrameLandmarks, LiveRetargeter, landmarks_from_pose

ROOT = Path(__file__).resolve().parents[2]
RECORDING = ROOT / "assets" / "recordings" / "holistic_both_hands_47f.pose"  # MediaPipe Holistic, world landmarks, both hands
VIDEO = ROOT / "assets" / "recordings" / "signer_webcam_58f.mp4"


@functools.cache
def _recorded():
    return landmarks_from_pose(RECORDING)


@pytest.fixture(scope="session")
def recorded() -> tuple[list[FrameLandmarks], np.ndarray]:
    """The shipped recording's frames of landmarks and their times (25 fps)."""
    return _recorded()


class ReplayTracker:
    """Stands in for MediaPipe: each ``process(image)`` returns the next of the given landmarks (the image is ignored)."""

    def __init__(self, frames: list[FrameLandmarks]):
        self.frames, self.calls = list(frames), 0

    def process(self, image) -> FrameLandmarks:
        frame = self.frames[min(self.calls, len(self.frames) - 1)]
        self.calls += 1
        return frame


@functools.cache
def _model():
    from nlo_lab.model import load_pretrained
    from nlo_lab.robot import load_robot

    robot = load_robot("yumi")
    return robot, load_pretrained(robot)


@pytest.fixture(scope="session")
def make_live():
    """``make_live(frames, **options)``: a YuMi :class:`LiveRetargeter` whose landmarks are ``frames``, replayed."""

    def make(frames, **options):
        robot, model = _model()
        return LiveRetargeter(robot, model=model, tracker=ReplayTracker(frames), **options)

    return make


@pytest.fixture(scope="session")
def nobody() -> FrameLandmarks:
    return FrameLandmarks(width=640, height=480)


def _listening() -> set[tuple[str, int]]:
    import psutil

    return {(c.laddr.ip, c.laddr.port) for c in psutil.Process().net_connections(kind="inet") if c.status == psutil.CONN_LISTEN}


@pytest.fixture
def listening_sockets():
    """``listening_sockets()``: the ``(ip, port)`` this process listens on (the live path must add none: issue 30)."""
    return _listening

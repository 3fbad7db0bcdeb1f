"""Reading a video's frames (OpenCV): the file checked, its container's announcements, its frames as RGB images.

Needs the ``video`` extra (``pip install "nlo_lab[video]"``, which brings opencv).
Faults end in :class:`~nlo_lab.errors.DemonstrationError` naming the file: missing or
empty file, contents that are not a video container, a video no decoder opens or no frame
of which decodes, a truncated video (fewer frames decode than its header announces).
"""

from __future__ import annotations

import contextlib
import importlib
import os
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nlo_lab.errors import DemonstrationError
from nlo_lab.files import open_input

__all__ = [
    "VIDEO_SUFFIXES",
    "MAX_VIDEO_BYTES",
    "VideoInfo",
    "VideoFrames",
    "video_extra",
    "container_kind",
    "check_video_file",
    "open_video",
    "video_info",
    "read_video_frames",
    "native_output_silenced",
]

VIDEO_SUFFIXES = (".mp4", ".mov", ".webm", ".avi")
MAX_VIDEO_BYTES = 32 << 30  # the file; frames are decoded one at a time, so memory does not grow with it


def video_extra(path: Path, module: str):
    """Import ``module`` of the ``video`` extra (``cv2``, pose-format's Holistic); its absence is a one-line error naming ``path``."""
    try:
        return importlib.import_module(module)
    except ImportError as err:
        raise DemonstrationError(
            f"reading videos needs the video extra: pip install \"nlo_lab[video]\" ({err})", path=path
        ) from None


def container_kind(head: bytes) -> str | None:
    """The container a file's first bytes announce (None: not a video we know)."""
    if len(head) >= 12 and head[4:8] in (b"ftyp", b"moov", b"mdat", b"free", b"wide", b"skip", b"pnot"):
        return "MP4/QuickTime"
    if head[:4] == b"\x1a\x45\xdf\xa3":
        return "WebM/Matroska"
    if head[:4] == b"RIFF" and head[8:12] == b"AVI ":
        return "AVI"
    return None


def check_video_file(path: Path) -> None:
    """Missing, empty or non-video files, before any decoder sees them."""
    with open_input(path, kind="video", max_bytes=MAX_VIDEO_BYTES, error=DemonstrationError) as f:
        head = f.read(16)
    if container_kind(head) is None:
        raise DemonstrationError(
            f"not a video: the contents are no MP4, QuickTime, WebM or AVI container despite the {path.suffix} extension",
            path=path,
        )


@dataclass(frozen=True)
class VideoInfo:
    """What a video's container announces, read without decoding it."""

    fps: float
    width: int
    height: int
    frames: int  # as the container's header announces it (0: unknown)


def video_info(path) -> dict:
    """Frame rate, size and announced frame count of a video, without decoding it.

    Returns:
        ``{"fps", "width", "height", "frames"}`` (``frames`` 0 when the container does not say).

    Raises:
        DemonstrationError: missing, empty, not a video, or a video no decoder opens.
    """
    info = open_video(Path(path))
    return {"fps": info.fps, "width": info.width, "height": info.height, "frames": info.frames}


def open_video(path: Path) -> VideoInfo:
    """Check the file (:func:`check_video_file`) and read its frame rate, size and frame count."""
    check_video_file(path)
    cv2 = video_extra(path, "cv2")
    with native_output_silenced():
        cap = cv2.VideoCapture(str(path))
        try:
            if not cap.isOpened():
                raise DemonstrationError("unreadable or damaged video: no decoder can open it", path=path)
            fps = float(cap.get(cv2.CAP_PROP_FPS))
            info = VideoInfo(fps, int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)),
                         max(0, int(cap.get(cv2.CAP_PROP_FRAME_COUNT))))
        finally:
            cap.release()
    if not (np.isfinite(fps) and 0 < fps <= 1000):
        raise DemonstrationError(f"the video's frame rate is not usable ({fps})", path=path, field="fps")
    return info


class VideoFrames:
    """Iterates a video's frames as RGB ``uint8`` arrays (what MediaPipe expects); counts them.

    ``first`` and ``count`` read a part: from frame ``first`` (a seek), at most ``count`` frames.
    """

    def __init__(self, path: Path, info: VideoInfo, max_side: int | None = None, first: int = 0, count: int | None = None):
        self.path, self.info, self.max_side = path, info, max_side
        self.first, self.limit = int(first), count
        self.count = 0

    def __iter__(self) -> Iterator[np.ndarray]:
        cv2 = video_extra(self.path, "cv2")
        cap = cv2.VideoCapture(str(self.path))
        try:
            if self.first and not (cap.set(cv2.CAP_PROP_POS_FRAMES, self.first)
                                   and int(cap.get(cv2.CAP_PROP_POS_FRAMES)) == self.first):
                raise DemonstrationError(f"cannot seek to frame {self.first} (a damaged or unusual container)", path=self.path)
            while self.limit is None or self.count < self.limit:
                ok, bgr = cap.read()
                if not ok or bgr is None:
                    return
                if self.max_side and max(bgr.shape[:2]) > self.max_side:
                    s = self.max_side / max(bgr.shape[:2])
                    bgr = cv2.resize(bgr, (max(1, round(bgr.shape[1] * s)), max(1, round(bgr.shape[0] * s))),
                                     interpolation=cv2.INTER_AREA)
                self.count += 1
                yield cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        finally:
            cap.release()

    def check_complete(self) -> None:
        """A video that decodes to no frame, or to fewer than its header announces, is damaged."""
        if self.count == 0 and self.first == 0:
            raise DemonstrationError("unreadable or damaged video: no frame decodes", path=self.path)
        expected = self.info.frames - self.first if self.limit is None else min(self.limit, self.info.frames - self.first)
        if self.info.frames and self.count < expected:
            decoded = self.first + self.count
            raise DemonstrationError(
                f"truncated or damaged video: {decoded} of the {self.info.frames} frames its header announces decode",
                path=self.path, frame=decoded,
            )


def read_video_frames(path, max_side: int | None = 360) -> np.ndarray:
    """All frames of a video as RGB images (for showing them beside the 3-D view).

    Args:
        path: the video file.
        max_side: shrink frames so that their longer side is at most this many pixels (None: full size).

    Returns:
        ``(T, H, W, 3)`` ``uint8``.

    Raises:
        DemonstrationError: as :func:`nlo_lab.human.io_video.load_video` for unreadable, non-video or truncated files.
    """
    path = Path(path)
    frames = VideoFrames(path, open_video(path), max_side)
    with native_output_silenced():
        images = list(frames)
    frames.check_complete()
    return np.stack(images)


@contextlib.contextmanager
def native_output_silenced():
    """Silence file descriptors 1 and 2 for the block.

    MediaPipe, TensorFlow Lite and FFmpeg log from C++ straight to the process's
    stdout/stderr ("INFO: Created TensorFlow Lite XNNPACK delegate", decoder
    complaints about a damaged file). The command line promises a clean stdout
    (the JSON summary) and one line on stderr for a fault, so their output goes to
    /dev/null while they run.
    """
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    saved = []
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
    except OSError:
        yield
        return
    try:
        for fd in (1, 2):
            try:
                saved.append((fd, os.dup(fd)))
                os.dup2(devnull, fd)
            except OSError:
                pass
        yield
    finally:
        for fd, copy in saved:
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)

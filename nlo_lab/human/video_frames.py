"""Reading a video's frames (OpenCV): the file checked, its container's announcements, its frames as RGB images.

Needs the ``video`` extra (``pip install "nlo_lab[video]"``, which brings opencv).
Faults end in :class:`~nlo_lab.errors.DemonstrationError` naming the file: missing or
empty file, contents that are not a video container, a video no decoder opens or no frame
of which decodes, a truncated video (fewer frames decode than its header announces).

Memory stays bounded whatever the file: the container's announced size and frame count are
checked before any frame is decoded (a side of at most :data:`MAX_VIDEO_SIDE` pixels, at
most :data:`MAX_VIDEO_PIXELS` pixels a frame, at most
:data:`~nlo_lab.human.demonstration.MAX_FRAMES` frames); a decoded frame of another size
than announced, or more frames than that, is an error; frames are decoded one at a time,
and :func:`read_video_frames` keeps at most :data:`MAX_SHOWN_BYTES` of them.
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
from nlo_lab.files import as_path, format_size, open_input
from nlo_lab.human.demonstration import MAX_FRAMES

__all__ = [
    "VIDEO_SUFFIXES",
    "MAX_VIDEO_BYTES",
    "MAX_VIDEO_SIDE",
    "MAX_VIDEO_PIXELS",
    "MAX_SHOWN_BYTES",
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
MAX_VIDEO_SIDE = 7680  # pixels: 8K UHD's width
MAX_VIDEO_PIXELS = 7680 * 4320  # a frame (8K UHD: 33 MP, 100 MB decoded)
MAX_SHOWN_BYTES = 1 << 30  # the frames read_video_frames keeps (RGB, shrunk to max_side)


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
    info = open_video(as_path(path))
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
    check_video_size(path, info)
    return info


def check_video_size(path: Path, info: VideoInfo) -> None:
    """The announced frame size and count within the limits (before any frame is decoded)."""
    w, h = info.width, info.height
    if w <= 0 or h <= 0:
        raise DemonstrationError(f"the container announces no usable frame size ({w}x{h})", path=path)
    if max(w, h) > MAX_VIDEO_SIDE or w * h > MAX_VIDEO_PIXELS:
        raise DemonstrationError(f"the container announces frames of {w}x{h} pixels, more than nlo_lab reads "
                                 f"(a side of at most {MAX_VIDEO_SIDE}, at most {MAX_VIDEO_PIXELS:,} pixels: 8K UHD)", path=path)
    if info.frames > MAX_FRAMES:
        raise DemonstrationError(f"the container announces {info.frames} frames, more than the {MAX_FRAMES} this nlo_lab reads",
                                 path=path)


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
            w, h = self.info.width, self.info.height
            while self.limit is None or self.count < self.limit:
                ok, bgr = cap.read()
                if not ok or bgr is None:
                    return
                if bgr.shape[:2] not in ((h, w), (w, h)):  # (w, h): a frame turned by the container's rotation
                    raise DemonstrationError(f"frame {self.first + self.count} decodes to {bgr.shape[1]}x{bgr.shape[0]} pixels, "
                                             f"not the {w}x{h} its container announces", path=self.path, frame=self.first + self.count)
                if self.first + self.count >= MAX_FRAMES:
                    raise DemonstrationError(f"more than the {MAX_FRAMES} frames this nlo_lab reads decode", path=self.path)
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
        DemonstrationError: as :func:`nlo_lab.human.io_video.load_video` for unreadable, non-video or truncated
            files; frames that would take more than :data:`MAX_SHOWN_BYTES` (checked from the container's
            announcement before decoding, and again while decoding).
    """
    path = as_path(path)
    info = open_video(path)
    scale = min(1.0, max_side / max(info.width, info.height)) if max_side else 1.0
    frame_bytes = max(1, round(info.width * scale)) * max(1, round(info.height * scale)) * 3
    if info.frames * frame_bytes > MAX_SHOWN_BYTES:
        raise DemonstrationError(f"{info.frames} frames of {format_size(frame_bytes)} would take more than the "
                                 f"{format_size(MAX_SHOWN_BYTES)} kept for showing them (a smaller max_side helps)", path=path)
    frames = VideoFrames(path, info, max_side)
    images, total = [], 0
    with native_output_silenced():
        for image in frames:
            total += image.nbytes
            if total > MAX_SHOWN_BYTES:
                raise DemonstrationError(f"its frames take more than the {format_size(MAX_SHOWN_BYTES)} kept for showing them "
                                         "(more frames decode than its container announces)", path=path)
            images.append(image)
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

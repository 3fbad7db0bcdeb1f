"""Reader of videos (``.mp4``, ``.mov``, ``.webm``, ``.avi``): MediaPipe Holistic through pose-format.

The pipeline is video -> MediaPipe Holistic (pose-format's
:func:`pose_format.utils.holistic.load_holistic`, which keeps the world landmarks as
the ``POSE_WORLD_LANDMARKS`` component) -> a ``.pose`` recording -> the ``.pose``
reader (:func:`nlo_lab.human.io_pose.load_pose`). So a video and the ``.pose`` saved
from it give the same :class:`Demonstration`, and every convention of the ``.pose``
reader (body frame, metres, gap filling, masks) applies.

Needs the ``video`` extra (``pip install "nlo_lab[video]"``: mediapipe 0.10.21, the
last release whose wheel bundles the Holistic models, and opencv, which comes with
it). Nothing is downloaded at run time: :data:`MODEL_COMPLEXITY` is the one pose
model the wheel carries.

Threads: the video is cut into segments of :data:`SEGMENT_FRAMES` consecutive frames,
and each segment goes to a fresh Holistic instance that tracks through it (MediaPipe
tracks a person from frame to frame and smooths the landmarks; each segment starts
that anew from a detection). ``workers`` instances run side by side, one segment each,
each keeping about one core busy. Because the cut does not depend on the number of
workers, the landmarks, and so the demonstration, are the same for any number of
workers, frame by frame, in the video's order. The number of workers
(:func:`pose_workers`) is the cores this process may use (``os.sched_getaffinity``,
else ``os.cpu_count()``), never more than asked for (``threads``, ``--threads N``, or
``NLO_LAB_THREADS``), nor more than the video has segments.

Faults end in :class:`~nlo_lab.errors.DemonstrationError` naming the file: missing
or empty file, contents that are not a video container, a video no frame of which
decodes, a truncated video (fewer frames decode than its header announces), no
person in any frame. Hands never seen are not an error: a :class:`VideoWarning`
says so and the fingers are masked.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from nlo_lab.errors import DemonstrationError
from nlo_lab.human.demonstration import Demonstration

__all__ = [
    "VIDEO_SUFFIXES",
    "MODEL_COMPLEXITY",
    "SEGMENT_FRAMES",
    "VideoWarning",
    "VideoPose",
    "pose_workers",
    "video_info",
    "read_video_frames",
    "estimate_pose",
    "pose_to_demonstration",
    "load_video",
]

VIDEO_SUFFIXES = (".mp4", ".mov", ".webm", ".avi")
# mediapipe 0.10.21 ships pose_landmark_full.tflite only: complexity 1. Complexity 0 (lite) and
# 2 (heavy) would be downloaded on first use, which library code must never do.
MODEL_COMPLEXITY = 1
# Frames per segment of the pose estimation (see the module docstring): long enough that
# tracking restarts rarely (once a second at 30 fps), short enough that the 58-frame sample
# already has two segments for two cores.
SEGMENT_FRAMES = 30
_POSE = "POSE_LANDMARKS"
_HANDS = {"left": "LEFT_HAND_LANDMARKS", "right": "RIGHT_HAND_LANDMARKS"}


class VideoWarning(UserWarning):
    """Something about a video the user should know that does not stop the retargeting."""


# ----------------------------------------------------------------------------- reading frames
def _container_kind(head: bytes) -> str | None:
    """The container a file's first bytes announce (None: not a video we know)."""
    if len(head) >= 12 and head[4:8] in (b"ftyp", b"moov", b"mdat", b"free", b"wide", b"skip", b"pnot"):
        return "MP4/QuickTime"
    if head[:4] == b"\x1a\x45\xdf\xa3":
        return "WebM/Matroska"
    if head[:4] == b"RIFF" and head[8:12] == b"AVI ":
        return "AVI"
    return None


def _check_file(path: Path) -> None:
    """Missing, empty or non-video files, before any decoder sees them."""
    try:
        with path.open("rb") as f:
            head = f.read(16)
    except FileNotFoundError:
        raise DemonstrationError("no such file", path=path) from None
    except IsADirectoryError:
        raise DemonstrationError("is a folder, not a video file", path=path) from None
    except OSError as err:
        raise DemonstrationError(f"cannot read the file ({err.strerror or err})", path=path) from None
    if not head:
        raise DemonstrationError("the file is empty", path=path)
    if _container_kind(head) is None:
        raise DemonstrationError(
            f"not a video: the contents are no MP4, QuickTime, WebM or AVI container despite the {path.suffix} extension",
            path=path,
        )


def _cv2(path: Path):
    try:
        import cv2
    except ImportError as err:
        raise DemonstrationError(
            f"reading videos needs the video extra: pip install \"nlo_lab[video]\" ({err})", path=path
        ) from None
    return cv2


@dataclass(frozen=True)
class _Info:
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
    info = _open_info(Path(path))
    return {"fps": info.fps, "width": info.width, "height": info.height, "frames": info.frames}


def _open_info(path: Path) -> _Info:
    _check_file(path)
    cv2 = _cv2(path)
    with _native_output_silenced():
        cap = cv2.VideoCapture(str(path))
        try:
            if not cap.isOpened():
                raise DemonstrationError("unreadable or damaged video: no decoder can open it", path=path)
            fps = float(cap.get(cv2.CAP_PROP_FPS))
            info = _Info(fps, int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)),
                         max(0, int(cap.get(cv2.CAP_PROP_FRAME_COUNT))))
        finally:
            cap.release()
    if not (np.isfinite(fps) and 0 < fps <= 1000):
        raise DemonstrationError(f"the video's frame rate is not usable ({fps})", path=path, field="fps")
    return info


class _Frames:
    """Iterates a video's frames as RGB ``uint8`` arrays (what MediaPipe expects); counts them."""

    def __init__(self, path: Path, info: _Info, max_side: int | None = None):
        self.path, self.info, self.max_side = path, info, max_side
        self.count = 0

    def __iter__(self) -> Iterator[np.ndarray]:
        cv2 = _cv2(self.path)
        cap = cv2.VideoCapture(str(self.path))
        try:
            while True:
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
        if self.count == 0:
            raise DemonstrationError("unreadable or damaged video: no frame decodes", path=self.path)
        if self.info.frames and self.count < self.info.frames:
            raise DemonstrationError(
                f"truncated or damaged video: {self.count} of the {self.info.frames} frames its header announces decode",
                path=self.path, frame=self.count,
            )


def read_video_frames(path, max_side: int | None = 360) -> np.ndarray:
    """All frames of a video as RGB images (for showing them beside the 3-D view).

    Args:
        path: the video file.
        max_side: shrink frames so that their longer side is at most this many pixels (None: full size).

    Returns:
        ``(T, H, W, 3)`` ``uint8``.

    Raises:
        DemonstrationError: as :func:`load_video` for unreadable, non-video or truncated files.
    """
    path = Path(path)
    frames = _Frames(path, _open_info(path), max_side)
    with _native_output_silenced():
        images = list(frames)
    frames.check_complete()
    return np.stack(images)


# ----------------------------------------------------------------------------- quiet native code
def _stderr_stream():
    """Where our progress bar writes: the real stderr, also while fd 2 is silenced."""
    try:
        if sys.stderr.fileno() == 2:
            return os.fdopen(os.dup(2), "w", buffering=1)
    except (AttributeError, OSError, ValueError):
        pass
    return None  # not a file descriptor (a notebook's stream): use sys.stderr as it is


@contextlib.contextmanager
def _native_output_silenced():
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


# ----------------------------------------------------------------------------- pose estimation
def _available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the system has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def pose_workers(threads: int | None = None, frames: int = 0) -> int:
    """Holistic instances to run side by side.

    Args:
        threads: the most the caller allows; None: ``NLO_LAB_THREADS`` if set, else no limit.
        frames: the video's frame count (0: unknown): no more workers than it has segments of
            :data:`SEGMENT_FRAMES`.

    Returns:
        ``min(threads, cores available, segments)``, at least 1.
    """
    if threads is None:
        env = os.environ.get("NLO_LAB_THREADS")
        try:
            asked = int(env) if env else None
        except ValueError:
            asked = None
        if asked is not None and asked < 1:
            asked = 1
    else:
        asked = int(threads)
        if asked < 1:
            raise DemonstrationError(f"threads must be >= 1, got {asked}")
    workers = _available_cores() if asked is None else min(asked, _available_cores())
    if frames > 0:
        workers = min(workers, -(-int(frames) // SEGMENT_FRAMES))
    return max(1, workers)


@dataclass
class VideoPose:
    """MediaPipe Holistic landmarks of a video (a pose-format ``Pose``) and how they were made.

    Attributes:
        path: the video.
        pose: the ``pose_format.Pose`` (components POSE_LANDMARKS, FACE_LANDMARKS,
            LEFT/RIGHT_HAND_LANDMARKS, POSE_WORLD_LANDMARKS).
        seconds: wall time of the pose estimation [s] (decoding included).
        workers: Holistic instances used side by side (:func:`pose_workers`).
        fps, width, height: of the video.
    """

    path: Path
    pose: object
    seconds: float
    workers: int
    fps: float
    width: int
    height: int

    def __len__(self) -> int:
        return int(self.pose.body.data.shape[0])

    def to_bytes(self) -> bytes:
        """The ``.pose`` file's contents."""
        import io

        buffer = io.BytesIO()
        self.pose.write(buffer)
        return buffer.getvalue()


def _holistic(path: Path):
    try:
        from pose_format.utils.holistic import load_holistic
    except ImportError as err:
        raise DemonstrationError(
            f"reading videos needs the video extra: pip install \"nlo_lab[video]\" ({err})", path=path
        ) from None
    return load_holistic


def _segments(frames, size: int) -> Iterator[list[np.ndarray]]:
    """Consecutive lists of ``size`` frames (the last one shorter)."""
    chunk: list[np.ndarray] = []
    for frame in frames:
        chunk.append(frame)
        if len(chunk) == size:
            yield chunk
            chunk = []
    if chunk:
        yield chunk


def _join(poses: list):
    """One ``Pose`` of the segments' poses, in order (same header; frames concatenated)."""
    from pose_format import Pose
    from pose_format.numpy import NumPyPoseBody

    if len(poses) == 1:
        return poses[0]
    data = np.ma.concatenate([p.body.data for p in poses], axis=0)
    confidence = np.concatenate([p.body.confidence for p in poses], axis=0)
    return Pose(poses[0].header, NumPyPoseBody(poses[0].body.fps, data, confidence))


def estimate_pose(path, *, threads: int | None = None, progress: bool = False) -> VideoPose:
    """MediaPipe Holistic on every frame of a video, through pose-format.

    Args:
        path: a ``.mp4``, ``.mov``, ``.webm`` or ``.avi`` file.
        threads: the most Holistic instances to run side by side (:func:`pose_workers`;
            default: every core available). The result does not depend on it.
        progress: a progress bar over the frames on stderr (in a notebook: below the cell).

    Returns:
        A :class:`VideoPose`.

    Raises:
        DemonstrationError: the file is missing, empty, not a video, undecodable or
            truncated, or no person is found in any frame.
    """
    from concurrent.futures import ThreadPoolExecutor

    path = Path(path)
    info = _open_info(path)
    workers = pose_workers(threads, info.frames)
    load_holistic = _holistic(path)
    frames = _Frames(path, info)

    def segment_pose(segment: list[np.ndarray]):
        # a fresh instance per segment (reuse=False): it starts from a detection, whoever runs it
        return load_holistic(segment, fps=info.fps, width=info.width, height=info.height, progress=False,
                             additional_holistic_config={"model_complexity": MODEL_COMPLEXITY},
                             pose_workers=1, reuse=False)

    start = time.perf_counter()
    bar_stream = _stderr_stream() if progress else None
    poses = []
    try:
        with _native_output_silenced(), ThreadPoolExecutor(max_workers=workers) as pool:
            source = frames
            if progress:
                from tqdm.auto import tqdm

                # mininterval=0: every frame is shown (a frame takes far longer than drawing the bar),
                # so the last count appears before the bar closes, however fast the frames come
                source = tqdm(frames, total=info.frames or None, desc=f"pose estimation {path.name}", unit="frame",
                              file=bar_stream or sys.stderr, leave=False, dynamic_ncols=True, mininterval=0)
            try:
                pending = []  # futures in the video's order; at most `workers` ahead of decoding (bounded memory)
                for segment in _segments(source, SEGMENT_FRAMES):
                    pending.append(pool.submit(segment_pose, segment))
                    if len(pending) > workers:
                        poses.append(pending.pop(0).result())
                poses.extend(f.result() for f in pending)
            finally:
                if progress:
                    source.close()
    finally:
        if bar_stream is not None:
            bar_stream.close()
    seconds = time.perf_counter() - start
    frames.check_complete()
    if not poses:
        raise DemonstrationError("unreadable or damaged video: no frame decodes", path=path)
    result = VideoPose(path=path, pose=_join(poses), seconds=seconds, workers=workers, fps=info.fps,
                       width=info.width, height=info.height)
    _check_person(result)
    return result


def _component(pose, name: str) -> np.ndarray:
    """The confidence ``(T, P)`` of one component of the first person."""
    start = 0
    for comp in pose.header.components:
        n = len(comp.points)
        if comp.name == name:
            return np.asarray(pose.body.confidence[:, 0, start:start + n])
        start += n
    raise KeyError(name)


def _check_person(video: VideoPose) -> None:
    seen = (_component(video.pose, _POSE) > 0).any(axis=1)
    if not seen.any():
        raise DemonstrationError(f"no person found in any of the {len(video)} frames of the video", path=video.path)


def pose_to_demonstration(video: VideoPose) -> Demonstration:
    """The :class:`Demonstration` of a video's landmarks: exactly what the ``.pose`` reader makes of them.

    The landmarks are written to a private temporary ``.pose`` file and read back with
    :func:`nlo_lab.human.io_pose.load_pose`, so the result equals reading the file that
    ``--save-pose`` keeps. A hand never seen gives a :class:`VideoWarning` and masked fingers.

    Returns:
        The demonstration; ``meta`` as the ``.pose`` reader's, with ``source`` the video's
        file name, ``format`` ``"video"``, and ``pose_seconds``, ``pose_workers`` and
        ``model_complexity`` added; ``name`` is the video's stem.
    """
    from nlo_lab.human.io_pose import load_pose

    with tempfile.TemporaryDirectory(prefix="nlo_lab_video_") as tmp:
        pose_file = Path(tmp) / f"{video.path.stem}.pose"
        pose_file.write_bytes(video.to_bytes())
        try:
            demo = load_pose(pose_file)
        except DemonstrationError as err:  # name the video, not our temporary file
            raise DemonstrationError(str(err).replace(str(pose_file), str(video.path))) from None
    demo.meta.update(source=video.path.name, format="video", pose_seconds=round(video.seconds, 4), pose_workers=video.workers,
                     model_complexity=MODEL_COMPLEXITY)
    hands = demo.meta.get("hands", {})
    never = [side for side in _HANDS if not hands.get(side, {}).get("observed_frames", 0)]
    if len(never) == 2:
        warnings.warn(f"{video.path.name}: neither hand is seen in any frame; the fingers and wrist orientations are masked",
                      VideoWarning, stacklevel=2)
    elif never:
        warnings.warn(f"{video.path.name}: the {never[0]} hand is never seen; its fingers and wrist orientation are masked",
                      VideoWarning, stacklevel=2)
    return demo


def load_video(path, *, threads: int | None = None, progress: bool = False, save_pose=None) -> Demonstration:
    """Read a video into a :class:`Demonstration` (MediaPipe Holistic, see the module docstring).

    Args:
        path: a ``.mp4``, ``.mov``, ``.webm`` or ``.avi`` file.
        threads: the most Holistic instances side by side (default: every core available, see
            :func:`pose_workers`); the demonstration does not depend on it.
        progress: show a progress bar of the pose estimation.
        save_pose: also keep the landmarks as this ``.pose`` file (written atomically,
            only once the demonstration has been read without error).

    Returns:
        The demonstration (``meta["pose_seconds"]``: the pose estimation's wall time).

    Raises:
        DemonstrationError: see :func:`estimate_pose` and :func:`nlo_lab.human.io_pose.load_pose`.
    """
    video = estimate_pose(path, threads=threads, progress=progress)
    demo = pose_to_demonstration(video)
    if save_pose is not None:
        from nlo_lab.atomic_files import atomic_write_bytes

        atomic_write_bytes(save_pose, video.to_bytes())
    return demo

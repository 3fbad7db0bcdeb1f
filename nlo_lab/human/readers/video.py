"""The video reader (``.mp4``, ``.mov``, ``.webm``, ``.avi``): frames, MediaPipe Holistic through pose-format, a demonstration.

The pipeline is video -> MediaPipe Holistic (pose-format's
:func:`pose_format.utils.holistic.load_holistic`, which keeps the world landmarks as
the ``POSE_WORLD_LANDMARKS`` component) -> a ``.pose`` recording -> the ``.pose``
reader (:func:`nlo_lab.human.readers.pose.load_pose`). So a video and the ``.pose`` saved
from it give the same :class:`Demonstration`, and every convention of the ``.pose``
reader (body frame, metres, gap filling, masks) applies.

Needs the ``video`` extra (``pip install "nlo_lab[video]"``: mediapipe 0.10.21, the
last release whose wheel bundles the Holistic models, and opencv, which comes with
it). Frames are read with OpenCV (section "frames"), the landmarks estimated on every core
available, the same landmarks for any number (section "pose estimation").

Faults end in :class:`~nlo_lab.errors.DemonstrationError` naming the file: missing
or empty file, contents that are not a video container, a video no frame of which
decodes, a truncated video (fewer frames decode than its header announces), no
person in any frame. Hands never seen are not an error: a :class:`VideoWarning`
says so and the fingers are masked.

Frames (section "frames"):
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

Pose estimation (section "pose estimation"):
The landmarks come from pose-format's :func:`pose_format.utils.holistic.load_holistic`, which
keeps the world landmarks as the ``POSE_WORLD_LANDMARKS`` component. Nothing is downloaded at
run time: :data:`MODEL_COMPLEXITY` is the one pose model the mediapipe wheel carries.

Threads: the video is cut into segments of :data:`SEGMENT_FRAMES` consecutive frames,
and each segment goes to a fresh Holistic instance that tracks through it (MediaPipe
tracks a person from frame to frame and smooths the landmarks; each segment starts
that anew from a detection). ``workers`` instances run side by side, one segment each,
each on its share of the cores: MediaPipe would run each instance's graph on a pool of as many
threads as the machine has cores (blind to CPU affinity and to a cluster job's share), so it is
told how many to use (:func:`holistic_loader`: the cores allowed over the instances, at least one;
one for :func:`estimate_segment`; the landmarks are the same). Because the cut does not depend on the number of
workers, the landmarks, and so the demonstration, are the same for any number of
workers, frame by frame, in the video's order. The number of workers
(:func:`pose_workers`) is the cores this process may use (``os.sched_getaffinity``,
else ``os.cpu_count()``), never more than asked for (``threads``, ``--threads N``, or
``NLO_LAB_THREADS``), nor more than the video has segments, nor more than fit their
frames in :data:`IN_FLIGHT_BYTES` (frames larger than :data:`MAX_ESTIMATION_SIDE` are
shrunk before MediaPipe sees them, so that is several workers even for 8K video).

Segments can also be estimated apart, in other processes or on other machines
(``nlo-lab batch`` does): :func:`segment_bounds` cuts the video at the same frames,
:func:`estimate_segment` estimates one range (a seek, then its 30-frame segments) and
:func:`join_segments` joins them, giving the same landmarks as :func:`estimate_pose`.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import sys
import tempfile
import threading
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nlo_lab.errors import DemonstrationError
from nlo_lab.files import as_path, format_size, open_input
from nlo_lab.human.demonstration import MAX_FRAMES, Demonstration
from nlo_lab.human.readers.pose import load_pose
from nlo_lab.settings import check_int
from nlo_lab.threads import check_threads, env_threads

__all__ = [
    "VIDEO_SUFFIXES",
    "MAX_VIDEO_BYTES",
    "MAX_VIDEO_SIDE",
    "MAX_VIDEO_PIXELS",
    "MAX_SHOWN_BYTES",
    "MODEL_COMPLEXITY",
    "SEGMENT_FRAMES",
    "MAX_ESTIMATION_SIDE",
    "IN_FLIGHT_BYTES",
    "VideoInfo",
    "VideoFrames",
    "VideoPose",
    "SegmentPose",
    "VideoWarning",
    "video_extra",
    "container_kind",
    "check_video_file",
    "open_video",
    "video_info",
    "read_video_frames",
    "native_output_silenced",
    "holistic_loader",
    "holistic_config",
    "pose_workers",
    "estimate_pose",
    "segment_bounds",
    "estimate_segment",
    "join_segments",
    "pose_to_demonstration",
    "load_video",
]


# ----------------------------------------------------------------------------- frames
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
        DemonstrationError: as :func:`nlo_lab.human.readers.video.load_video` for unreadable, non-video or truncated
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


# ----------------------------------------------------------------------------- pose estimation
# mediapipe 0.10.21 ships pose_landmark_full.tflite only: complexity 1. Complexity 0 (lite) and
# 2 (heavy) would be downloaded on first use, which library code must never do.
MODEL_COMPLEXITY = 1
_HOLISTIC_LOCK = threading.Lock()


class _SolutionsWithThreads:
    """``mediapipe.solutions.holistic`` as pose-format sees it, with a ``Holistic`` whose graph's thread count is ours."""

    def __init__(self, module, holistic) -> None:
        self._module, self.Holistic = module, holistic

    def __getattr__(self, name: str):
        return getattr(self._module, name)


def holistic_loader(path):
    """pose-format's ``load_holistic``, whose Holistic instances run their MediaPipe graph on as many threads
    as the Holistic config's ``graph_threads`` says (:func:`holistic_config`; 1 if it says nothing).

    MediaPipe runs a graph's calculators on a pool of min(cores, nodes) threads, the cores being
    every core of the machine (``sysconf(_SC_NPROCESSORS_ONLN)``: blind to CPU affinity, to a
    cluster job's share and to the other instances running beside it). One Holistic instance ran
    on 1.4 cores here (4 segments of the sample video: 4.1 s of CPU in 3.0 s; docs/RESULTS.md's video
    section measured 1.43 for one worker), so two of them, or two batch workers, asked for 4 threads
    of 2 cores. Our parallelism is by segments (:func:`estimate_pose`'s instances, ``nlo-lab batch``'s
    workers), so each instance gets its share of the cores it may use. Only the instances pose-format
    creates are concerned (its handle on MediaPipe's holistic module is swapped for one whose
    ``Holistic`` does this; MediaPipe itself is left as it is); the landmarks are the same, bit for
    bit, whatever the threads (tested).

    Raises:
        DemonstrationError: the video extra is missing (naming ``path``).
    """
    module = video_extra(path, "pose_format.utils.holistic")
    with _HOLISTIC_LOCK:
        if not isinstance(module.mp_holistic, _SolutionsWithThreads):
            framework = video_extra(path, "mediapipe.framework.thread_pool_executor_pb2")
            module.mp_holistic = _SolutionsWithThreads(module.mp_holistic, _holistic_with_threads(module.mp_holistic.Holistic, framework))
    return module.load_holistic


def holistic_config(graph_threads: int = 1) -> dict:
    """The Holistic settings every estimation uses (:data:`MODEL_COMPLEXITY`), its graph on ``graph_threads`` threads."""
    return {"model_complexity": MODEL_COMPLEXITY, "graph_threads": int(graph_threads)}


def _holistic_with_threads(holistic, framework):
    """A subclass of MediaPipe's ``Holistic`` taking ``graph_threads``: its graph's default executor's thread count."""
    options = framework.ThreadPoolExecutorOptions.ext

    class HolisticWithThreads(holistic):
        def __init__(self, *args, graph_threads: int = 1, **kwargs) -> None:
            self._graph_threads = max(1, int(graph_threads))
            super().__init__(*args, **kwargs)

        def _initialize_graph_interface(self, *args, **kwargs):  # SolutionBase's: the graph's config, before the graph is made
            config = super()._initialize_graph_interface(*args, **kwargs)
            default = [e for e in config.executor if not e.name] or [config.executor.add()]
            if not default[0].type:  # a thread pool of MediaPipe's choosing (not a given executor type)
                default[0].options.Extensions[options].num_threads = self._graph_threads
            return config

    return HolisticWithThreads


# Frames per segment of the pose estimation (see the module docstring): long enough that
# tracking restarts rarely (once a second at 30 fps), short enough that the 58-frame sample
# already has two segments for two cores.
SEGMENT_FRAMES = 30
# Frames go to MediaPipe with a longer side of at most this (a larger frame is shrunk first: the models
# see 256-pixel crops, so more pixels only cost memory): a segment of 30 frames is at most 187 MB.
MAX_ESTIMATION_SIDE = 1920
IN_FLIGHT_BYTES = 1 << 30  # decoded frames waiting for or inside the Holistic instances, at most (workers capped to fit)
_POSE = "POSE_LANDMARKS"


def _available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the system has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def pose_workers(threads: int | None = None, frames: int = 0, segment_frames: int = SEGMENT_FRAMES) -> int:
    """Holistic instances to run side by side.

    Args:
        threads: the most the caller allows, 1..256; None: ``NLO_LAB_THREADS`` if set, else no limit.
        frames: the video's frame count (0: unknown): no more workers than it has segments of
            ``segment_frames`` (default :data:`SEGMENT_FRAMES`).
        segment_frames: the frames of a segment (as :func:`estimate_pose`'s).

    Returns:
        ``min(threads, cores available, segments)``, at least 1.

    Raises:
        SettingsError: ``threads`` or ``NLO_LAB_THREADS`` not a whole number in 1..256.
    """
    asked = env_threads() if threads is None else check_threads("threads", threads)
    workers = _available_cores() if asked is None else min(asked, _available_cores())
    if frames > 0:
        workers = min(workers, -(-int(frames) // _check_segment_frames(segment_frames)))
    return max(1, workers)


def _check_segment_frames(value) -> int:
    """``segment_frames`` checked: a whole number >= 1 (any number above a video's frame count makes one segment of it)."""
    return check_int("segment_frames", value, 1)


def _workers_in_memory(info, segment_frames: int = SEGMENT_FRAMES) -> int:
    """The most workers whose segments fit in :data:`IN_FLIGHT_BYTES` (each worker's, one waiting, one being decoded)."""
    scale = min(1.0, MAX_ESTIMATION_SIDE / max(info.width, info.height, 1))
    frames = min(segment_frames, info.frames or segment_frames)  # a segment holds at most the whole video
    segment = frames * 3 * max(1, round(info.width * scale)) * max(1, round(info.height * scale))
    return max(1, IN_FLIGHT_BYTES // segment - 2)


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


def _stderr_stream():
    """Where our progress bar writes: the real stderr, also while fd 2 is silenced."""
    try:
        if sys.stderr.fileno() == 2:
            return os.fdopen(os.dup(2), "w", buffering=1)
    except (AttributeError, OSError, ValueError):
        pass
    return None  # not a file descriptor (a notebook's stream): use sys.stderr as it is


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


def _holistic(load_holistic, segment: list[np.ndarray], info, graph_threads: int = 1):
    """One segment's landmarks, by a fresh Holistic instance (reuse=False): it starts from a detection, whoever runs it."""
    return load_holistic(segment, fps=info.fps, width=info.width, height=info.height, progress=False,
                         additional_holistic_config=holistic_config(graph_threads), pose_workers=1, reuse=False)


def estimate_pose(path, *, threads: int | None = None, progress: bool = False,
                  segment_frames: int = SEGMENT_FRAMES) -> VideoPose:
    """MediaPipe Holistic on every frame of a video, through pose-format.

    Args:
        path: a ``.mp4``, ``.mov``, ``.webm`` or ``.avi`` file.
        threads: the most Holistic instances to run side by side (:func:`pose_workers`;
            default: every core available). The result does not depend on it.
        progress: a progress bar over the frames on stderr (in a notebook: below the cell).
        segment_frames: frames per segment, each tracked by a fresh Holistic instance (default
            :data:`SEGMENT_FRAMES`; more than the video's frames: one segment, pure tracking, one worker).
            The landmarks depend on it (tracking restarts at every segment's first frame);
            :func:`segment_bounds`, :func:`estimate_segment` and ``nlo-lab batch`` cut at :data:`SEGMENT_FRAMES`.

    Returns:
        A :class:`VideoPose`.

    Raises:
        DemonstrationError: the file is missing, empty, not a video, undecodable or
            truncated, or no person is found in any frame.
        SettingsError: ``threads`` or ``segment_frames`` out of range (or not whole numbers).
    """
    from concurrent.futures import ThreadPoolExecutor

    segment_frames = _check_segment_frames(segment_frames)
    path = as_path(path)
    info = open_video(path)
    workers = min(pose_workers(threads, info.frames, segment_frames), _workers_in_memory(info, segment_frames))
    load_holistic = holistic_loader(path)
    frames = VideoFrames(path, info, max_side=MAX_ESTIMATION_SIDE)

    graph_threads = max(1, pose_workers(threads) // workers)  # the cores allowed, shared by the instances (fewer segments: more each)

    def segment_pose(segment: list[np.ndarray]):
        return _holistic(load_holistic, segment, info, graph_threads)

    start = time.perf_counter()
    bar_stream = _stderr_stream() if progress else None
    poses = []
    try:
        with native_output_silenced(), ThreadPoolExecutor(max_workers=workers) as pool:
            source = frames
            if progress:
                from tqdm.auto import tqdm

                # mininterval=0: every frame is shown (a frame takes far longer than drawing the bar),
                # so the last count appears before the bar closes, however fast the frames come
                source = tqdm(frames, total=info.frames or None, desc=f"pose estimation {path.name}", unit="frame",
                              file=bar_stream or sys.stderr, leave=False, dynamic_ncols=True, mininterval=0)
            try:
                pending = []  # futures in the video's order; at most `workers` ahead of decoding (bounded memory)
                for segment in _segments(source, segment_frames):
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


@dataclass
class SegmentPose:
    """The landmarks of frames ``first ...`` of a video (:func:`estimate_segment`).

    Attributes:
        first: the first frame.
        pose: a ``pose_format.Pose`` of the range's frames.
        seconds: wall time of its estimation [s] (decoding included).
    """

    first: int
    pose: object
    seconds: float

    def __len__(self) -> int:
        return int(self.pose.body.data.shape[0])


def segment_bounds(path) -> list[tuple[int, int | None]]:
    """The ranges ``(first, end)`` to estimate apart: the cut of :func:`estimate_pose`, one range a segment.

    The last range has ``end`` None (to the video's end). One range ``(0, None)`` when the
    container does not announce its length.

    Raises:
        DemonstrationError: missing, empty, not a video, or a video no decoder opens.
    """
    frames = open_video(as_path(path)).frames
    starts = list(range(0, max(frames, 1), SEGMENT_FRAMES))
    return [(a, a + SEGMENT_FRAMES) for a in starts[:-1]] + [(starts[-1], None)]


def estimate_segment(path, first: int = 0, end: int | None = None) -> SegmentPose:
    """MediaPipe Holistic on frames ``[first, end)`` of a video (``end`` None: to its end), on one core.

    ``first`` is a multiple of :data:`SEGMENT_FRAMES` (a range of :func:`segment_bounds`); the
    frames are tracked in segments of that many, as :func:`estimate_pose` tracks them.

    Raises:
        DemonstrationError: the video is missing, not a video, cannot seek to ``first``, or
            decodes fewer frames there than its header announces.
    """
    path = as_path(path)
    info = open_video(path)
    load_holistic = holistic_loader(path)
    frames = VideoFrames(path, info, max_side=MAX_ESTIMATION_SIDE, first=first, count=None if end is None else end - first)
    start = time.perf_counter()
    with native_output_silenced():
        poses = [_holistic(load_holistic, segment, info) for segment in _segments(frames, SEGMENT_FRAMES)]
    frames.check_complete()
    if not poses:
        raise DemonstrationError(f"no frame decodes from frame {first} on", path=path, frame=first)
    return SegmentPose(first, _join(poses), time.perf_counter() - start)


def join_segments(path, segments: list[SegmentPose]) -> VideoPose:
    """One :class:`VideoPose` of a video's ranges (:func:`estimate_segment` of each of :func:`segment_bounds`).

    ``seconds`` is the ranges' total estimation time (their work, not the wall time of a run
    that estimated them side by side); ``workers`` 1 (one Holistic instance at a time each).

    Raises:
        DemonstrationError: the ranges do not follow each other, or no person is found in any frame.
    """
    path = as_path(path)
    expected = 0
    for segment in segments:
        if segment.first != expected:
            raise DemonstrationError(f"the pose estimation's ranges do not join: frame {expected} expected, got {segment.first}",
                                     path=path)
        expected += len(segment)
    if not segments:
        raise DemonstrationError("unreadable or damaged video: no frame decodes", path=path)
    info = open_video(path)
    result = VideoPose(path=path, pose=_join([s.pose for s in segments]), seconds=sum(s.seconds for s in segments), workers=1,
                       fps=info.fps, width=info.width, height=info.height)
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


# ----------------------------------------------------------------------------- the reader
_HANDS = ("left", "right")


class VideoWarning(UserWarning):
    """Something about a video the user should know that does not stop the retargeting."""


def pose_to_demonstration(video: VideoPose) -> Demonstration:
    """The :class:`Demonstration` of a video's landmarks: exactly what the ``.pose`` reader makes of them.

    The landmarks are written to a private temporary ``.pose`` file and read back with
    :func:`nlo_lab.human.readers.pose.load_pose`, so the result equals reading the file that
    ``--save-pose`` keeps. A hand never seen gives a :class:`VideoWarning` and masked fingers.

    Returns:
        The demonstration; ``meta`` as the ``.pose`` reader's, with ``source`` the video's
        file name, ``format`` ``"video"``, and ``pose_seconds``, ``pose_workers`` and
        ``model_complexity`` added; ``name`` is the video's stem.
    """
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
        DemonstrationError: see :func:`estimate_pose` and :func:`nlo_lab.human.readers.pose.load_pose`.
    """
    video = estimate_pose(path, threads=threads, progress=progress)
    demo = pose_to_demonstration(video)
    if save_pose is not None:
        from nlo_lab.atomic_files import atomic_write_bytes

        atomic_write_bytes(save_pose, video.to_bytes())
    return demo

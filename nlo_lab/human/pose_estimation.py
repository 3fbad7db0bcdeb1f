"""Pose estimation of a video: MediaPipe Holistic on every frame, through pose-format, on several cores.

The landmarks come from pose-format's :func:`pose_format.utils.holistic.load_holistic`, which
keeps the world landmarks as the ``POSE_WORLD_LANDMARKS`` component. Nothing is downloaded at
run time: :data:`MODEL_COMPLEXITY` is the one pose model the mediapipe wheel carries.

Threads: the video is cut into segments of :data:`SEGMENT_FRAMES` consecutive frames,
and each segment goes to a fresh Holistic instance that tracks through it (MediaPipe
tracks a person from frame to frame and smooths the landmarks; each segment starts
that anew from a detection). ``workers`` instances run side by side, one segment each,
each keeping about one core busy. Because the cut does not depend on the number of
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

import os
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nlo_lab.errors import DemonstrationError
from nlo_lab.files import as_path
from nlo_lab.human.video_frames import VideoFrames, native_output_silenced, open_video, video_extra
from nlo_lab.threads import check_threads, env_threads

__all__ = [
    "MODEL_COMPLEXITY",
    "SEGMENT_FRAMES",
    "VideoPose",
    "SegmentPose",
    "pose_workers",
    "estimate_pose",
    "segment_bounds",
    "estimate_segment",
    "join_segments",
]

# mediapipe 0.10.21 ships pose_landmark_full.tflite only: complexity 1. Complexity 0 (lite) and
# 2 (heavy) would be downloaded on first use, which library code must never do.
MODEL_COMPLEXITY = 1
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


def pose_workers(threads: int | None = None, frames: int = 0) -> int:
    """Holistic instances to run side by side.

    Args:
        threads: the most the caller allows, 1..256; None: ``NLO_LAB_THREADS`` if set, else no limit.
        frames: the video's frame count (0: unknown): no more workers than it has segments of
            :data:`SEGMENT_FRAMES`.

    Returns:
        ``min(threads, cores available, segments)``, at least 1.

    Raises:
        SettingsError: ``threads`` or ``NLO_LAB_THREADS`` not a whole number in 1..256.
    """
    asked = env_threads() if threads is None else check_threads("threads", threads)
    workers = _available_cores() if asked is None else min(asked, _available_cores())
    if frames > 0:
        workers = min(workers, -(-int(frames) // SEGMENT_FRAMES))
    return max(1, workers)


def _workers_in_memory(info) -> int:
    """The most workers whose segments fit in :data:`IN_FLIGHT_BYTES` (each worker's, one waiting, one being decoded)."""
    scale = min(1.0, MAX_ESTIMATION_SIDE / max(info.width, info.height, 1))
    segment = SEGMENT_FRAMES * 3 * max(1, round(info.width * scale)) * max(1, round(info.height * scale))
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


def _holistic(load_holistic, segment: list[np.ndarray], info):
    """One segment's landmarks, by a fresh Holistic instance (reuse=False): it starts from a detection, whoever runs it."""
    return load_holistic(segment, fps=info.fps, width=info.width, height=info.height, progress=False,
                         additional_holistic_config={"model_complexity": MODEL_COMPLEXITY}, pose_workers=1, reuse=False)


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

    path = as_path(path)
    info = open_video(path)
    workers = min(pose_workers(threads, info.frames), _workers_in_memory(info))
    load_holistic = video_extra(path, "pose_format.utils.holistic").load_holistic
    frames = VideoFrames(path, info, max_side=MAX_ESTIMATION_SIDE)

    def segment_pose(segment: list[np.ndarray]):
        return _holistic(load_holistic, segment, info)

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
    load_holistic = video_extra(path, "pose_format.utils.holistic").load_holistic
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

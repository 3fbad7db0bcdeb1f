"""What runs on a worker: one input read, retargeted and written; a video's pose estimation by segments.

Each task returns a value, never raises for a bad input: a row of ``results.csv`` (see
:mod:`nlo_lab.batch.table`) or, for the pieces of a video, a :class:`Failure` that the input's
row then carries. So a corrupt file is one ``failed`` row, not an exception in the worker's
log, and only a worker's death makes the scheduler run a task again (elsewhere).

A worker process builds the retargeter (robot, model) once per settings
(:func:`cached_retargeter`) and reuses it for every input it is given.
"""

from __future__ import annotations

import ctypes
import os
import sys
import threading
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

from nlo_lab.batch.inputs import BatchInput
from nlo_lab.batch.output_folder import SUMMARY_FILE, VIEWER_FILE, write_output_folder
from nlo_lab.batch.settings import BatchSettings
from nlo_lab.batch.table import failed_row, row_from_summary
from nlo_lab.errors import NloLabError, escape

__all__ = ["Job", "Failure", "failure_text", "cached_retargeter", "undo_malloc_trim", "warm_up", "retarget_input", "video_segments", "video_segment"]

_CACHE: dict[BatchSettings, object] = {}
_CACHE_SIZE = 4  # settings kept per process (a notebook may try a few)
_LOCK = threading.Lock()


@dataclass(frozen=True)
class Job:
    """One input to retarget: where it goes, what it is, and the settings."""

    item: BatchInput
    folder: str  # the input's output folder (absolute)
    input_sha256: str
    settings: BatchSettings
    fingerprint: str  # settings.fingerprint(), and what it is made of: computed once, on the client
    settings_key: dict


@dataclass(frozen=True)
class Failure:
    """A piece of an input that failed (a video's plan or segment): the one-line error."""

    error: str


def failure_text(exc: BaseException, path) -> str:
    """One line saying what went wrong with the input ``path`` (escaped; names the file)."""
    if isinstance(exc, NloLabError):
        text = str(exc)
    elif isinstance(exc, FileNotFoundError):
        text = f"file not found: {exc.filename or path}"
    elif isinstance(exc, MemoryError):
        text = "out of memory (the input is too large for this worker)"
    elif isinstance(exc, OSError):
        text = f"{exc.strerror or exc}: {exc.filename}" if exc.filename else str(exc.strerror or exc)
    else:  # a bug of nlo_lab: the row says so (the run goes on)
        text = f"internal error, please report it: {type(exc).__name__}: {exc}"
    text = " ".join(str(text).split())
    if str(path) not in text:
        text = f"{path}: {text}"
    return escape(text)


def undo_malloc_trim() -> bool:
    """Give glibc's allocator back the thresholds it would have without ``MALLOC_TRIM_THRESHOLD_``.

    dask's nanny starts its workers with ``MALLOC_TRIM_THRESHOLD_=65536`` (memory goes back to the
    system sooner). Setting it also freezes glibc's mmap threshold at 128 KiB, so every tensor above
    that is a fresh ``mmap`` and ``munmap``: retargeting, thousands of small tensors a second, then
    takes twice the CPU (measured: 4.8 s against 2.5 s for the same five retargetings). This sets the
    two thresholds where glibc's own dynamic rule ends (32 MiB, and twice that to trim). Only where the
    variable is set, on Linux; returns whether it changed anything.
    """
    if "MALLOC_TRIM_THRESHOLD_" not in os.environ or not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc
        return False
    mmap_threshold, trim_threshold = -3, -1  # M_MMAP_THRESHOLD, M_TRIM_THRESHOLD (malloc.h)
    return bool(mallopt(mmap_threshold, 32 << 20)) and bool(mallopt(trim_threshold, 64 << 20))


def cached_retargeter(settings: BatchSettings):
    """The retargeter of ``settings``, built once per worker process (robot and model loaded once)."""
    with _LOCK:
        if settings not in _CACHE:
            if not _CACHE:
                undo_malloc_trim()
            while len(_CACHE) >= _CACHE_SIZE:
                _CACHE.pop(next(iter(_CACHE)))
            _CACHE[settings] = settings.build()
        return _CACHE[settings]


def warm_up(settings: BatchSettings) -> str | NloLabError:
    """Build the retargeter of ``settings`` in this worker (kept for the inputs to come): nlo_lab's version
    here, or the error that building met (an unknown robot, a bad spec or checkpoint, a setting out of
    range), returned rather than raised so that the worker's log stays clean."""
    # lazy: the version, on the worker
    import nlo_lab

    try:
        cached_retargeter(settings)
    except NloLabError as exc:
        return exc
    return nlo_lab.__version__


def video_segments(path: str) -> list[tuple[int, int | None]] | Failure:
    """The frame ranges of a video's pose estimation, one task each (:func:`nlo_lab.human.readers.video.segment_bounds`)."""
    # lazy: mediapipe (the video extra): only for videos
    from nlo_lab.human.readers import segment_bounds

    try:
        return segment_bounds(path)
    except Exception as exc:  # noqa: BLE001 - every fault becomes the input's row
        return Failure(failure_text(exc, path))


def video_segment(path: str, first: int, end: int | None) -> tuple | Failure:
    """MediaPipe Holistic on frames ``[first, end)`` of a video (:func:`nlo_lab.human.readers.video.estimate_segment`).

    Returns ``(segment,)``: the :class:`~nlo_lab.human.readers.video.SegmentPose` in a tuple, or a
    :class:`Failure`. The value stays on the workers (the input's retarget task takes it), but dask
    tells the client the type of every result it holds a future of, and the client unpickles that
    type: ``SegmentPose`` would import ``nlo_lab.human`` and so torch there, 1.4 s of CPU taken from
    the workers; a tuple costs nothing.
    """
    # lazy: mediapipe (the video extra): only for videos
    from nlo_lab.human.readers import estimate_segment

    try:
        return (estimate_segment(path, first, end),)
    except Exception as exc:  # noqa: BLE001
        return Failure(failure_text(exc, path))


def _read(job: Job, segments) -> tuple:
    """The demonstration and, for a video, the pose estimation's seconds (None otherwise)."""
    if not job.item.is_video:
        # lazy: the readers, on the worker
        from nlo_lab.human import load_demonstration

        return load_demonstration(job.item.path), None
    # lazy: mediapipe (the video extra): only for videos
    from nlo_lab.human import pose_to_demonstration
    from nlo_lab.human.readers import join_segments

    video = join_segments(job.item.path, [segment for (segment,) in segments or ()])
    return pose_to_demonstration(video), video.seconds


def retarget_input(job: Job, segments=None) -> dict:
    """Read ``job``'s input, retarget it, write its output folder; its row of ``results.csv``.

    Args:
        job: the input and settings.
        segments: for a video, the results of :func:`video_segment` for every range of
            :func:`video_segments`, in order.
    """
    path = job.item.path
    start = time.perf_counter()
    try:
        failed = [s for s in segments or () if isinstance(s, Failure)]
        if failed:
            return failed_row(path, job.item.name, failed[0].error, input_sha256=job.input_sha256, settings=job.fingerprint)
        retargeter = cached_retargeter(job.settings)
        start = time.perf_counter()  # the input's own time: the worker's one-off model loading is not
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("ignore")
            warnings.simplefilter("always", UserWarning)  # the readers' warnings go into the row
            demo, pose_seconds = _read(job, segments)
            result = retargeter(demo)
        summary = dict(result.summary)
        if pose_seconds is not None:
            summary["pose_seconds"] = round(float(pose_seconds), 4)
        seconds = time.perf_counter() - start + (pose_seconds or 0.0)  # the segments' own time counts too
        summary["batch"] = {
            "input": str(path), "output": job.item.name, "input_sha256": job.input_sha256, "settings": job.fingerprint,
            "settings_key": job.settings_key, "seconds": round(seconds, 4),
            "warnings": list(dict.fromkeys(escape(w.message) for w in caught)),
        }
        write_output_folder(Path(job.folder), result, demo, retargeter.robot, viewer=job.settings.viewer, summary=summary,
                            stale=(VIEWER_FILE, SUMMARY_FILE))
        return row_from_summary(summary)
    except Exception as exc:  # noqa: BLE001 - a bad input is a failed row, never a retried task
        return failed_row(path, job.item.name, failure_text(exc, path), input_sha256=job.input_sha256,
                          settings=job.fingerprint, seconds=round(time.perf_counter() - start, 4))

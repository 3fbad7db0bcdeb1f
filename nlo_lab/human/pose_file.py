"""Reading a ``.pose`` file (library ``pose-format``): its sizes checked, its first person's landmarks per component.

A crafted file of a few kB must not make us read or allocate gigabytes: the file must be a
regular file of at most :data:`MAX_POSE_BYTES`, its header is parsed alone first (at most
:data:`MAX_HEADER_BYTES`) and the body's declared frames, people and points are checked
against the file's length before pose-format parses the body (every version: 0.0, 0.1, 0.2).
What the landmarks mean and how they become a demonstration is :mod:`nlo_lab.human.io_pose`.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from nlo_lab.errors import DemonstrationError
from nlo_lab.files import format_size, read_input_bytes
from nlo_lab.human.demonstration import MAX_FRAMES

__all__ = ["MIN_CONFIDENCE", "MAX_PEOPLE", "MAX_HEADER_BYTES", "MAX_POSE_BYTES", "check_pose_sizes", "read_pose_file",
           "PoseComponents"]

MIN_CONFIDENCE = 0.0  # a landmark is observed when its confidence is above this
# Sizes a .pose file may have or its header declare, checked before the body is parsed.
MAX_POSE_BYTES = 256 << 20  # the file: 29,000 frames of Holistic with the face mesh (16 min at 30 fps), 150,000 without
MAX_PEOPLE = 64  # people per frame (only the first is read)
MAX_HEADER_BYTES = 1 << 20  # a Holistic header with the face mesh is about 10 kB


def _fail(path, message):
    raise DemonstrationError(message, path=path)


def check_pose_sizes(path: Path, raw: bytes) -> None:
    """Refuse a file whose header declares more than we read, or a body its length does not hold exactly.

    ``raw`` is the whole file (at most :data:`MAX_POSE_BYTES`). Reads only the header and the
    body's counts, for every version pose-format reads (0.0, 0.1, 0.2; others are refused):
    frames at most :data:`~nlo_lab.human.demonstration.MAX_FRAMES`, people at most
    :data:`MAX_PEOPLE`, and the declared frames x people x points x (dims + confidence)
    float32 values must be exactly what the file holds after its header, so a truncated
    file (a version 0.1 file cut between frames too) is an error, never fewer frames.
    Version 0.0 stores each frame's people separately, and a frame without a person
    still makes pose-format allocate a whole frame: its frames are walked one by one and
    the values the reader will allocate are bounded as if they were stored.
    """
    from pose_format.pose_header import PoseHeader
    from pose_format.utils.reader import BufferReader

    reader = BufferReader(raw[:MAX_HEADER_BYTES])
    try:
        header = PoseHeader.read(reader)
        version = round(float(header.version), 3)
        points = sum(len(c.points) for c in header.components)
        dims = max(len(c.format) for c in header.components) - 1  # as pose-format's body reader counts them
    except Exception as err:  # a header pose-format cannot parse, or longer than the limit
        too_long = len(raw) > MAX_HEADER_BYTES
        _fail(path, f"not a readable .pose file ({f'no header within {MAX_HEADER_BYTES} bytes' if too_long else f'{type(err).__name__}: {err}'})")
    start = reader.read_offset
    size = len(raw)
    try:
        if version == 0.2:
            _fps, frames, people = struct.unpack_from("<fIH", raw, start)
            body_start = start + struct.calcsize("<fIH")
        elif version == 0.1:
            _fps, declared, people = struct.unpack_from("<HHH", raw, start)
            body_start = start + struct.calcsize("<HHH")
            per_frame = people * points * (dims + 1) * 4
            # pose-format takes the frames from the file's length; the header's count is 16-bit
            frames = (size - body_start) // per_frame if per_frame else 0
            if per_frame and (size - body_start) % per_frame == 0 and frames % 65536 != declared:
                _fail(path, f"truncated or padded: the header declares {declared} frames, the body holds {frames}")
        elif version == 0.0:
            frames, people, body_start = _walk_v0_0(path, raw, start, header)
        else:
            _fail(path, f"unsupported .pose version {header.version:g} (pose-format writes 0.0, 0.1 and 0.2)")
    except struct.error:
        _fail(path, "truncated: the file ends inside the body's counts")
    if frames > MAX_FRAMES:
        _fail(path, f"declares {frames} frames, more than the {MAX_FRAMES} this nlo_lab reads")
    if people > MAX_PEOPLE:
        _fail(path, f"declares {people} people per frame, more than {MAX_PEOPLE}")
    body = frames * people * points * (dims + 1) * 4
    if version != 0.0 and body != size - body_start:
        _fail(path, f"truncated or padded: the header declares {frames} frames x {people} people x {points} points "
                    f"({body} bytes), but the file holds {size - body_start} bytes after its header")
    if body > MAX_POSE_BYTES:
        _fail(path, f"declares {frames} frames x {people} people x {points} points ({format_size(body)} of values), "
                    f"more than the {format_size(MAX_POSE_BYTES)} a .pose file may hold")


def _walk_v0_0(path: Path, raw: bytes, start: int, header) -> tuple[int, int, int]:
    """Frames and people (at least 1: pose-format fills a frame without a person) of a version 0.0 body, walked.

    Each frame: people (uint16), then per person an id (int16) and each component's
    points x format float32 values. The walk must end exactly at the end of the file.
    """
    _fps, frames = struct.unpack_from("<HH", raw, start)
    offset = start + 4
    person = 2 + 4 * sum(len(c.points) * len(c.format) for c in header.components)
    most = 1
    for t in range(frames):
        (people,) = struct.unpack_from("<H", raw, offset)
        if people > MAX_PEOPLE:
            _fail(path, f"frame {t} declares {people} people, more than {MAX_PEOPLE}")
        most = max(most, people)
        offset += 2 + people * person
        if offset > len(raw):
            _fail(path, f"truncated: the file ends inside frame {t} of the {frames} its header declares")
    if offset != len(raw):
        _fail(path, f"padded: {len(raw) - offset} bytes follow the {frames} frames its header declares")
    return frames, 1, start + 4  # pose-format keeps the first person only


def read_pose_file(path: Path):
    """The file's ``Pose`` and its arrays: ``(pose, data (T, P, N, D), mask, confidence (T, P, N), fps)``.

    The file is checked first (:func:`nlo_lab.files.read_input_bytes`: a regular file of at most
    :data:`MAX_POSE_BYTES`), then its sizes (:func:`check_pose_sizes`), then parsed.
    """
    try:
        from pose_format import Pose
    except ImportError as err:  # pragma: no cover - a declared dependency
        raise DemonstrationError(f"reading .pose files needs the pose-format package ({err})", path=path) from None
    raw = read_input_bytes(path, kind=".pose", max_bytes=MAX_POSE_BYTES, error=DemonstrationError)
    check_pose_sizes(path, raw)  # before the body is parsed or allocated
    try:
        pose = Pose.read(raw)
        data = np.ma.getdata(pose.body.data)
        mask = np.ma.getmaskarray(pose.body.data)
        conf = np.asarray(pose.body.confidence)
        fps = pose.body.fps
    except Exception as err:  # pose-format raises many types on a truncated or foreign file
        raise DemonstrationError(f"not a readable .pose file ({type(err).__name__}: {err})", path=path) from None
    expected = sum(len(c.points) for c in pose.header.components)
    if data.ndim != 4 or data.shape[2] != expected or data.shape[3] not in (2, 3) or conf.shape != data.shape[:3]:
        raise DemonstrationError(
            f"body data of shape {data.shape} (confidence {conf.shape}) does not match the header's {expected} points",
            path=path, field="body.data",
        )
    return pose, data, mask, conf, fps


class PoseComponents:
    """The first person's points per component: values ``(T, P, 3)`` and observed ``(T, P)``."""

    def __init__(self, pose, data, mask, conf, path: Path):
        self.path = path
        self.names: dict[str, list[str]] = {}
        self.values: dict[str, np.ndarray] = {}
        self.observed: dict[str, np.ndarray] = {}
        self.confidence: dict[str, np.ndarray] = {}
        if data.shape[1] == 0:
            raise DemonstrationError("the file holds no person", path=path, field="body.data")
        start = 0
        for comp in pose.header.components:
            n = len(comp.points)
            v = np.asarray(data[:, 0, start : start + n], dtype=np.float64)
            if v.shape[-1] == 2:
                v = np.concatenate([v, np.zeros(v.shape[:-1] + (1,))], axis=-1)
            c = np.asarray(conf[:, 0, start : start + n], dtype=np.float64)
            seen = (c > MIN_CONFIDENCE) & ~mask[:, 0, start : start + n].any(axis=-1)
            bad = seen & ~np.isfinite(v).all(axis=-1)
            if bad.any():
                t, p = np.argwhere(bad)[0]
                raise DemonstrationError("NaN or inf in an observed landmark", path=path, frame=int(t),
                                         field=f"{comp.name}/{comp.points[p]}")
            self.names[comp.name] = list(comp.points)
            self.values[comp.name], self.observed[comp.name], self.confidence[comp.name] = v, seen, c
            start += n

    def point(self, component: str, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if name not in self.names[component]:
            raise DemonstrationError(f"the {component} component has no {name} point", path=self.path, field=f"{component}/{name}")
        i = self.names[component].index(name)
        return self.values[component][:, i], self.observed[component][:, i], self.confidence[component][:, i]

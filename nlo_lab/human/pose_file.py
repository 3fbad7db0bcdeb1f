"""Reading a ``.pose`` file (library ``pose-format``): its sizes checked, its first person's landmarks per component.

A crafted file of a few kB must not make us read or allocate gigabytes: the header is parsed
alone first (at most :data:`MAX_HEADER_BYTES`) and the body's declared frames, people and
points are checked against the file's length before the body is read. What the landmarks
mean and how they become a demonstration is :mod:`nlo_lab.human.io_pose`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nlo_lab.errors import DemonstrationError
from nlo_lab.human.demonstration import MAX_FRAMES
from nlo_lab.human.file_head import read_head

__all__ = ["MIN_CONFIDENCE", "MAX_PEOPLE", "MAX_HEADER_BYTES", "check_pose_sizes", "read_pose_file", "PoseComponents"]

MIN_CONFIDENCE = 0.0  # a landmark is observed when its confidence is above this
# Sizes a .pose header may declare, checked before the body is read or allocated.
MAX_PEOPLE = 64  # people per frame (only the first is read)
MAX_HEADER_BYTES = 1 << 20  # a Holistic header with the face mesh is about 10 kB


def check_pose_sizes(path: Path, head: bytes, size: int) -> None:
    """Refuse a file whose header declares more than we read, or a body its length cannot hold.

    ``head`` is the file's first bytes (at most :data:`MAX_HEADER_BYTES`), ``size`` its length.
    Reads only the header and the body's counts: frames at
    most :data:`~nlo_lab.human.demonstration.MAX_FRAMES`, people at most :data:`MAX_PEOPLE`,
    and the declared frames x people x points x (dims + confidence) float32 values must be
    exactly what the file holds after its header.
    """
    import struct

    from pose_format.pose_header import PoseHeader
    from pose_format.utils.reader import BufferReader

    prefix = head[:MAX_HEADER_BYTES]
    reader = BufferReader(prefix)
    try:
        header = PoseHeader.read(reader)
        version = round(float(header.version), 3)
        points = sum(len(c.points) for c in header.components)
        dims = max(len(c.format) for c in header.components) - 1  # as pose-format's body reader counts them
        if version == 0.2:
            _fps, frames, people = struct.unpack_from("<fIH", prefix, reader.read_offset)
            body_start = reader.read_offset + struct.calcsize("<fIH")
        elif version == 0.1:  # frames follow from the file's length (pose-format computes them so)
            _fps, _frames, people = struct.unpack_from("<HHH", prefix, reader.read_offset)
            body_start = reader.read_offset + struct.calcsize("<HHH")
            per_frame = people * points * (dims + 1) * 4
            frames = (size - body_start) // per_frame if per_frame else 0
        else:
            return  # other versions: pose-format's own reader decides (it refuses unknown ones)
    except Exception as err:  # a header pose-format cannot parse, or longer than the limit
        detail = f"{type(err).__name__}: {err}" if size <= MAX_HEADER_BYTES else f"no header within {MAX_HEADER_BYTES} bytes"
        raise DemonstrationError(f"not a readable .pose file ({detail})", path=path) from None
    if frames > MAX_FRAMES:
        raise DemonstrationError(f"declares {frames} frames, more than the {MAX_FRAMES} this nlo_lab reads", path=path)
    if people > MAX_PEOPLE:
        raise DemonstrationError(f"declares {people} people per frame, more than {MAX_PEOPLE}", path=path)
    body = frames * people * points * (dims + 1) * 4
    if version == 0.2 and body != size - body_start:
        raise DemonstrationError(
            f"declares {frames} frames x {people} people x {points} points ({body} bytes), "
            f"but the file holds {size - body_start} bytes after its header", path=path,
        )


def read_pose_file(path: Path):
    """The file's ``Pose`` and its arrays: ``(pose, data (T, P, N, D), mask, confidence (T, P, N), fps)``."""
    try:
        from pose_format import Pose
    except ImportError as err:  # pragma: no cover - a declared dependency
        raise DemonstrationError(f"reading .pose files needs the pose-format package ({err})", path=path) from None
    head, size = read_head(path, MAX_HEADER_BYTES, ".pose")
    check_pose_sizes(path, head, size)  # before the body is read or allocated
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise DemonstrationError(f"cannot read the file ({err.strerror or err})", path=path) from None
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

"""A robot's joint trajectory and its files (.npz, .json, .csv).

Writes are atomic (:mod:`nlo_lab.atomic_files`): the data goes to a temporary file in the
destination folder which is then renamed over the target, so a reader never sees half a
file; the file gets the umask-derived mode of an ordinary ``open``.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from nlo_lab.atomic_files import atomic_write_bytes
from nlo_lab.errors import NloLabError
from nlo_lab.files import as_path, read_input_bytes
from nlo_lab.npz_archive import Member, read_npz_members

__all__ = ["RobotTrajectory", "TrajectoryError", "FORMAT_VERSION", "MAX_TRAJECTORY_BYTES"]

FORMAT_VERSION = 2  # bump when the file layout changes (2: per-frame `time`)
READ_VERSIONS = (1, 2)  # version 1 files have no `time`: frames are 1/fps apart
MAX_TRAJECTORY_BYTES = 512 << 20  # a file (.npz or .json), and what an .npz's members may inflate to
_MAX_JOINTS, _MAX_NAME = 1024, 256  # joints of a trajectory, characters of a name
_NPZ_LAYOUT = {
    "format_version": Member("iu"),
    "robot": Member("U", max_chars=_MAX_NAME),
    "joint_names": Member("U", ndim=1, max_elements=_MAX_JOINTS, max_chars=_MAX_NAME),
    "angles": Member("f", ndim=2, max_elements=MAX_TRAJECTORY_BYTES // 8),
    "fps": Member("iuf"),
    "time": Member("f", ndim=1, max_elements=MAX_TRAJECTORY_BYTES // 8),
}


class TrajectoryError(NloLabError, ValueError):
    """A robot trajectory that is malformed, or a trajectory file that cannot be read."""


@dataclass(frozen=True)
class RobotTrajectory:
    """Joint angles of one robot over time.

    Attributes:
        robot: the robot's name (``"yumi"``, ``"nao"``, ``"pepper"`` or a spec name).
        joint_names: the actuated joints, in the column order of ``angles`` (n,).
        angles: ``(T, n)`` float64 joint angles [rad] (read-only array).
        fps: frames per second of the recording (> 0).
        time: ``(T,)`` per-frame times [s], starting at 0 and strictly increasing, or
            None = frames ``1/fps`` apart. A retimed trajectory (``nlo_lab.inference.retime``) is
            slower than the recording where the robot could not follow: its frames are
            further apart than ``1/fps`` there.
    """

    robot: str
    joint_names: tuple[str, ...]
    angles: np.ndarray = field(repr=False)
    fps: float
    time: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.robot, str) or not self.robot:
            raise TrajectoryError(f"robot must be a non-empty name, got {self.robot!r}")
        if isinstance(self.joint_names, (str, bytes)) or not isinstance(self.joint_names, (list, tuple, np.ndarray)):
            raise TrajectoryError(f"joint_names must be a list of names, got {type(self.joint_names).__name__}")
        names = tuple(self.joint_names)
        if not all(isinstance(n, str) and n for n in names):
            raise TrajectoryError(f"joint_names must be non-empty strings, got {list(names)!r}")
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise TrajectoryError(f"joint_names has duplicates: {dup}")
        try:
            angles = np.array(self.angles, dtype=np.float64)  # a private copy
        except (TypeError, ValueError) as exc:
            raise TrajectoryError(f"angles are not numeric: {exc}") from None
        if angles.ndim != 2 or angles.shape[1] != len(names):
            raise TrajectoryError(f"angles must be (T, {len(names)}) to match joint_names, got shape {angles.shape}")
        if angles.shape[0] == 0:
            raise TrajectoryError("angles have no frames")
        bad = ~np.isfinite(angles)
        if bad.any():
            frame, joint = (int(i) for i in np.argwhere(bad)[0])
            raise TrajectoryError(f"angles hold NaN or inf at frame {frame}, joint {names[joint]!r}")
        try:
            fps = float(self.fps)
        except (TypeError, ValueError):
            raise TrajectoryError(f"fps must be a number, got {self.fps!r}") from None
        if not math.isfinite(fps) or fps <= 0:
            raise TrajectoryError(f"fps must be > 0, got {self.fps!r}")
        angles.setflags(write=False)
        if self.time is not None:
            try:
                time = np.array(self.time, dtype=np.float64)
            except (TypeError, ValueError) as exc:
                raise TrajectoryError(f"time is not numeric: {exc}") from None
            if time.shape != (angles.shape[0],):
                raise TrajectoryError(f"time must be ({angles.shape[0]},) to match angles, got shape {time.shape}")
            if not np.isfinite(time).all():
                raise TrajectoryError(f"time holds NaN or inf at frame {int(np.argwhere(~np.isfinite(time))[0][0])}")
            if time[0] != 0.0 or (np.diff(time) <= 0).any():
                raise TrajectoryError("time must start at 0 and strictly increase")
            time.setflags(write=False)
            object.__setattr__(self, "time", time)
        object.__setattr__(self, "joint_names", names)
        object.__setattr__(self, "angles", angles)
        object.__setattr__(self, "fps", fps)

    # ---------------------------------------------------------------- access
    def __len__(self) -> int:
        return int(self.angles.shape[0])

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def times(self) -> np.ndarray:
        """``(T,)`` frame times [s]: :attr:`time`, or frames ``1/fps`` apart."""
        return np.arange(len(self)) / self.fps if self.time is None else self.time

    @property
    def duration(self) -> float:
        """Length in seconds: the last frame's time plus one frame period (``T / fps`` when not retimed)."""
        return float(self.times[-1]) + 1.0 / self.fps

    def at_frame_rate(self) -> RobotTrajectory:
        """The same samples ``1/fps`` apart, as recorded (a retimed trajectory without its retiming)."""
        return RobotTrajectory(self.robot, self.joint_names, self.angles, self.fps)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, RobotTrajectory):
            return NotImplemented
        return (
            self.robot == other.robot
            and self.joint_names == other.joint_names
            and self.fps == other.fps
            and np.array_equal(self.angles, other.angles)
            and np.array_equal(self.times, other.times)
        )

    __hash__ = None  # type: ignore[assignment]  # holds an array

    # ---------------------------------------------------------------- writers
    def save_npz(self, path: str | os.PathLike) -> Path:
        """Write ``robot``, ``joint_names``, ``angles``, ``fps``, ``time`` and a format version to ``path`` (.npz)."""
        buf = io.BytesIO()
        np.savez(
            buf,
            format_version=np.int64(FORMAT_VERSION),
            robot=np.str_(self.robot),
            joint_names=np.array(self.joint_names, dtype=np.str_),
            angles=self.angles,
            fps=np.float64(self.fps),
            time=np.asarray(self.times, dtype=np.float64),
        )
        return _atomic_write(path, buf.getvalue())

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict; angles as a list of per-frame lists [rad]."""
        return {
            "format_version": FORMAT_VERSION,
            "robot": self.robot,
            "joint_names": list(self.joint_names),
            "fps": self.fps,
            "time": self.times.tolist(),
            "angles": self.angles.tolist(),
        }

    def save_json(self, path: str | os.PathLike) -> Path:
        """Write :meth:`to_dict` as JSON (floats round-trip exactly)."""
        return _atomic_write(path, json.dumps(self.to_dict()).encode("utf-8"))

    def save_csv(self, path: str | os.PathLike) -> Path:
        """Write one row per frame: ``time_s`` (:attr:`times`) then one column per joint [rad] (header row first)."""
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(["time_s", *self.joint_names])
        for t, row in zip(self.times, self.angles, strict=True):
            writer.writerow([repr(float(t)), *(repr(float(v)) for v in row)])
        return _atomic_write(path, buf.getvalue().encode("utf-8"))

    # ---------------------------------------------------------------- readers
    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "<dict>") -> RobotTrajectory:
        """Build from :meth:`to_dict`'s layout; errors name ``source``."""
        if not isinstance(data, dict):
            raise TrajectoryError(f"{source}: expected a JSON object, got {type(data).__name__}")
        missing = [k for k in ("robot", "joint_names", "angles", "fps") if k not in data]
        if missing:
            raise TrajectoryError(f"{source}: missing field(s) {missing}")
        version = data.get("format_version", FORMAT_VERSION)
        if version not in READ_VERSIONS:
            raise TrajectoryError(f"{source}: format_version {version!r} is not supported (expected one of {READ_VERSIONS})")
        try:
            return cls(robot=data["robot"], joint_names=tuple(data["joint_names"]), angles=data["angles"], fps=data["fps"],
                       time=data.get("time"))
        except TrajectoryError as exc:
            raise TrajectoryError(f"{source}: {exc}") from None

    @classmethod
    def load(cls, path: str | os.PathLike) -> RobotTrajectory:
        """Read a trajectory written by :meth:`save_npz` (.npz) or :meth:`save_json` (.json).

        Raises:
            TrajectoryError: missing, unreadable or malformed file (the message names the file).
        """
        p = as_path(path)
        suffix = p.suffix.lower()
        if suffix not in (".npz", ".json"):
            raise TrajectoryError(f"{p}: unsupported trajectory file type {p.suffix!r} (expected .npz or .json)")
        if suffix == ".json":
            raw = read_input_bytes(p, kind="trajectory", max_bytes=MAX_TRAJECTORY_BYTES, error=TrajectoryError)
            try:
                data = json.loads(raw.decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
                raise TrajectoryError(f"{p}: not a readable JSON trajectory ({exc})") from None
            return cls.from_dict(data, source=str(p))
        data = read_npz_members(p, _NPZ_LAYOUT, kind="trajectory", max_bytes=MAX_TRAJECTORY_BYTES,
                                max_inflated=MAX_TRAJECTORY_BYTES, error=TrajectoryError)
        try:
            data = {
                "format_version": int(data.get("format_version", FORMAT_VERSION)),
                "robot": str(data["robot"]),
                "joint_names": [str(n) for n in data["joint_names"]],
                "angles": data["angles"],
                "fps": float(data["fps"]),
                "time": data.get("time"),  # absent in version 1 files
            }
        except KeyError as exc:
            raise TrajectoryError(f"{p}: missing field {exc.args[0]!r}") from None
        return cls.from_dict(data, source=str(p))


def _atomic_write(path: str | os.PathLike, payload: bytes) -> Path:
    """Write ``payload`` to ``path`` atomically (:mod:`nlo_lab.atomic_files`); a missing folder is a TrajectoryError."""
    target = Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise TrajectoryError(f"{target}: folder {folder} does not exist")
    return atomic_write_bytes(target, payload)

"""A live session kept: its landmarks as a ``.pose`` file and the robot's motion as a :class:`RobotTrajectory`.

:class:`LiveRecording` collects, for each processed camera frame, its time, MediaPipe's landmarks
and the robot's angles (never the images). The landmarks become a ``.pose`` file in pose-format's
Holistic layout, the one ``nlo-lab retarget``, :func:`nlo_lab.human.load_demonstration` and
notebook 08 read; the angles a :class:`~nlo_lab.inference.RobotTrajectory` whose ``time`` is the
camera's own (the frames a slow kernel dropped are simply not there), saved as ``.npz`` and
``.csv`` like ``nlo-lab retarget --out``. A ``.pose`` file has one frame rate: the session's
mean rate (frames over time). :func:`landmarks_from_pose` reads such a file back into frames of
landmarks, to replay it through :class:`~nlo_lab.live.LiveRetargeter` (``step_landmarks``).
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nlo_lab.atomic_files import atomic_write_bytes
from nlo_lab.errors import DemonstrationError, SettingsError
from nlo_lab.human.demonstration import FPS_RANGE
from nlo_lab.human.readers.pose import read_pose_file
from nlo_lab.inference import RobotTrajectory
from nlo_lab.live.holistic import COMPONENTS, FACE_POINTS, FrameLandmarks

__all__ = ["LiveRecording", "landmarks_from_pose"]


@dataclass
class LiveRecording:
    """The processed frames of a live session (see the module docstring).

    Attributes:
        robot: the robot's name; ``joint_names``: its actuated joints (the angles' columns).
        times: each frame's time [s] (the caller's ``t``); ``landmarks``: its landmarks; ``angles``: the robot's output.
        files: what :meth:`save` wrote (``{"pose": path, "trajectory": path, "csv": path}``).
    """

    robot: str
    joint_names: tuple[str, ...]
    times: list[float] = field(default_factory=list)
    landmarks: list[FrameLandmarks] = field(default_factory=list)
    angles: list[np.ndarray] = field(default_factory=list)
    files: dict[str, Path] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.times)

    def add(self, t: float, landmarks: FrameLandmarks, angles: np.ndarray) -> None:
        """Keep one processed frame."""
        self.times.append(float(t))
        self.landmarks.append(landmarks)
        self.angles.append(np.array(angles, dtype=np.float64))

    @property
    def fps(self) -> float:
        """The session's mean frame rate (the ``.pose`` file's ``fps``): frames over time, within the readers' range."""
        if len(self) < 2 or self.times[-1] <= self.times[0]:
            return 30.0
        return float(np.clip((len(self) - 1) / (self.times[-1] - self.times[0]), *FPS_RANGE))

    def _check(self) -> None:
        if not len(self):
            raise SettingsError("nothing was recorded: no camera frame was processed between record() and stop()")

    def trajectory(self) -> RobotTrajectory:
        """The robot's motion, on the camera's time base (``time`` from 0)."""
        self._check()
        t = np.asarray(self.times) - self.times[0]
        return RobotTrajectory(robot=self.robot, joint_names=tuple(self.joint_names), angles=np.stack(self.angles),
                               fps=self.fps, time=t)

    def pose(self):
        """The landmarks as a pose-format ``Pose`` (Holistic's components; the first frame's image size)."""
        # lazy: pose-format: only when a recording is saved
        from pose_format import Pose
        from pose_format.numpy import NumPyPoseBody
        from pose_format.pose_header import PoseHeader, PoseHeaderDimensions
        from pose_format.utils.holistic import holistic_components

        self._check()
        width, height = self.landmarks[0].width, self.landmarks[0].height
        data, conf = [], []
        for lm in self.landmarks:
            d, c = lm.pose_arrays()
            if (lm.width, lm.height) != (width, height):  # the page changed the frame size: pixels in the first size
                d = d * np.array([width / lm.width, height / lm.height, 1.0])
            data.append(d)
            conf.append(c)
        header = PoseHeader(version=0.2, dimensions=PoseHeaderDimensions(width=width, height=height, depth=0),
                            components=holistic_components("XYZC", 0))
        body = NumPyPoseBody(fps=self.fps, data=np.stack(data)[:, None].astype(np.float32),
                             confidence=np.stack(conf)[:, None].astype(np.float32))
        return Pose(header, body)

    def pose_bytes(self) -> bytes:
        """The ``.pose`` file's contents."""
        buffer = io.BytesIO()
        self.pose().write(buffer)
        return buffer.getvalue()

    def save(self, folder, name: str = "live") -> dict[str, Path]:
        """Write ``NAME.pose`` (the landmarks), ``NAME.npz`` and ``NAME.csv`` (the trajectory) into ``folder``.

        Each file is written atomically (a reader never sees half of one). Returns ``{"pose", "trajectory", "csv"}``.
        """
        if not isinstance(name, str) or not name or Path(name).name != name or name.startswith("."):
            raise SettingsError(f"name must be a plain file name without a folder, got {name!r}")
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        trajectory = self.trajectory()
        pose = atomic_write_bytes(folder / f"{name}.pose", self.pose_bytes())
        self.files = {"pose": pose, "trajectory": trajectory.save_npz(folder / f"{name}.npz"),
                      "csv": trajectory.save_csv(folder / f"{name}.csv")}
        return dict(self.files)


def _component_slices(names: list[str], sizes: list[int]) -> dict[str, slice]:
    out, start = {}, 0
    for name, n in zip(names, sizes, strict=True):
        out[name] = slice(start, start + n)
        start += n
    return out


def landmarks_from_pose(path) -> tuple[list[FrameLandmarks], np.ndarray]:
    """The frames of a Holistic ``.pose`` file as :class:`FrameLandmarks` and their times ``(T,)`` [s] (frame / fps).

    The file is read by the ``.pose`` reader's bounded reader (:func:`nlo_lab.human.readers.pose.read_pose_file`).

    Raises:
        DemonstrationError: an unreadable file, or one without Holistic's body, world and hand components.
    """
    path = Path(path)
    pose, data, mask, conf, fps = read_pose_file(path)
    comps = pose.header.components
    names, sizes = [c.name for c in comps], [len(c.points) for c in comps]
    wanted = dict(COMPONENTS)
    for name in ("POSE_LANDMARKS", "POSE_WORLD_LANDMARKS", "LEFT_HAND_LANDMARKS", "RIGHT_HAND_LANDMARKS"):
        if name not in names or sizes[names.index(name)] != wanted[name]:
            raise DemonstrationError(f"not a MediaPipe Holistic recording with world landmarks: no {name} of {wanted[name]} points",
                                     path=path, field=name)
    at = _component_slices(names, sizes)
    W, H = int(pose.header.dimensions.width), int(pose.header.dimensions.height)
    unscale = np.array([1.0 / W if W > 0 else 1.0, 1.0 / H if H > 0 else 1.0, 1.0])
    values = np.asarray(data[:, 0], dtype=np.float64)
    if values.shape[-1] == 2:
        values = np.concatenate([values, np.zeros(values.shape[:-1] + (1,))], axis=-1)
    values = values[..., :3]
    confidence = np.asarray(conf[:, 0], dtype=np.float64)
    seen = (confidence > 0) & ~np.asarray(mask[:, 0]).any(axis=-1)
    frames = []
    for t in range(values.shape[0]):
        body = at["POSE_LANDMARKS"]
        if not seen[t, body].any():
            frames.append(FrameLandmarks(width=W, height=H))
            continue
        hands = {}
        for side, name in (("left", "LEFT_HAND_LANDMARKS"), ("right", "RIGHT_HAND_LANDMARKS")):
            if seen[t, at[name]].all():
                hands[side] = values[t, at[name]]
        face = None
        if "FACE_LANDMARKS" in at and sizes[names.index("FACE_LANDMARKS")] == FACE_POINTS and seen[t, at["FACE_LANDMARKS"]].all():
            face = values[t, at["FACE_LANDMARKS"]]
        frames.append(FrameLandmarks(width=W, height=H, pose=values[t, body], pose_visibility=confidence[t, body],
                                     world=values[t, at["POSE_WORLD_LANDMARKS"]] * unscale, hands=hands, face=face))
    return frames, np.arange(len(frames)) / float(fps)

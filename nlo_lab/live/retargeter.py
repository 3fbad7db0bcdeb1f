"""Live retargeting: one camera frame in, one robot pose out, within the robot's limits on every frame.

:class:`LiveRetargeter` runs, for each frame a camera gives (:meth:`LiveRetargeter.step`):

1. MediaPipe Holistic in video (tracking) mode (:class:`~nlo_lab.live.holistic.HolisticTracker`);
2. the ``.pose`` reader's geometry made causal, with a One-Euro filter on the landmarks
   (:class:`~nlo_lab.live.causal_reader.CausalReader`): a one-frame demonstration in the body frame;
3. latent optimisation of that frame through the public pipeline (``RetargetConfig(...).build()``,
   :meth:`~nlo_lab.pipeline.Retargeter.optimize_frame`), warm-started from the previous frame's latent
   (the encoder's guess when the person (re)appears);
4. the robot's limits (:class:`~nlo_lab.live.motion_limits.MotionLimits`): the output moves towards the
   optimised pose by at most each joint's velocity limit times the time since the last frame (the
   caller's ``t``), inside the joint limits. The first output is the rest pose.

When nobody is seen, the robot holds its last target for ``hold_seconds`` (MediaPipe loses a person
for a frame now and then), then eases to its rest pose (``robot.neutral_q``, time constant
``ease_seconds``) while the tracking state (filters, warm start) is forgotten.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.human import Demonstration
from nlo_lab.inference import OptimizeSettings, RetargetInputs
from nlo_lab.live.causal_reader import CausalReader, FilterSettings
from nlo_lab.live.holistic import FrameLandmarks, HolisticTracker
from nlo_lab.live.motion_limits import MotionLimits, ease_toward
from nlo_lab.objective import LossWeights
from nlo_lab.pipeline import RetargetConfig
from nlo_lab.robot import Robot, load_robot
from nlo_lab.settings import ITERATIONS_RANGE, check_int, check_positive

__all__ = ["LiveFrame", "LiveRetargeter", "MAX_IMAGE_SIDE", "TIMINGS"]

MAX_IMAGE_SIDE = 4096  # [px] a larger frame is refused (a camera frame, not a poster)
TIMINGS = ("mediapipe", "filter", "optimization")  # the parts of a step's latency, in order [ms]


@dataclass
class LiveFrame:
    """What :meth:`LiveRetargeter.step` returns for one camera frame.

    Attributes:
        t: the frame's time [s] (the caller's).
        angles: ``(n,)`` the robot's joint angles [rad], in :attr:`joint_names` order: inside the joint limits,
            and no joint faster than its velocity limit since the previous frame.
        joint_names: the robot's actuated joints, each once, in the robot's order.
        found: a person was seen in this frame (and their shoulders).
        state: ``"tracking"`` (following the person), ``"holding"`` (nobody, the last pose kept for a moment)
            or ``"resting"`` (nobody: easing to the rest pose).
        latency_ms: wall time of :meth:`~LiveRetargeter.step` [ms]; ``timings``: its parts
            (:data:`TIMINGS`: ``mediapipe``, ``filter`` (the causal reader and its filter), ``optimization``) [ms].
        landmarks: MediaPipe's landmarks of the frame (image and world), also when nobody is seen.
        demonstration: the one-frame demonstration retargeted (body frame, filtered), None when nobody is seen.
        target: ``(n,)`` the optimised angles before the velocity limits, None when nobody is seen.
        loss: the optimised objective of the frame, None when nobody is seen.
        limited: the velocity limits held the output back from the target in this frame.
    """

    t: float
    angles: np.ndarray
    joint_names: tuple[str, ...]
    found: bool
    state: str
    latency_ms: float
    timings: dict[str, float] = field(default_factory=dict)
    landmarks: FrameLandmarks | None = None
    demonstration: Demonstration | None = None
    target: np.ndarray | None = None
    loss: float | None = None
    limited: bool = False


class LiveRetargeter:
    """A camera stream to a robot, frame by frame (see the module docstring).

    Args:
        robot: a robot name (``"yumi"``, ``"nao"``, ``"pepper"``, a spec file) or a loaded :class:`~nlo_lab.robot.Robot`.
        iterations: most Adam steps per frame (warm-started; the patience stop often ends sooner).
        weights: loss weights (:class:`~nlo_lab.objective.LossWeights`; default the pipeline's); change them with :attr:`weights`.
        filter: the landmarks' One-Euro filter (:class:`~nlo_lab.live.causal_reader.FilterSettings`); change it with :meth:`set_filter`.
        model: a trained model for the robot; None: the shipped checkpoint.
        hold_seconds: keep the last pose this long when nobody is seen [s].
        ease_seconds: then ease to the rest pose with this time constant [s].
        speed_fraction: move at most this fraction of each joint's velocity limit (1: the limit itself).
        tracker: what finds the landmarks; None: a :class:`~nlo_lab.live.holistic.HolisticTracker` (made on first use).

    Raises:
        UnknownRobotError: an unknown robot name. CheckpointError: no trained model for it.
        SettingsError: a setting out of range. InstallationError: no mediapipe (the ``video`` extra), at the first frame.
    """

    def __init__(self, robot: str | Robot = "yumi", iterations: int = 30, *, weights: LossWeights | None = None,
                 filter: FilterSettings | None = None, model=None, hold_seconds: float = 0.3, ease_seconds: float = 0.5,
                 speed_fraction: float = 1.0, tracker=None):
        self.robot = robot if isinstance(robot, Robot) else load_robot(robot)
        self.iterations = check_int("iterations", iterations, 1, ITERATIONS_RANGE[1])
        self.hold_seconds = check_positive("hold_seconds", hold_seconds)
        self.ease_seconds = check_positive("ease_seconds", ease_seconds)
        self.limits = MotionLimits.of(self.robot, speed_fraction)
        self.reader = CausalReader(filter)
        self._tracker = tracker
        self._weights = weights or LossWeights()
        self._pipeline = RetargetConfig(self.robot, settings=self._settings(), weights=self._weights, model=model).build()
        self.rest = self.robot.neutral_q.detach().cpu().double().numpy()
        self.reset()

    # ---------------------------------------------------------------- settings that act on the running stream
    def _settings(self) -> OptimizeSettings:
        return OptimizeSettings(init="encoder", iterations=self.iterations)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The robot's actuated joints, in its order (the columns of every frame's ``angles``)."""
        return tuple(self.robot.joint_names)

    @property
    def weights(self) -> LossWeights:
        """The loss weights; set new ones and the next frame is optimised with them."""
        return self._weights

    @weights.setter
    def weights(self, weights: LossWeights) -> None:
        if not isinstance(weights, LossWeights):
            raise SettingsError(f"weights must be LossWeights, got {type(weights).__name__}")
        self._weights = weights
        self._pipeline = RetargetConfig(self.robot, settings=self._settings(), weights=weights, model=self._pipeline.model).build()

    def set_weights(self, **weights: float) -> None:
        """Change some loss weights (``ee=500, tip=0``); the others stay."""
        self.weights = LossWeights(**{**self._weights.as_dict(), **weights})

    def set_iterations(self, iterations: int) -> None:
        """The most Adam steps per frame from the next frame on."""
        self.iterations = check_int("iterations", iterations, 1, ITERATIONS_RANGE[1])
        self._pipeline = RetargetConfig(self.robot, settings=self._settings(), weights=self._weights, model=self._pipeline.model).build()

    @property
    def filter(self) -> FilterSettings:
        """The landmarks' One-Euro settings (read); change them with :meth:`set_filter`."""
        return self.reader.settings

    def set_filter(self, **settings: float) -> None:
        """Change the One-Euro filter (``min_cutoff`` [Hz], ``beta``, ``d_cutoff`` [Hz]); the next frame uses it."""
        self.reader.set_filter(**settings)

    @property
    def tracker(self):
        """The landmark finder (MediaPipe Holistic, started on first use: importing mediapipe takes seconds)."""
        if self._tracker is None:
            self._tracker = HolisticTracker()
        return self._tracker

    def reset(self) -> None:
        """Back to the start: the rest pose, no past (filters, warm start, times)."""
        self.reader.reset()
        self._q = self.rest.copy()
        self._target: np.ndarray | None = None
        self._z: torch.Tensor | None = None
        self._t: float | None = None
        self._last_seen = -math.inf

    def close(self) -> None:
        """Release MediaPipe (its graph's threads and models)."""
        if self._tracker is not None and hasattr(self._tracker, "close"):
            self._tracker.close()
        self._tracker = None

    def __enter__(self) -> LiveRetargeter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---------------------------------------------------------------- one frame
    def step(self, image: np.ndarray, t: float) -> LiveFrame:
        """Retarget one camera frame.

        Args:
            image: ``(H, W, 3)`` RGB ``uint8`` (at most :data:`MAX_IMAGE_SIDE` pixels a side).
            t: its time [s], later than the previous frame's (the camera's clock: velocities use it).

        Returns:
            A :class:`LiveFrame`, also when nobody is seen; its ``angles`` are within the limits.

        Raises:
            SettingsError: an image of another shape or type, a time that is not finite or not after the last one.
        """
        image = _check_image(image)
        t = self._check_time(t)
        start = time.perf_counter()
        landmarks = self.tracker.process(image)
        return self._step(landmarks, t, start, {"mediapipe": 1000 * (time.perf_counter() - start)})

    def step_landmarks(self, landmarks: FrameLandmarks, t: float) -> LiveFrame:
        """:meth:`step` from landmarks already found (a recorded ``.pose`` replayed: :func:`~nlo_lab.live.landmarks_from_pose`)."""
        if not isinstance(landmarks, FrameLandmarks):
            raise SettingsError(f"landmarks must be FrameLandmarks, got {type(landmarks).__name__}")
        t = self._check_time(t)
        return self._step(landmarks, t, time.perf_counter(), {"mediapipe": 0.0})

    def _check_time(self, t) -> float:
        try:
            t = float(t)
        except (TypeError, ValueError):
            raise SettingsError(f"t must be a time in seconds, got {t!r}") from None
        if not math.isfinite(t):
            raise SettingsError(f"t must be finite, got {t}")
        if self._t is not None and t <= self._t:
            raise SettingsError(f"frames must come in time order: t = {t} s is not after the previous frame's {self._t} s")
        return t

    def _step(self, landmarks: FrameLandmarks, t: float, start: float, timings: dict[str, float]) -> LiveFrame:
        mark = time.perf_counter()
        demo = self.reader.read(landmarks, t)
        timings["filter"] = 1000 * (time.perf_counter() - mark)
        mark = time.perf_counter()
        target, loss = None, None
        if demo is not None:
            target, loss = self._optimize(demo)
        timings["optimization"] = 1000 * (time.perf_counter() - mark)
        dt = 0.0 if self._t is None else t - self._t
        if target is not None:
            self._last_seen, self._target, state = t, target, "tracking"
            goal = target
        elif t - self._last_seen <= self.hold_seconds and self._target is not None:
            state, goal = "holding", self._target
        else:
            if self._z is not None or self._target is not None:  # the person left: start again from the encoder
                self.reader.reset()
                self._z, self._target = None, None
            state, goal = "resting", ease_toward(self._q, self.rest, dt, self.ease_seconds)
        q = self.limits.step(self._q, goal, dt)
        limited = bool(np.abs(q - self.limits.clip(goal)).max() > 1e-12)
        self._q, self._t = q, t
        return LiveFrame(t=t, angles=q.copy(), joint_names=self.joint_names, found=demo is not None, state=state,
                         latency_ms=1000 * (time.perf_counter() - start), timings=timings, landmarks=landmarks,
                         demonstration=demo, target=target, loss=loss, limited=limited)

    def _inputs(self, demo: Demonstration) -> RetargetInputs:
        """The pipeline's inputs of the one frame, with the demonstrator's lengths of the recent past.

        Offline, the objective scales the human to the robot by the recording's median arm, forearm and hand
        lengths; one frame's own lengths would rescale every frame by MediaPipe's noise (a forearm pointing at the
        camera measures half its length), so the reader's running medians take their place.
        """
        inputs = self._pipeline.inputs(demo)
        targets = inputs.targets
        recent = self.reader.body_lengths()

        def length(name: str) -> torch.Tensor:
            own = getattr(targets, name)
            value = torch.as_tensor(recent[name], dtype=own.dtype, device=own.device).reshape(1, 2)
            return torch.where(torch.isfinite(value) & (value > 0), value, own)

        targets = dataclasses.replace(targets, arm_length=length("arm_length"), fore_length=length("fore_length"),
                                      hand_length=length("hand_length"))
        return RetargetInputs(targets, inputs.encoder)

    def _optimize(self, demo: Demonstration) -> tuple[np.ndarray | None, float | None]:
        """The frame's optimised angles and loss (None, None when the loss is not finite: the frame is skipped)."""
        inputs = self._inputs(demo)
        result = self._pipeline.optimize_frame(inputs, 0, z0=self._z)
        q = result.q[0].detach().cpu().double().numpy()
        loss = float(result.loss[0])
        if not (np.isfinite(q).all() and math.isfinite(loss)) or result.z is None:
            self._z = None
            return None, None
        self._z = result.z.detach()
        return q, loss


def _check_image(image) -> np.ndarray:
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        shape = getattr(image, "shape", None)
        raise SettingsError(f"image must be an (H, W, 3) uint8 RGB array, got {type(image).__name__} "
                            f"{tuple(shape) if shape is not None else ''} {getattr(image, 'dtype', '')}".rstrip())
    h, w = image.shape[:2]
    if not (1 <= h <= MAX_IMAGE_SIDE and 1 <= w <= MAX_IMAGE_SIDE):
        raise SettingsError(f"image must be 1 to {MAX_IMAGE_SIDE} pixels a side, got {w}x{h}")
    return image

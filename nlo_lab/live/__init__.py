"""Live retargeting: a camera in the learner's browser drives the robot, frame by frame.

* :mod:`~nlo_lab.live.one_euro`: :class:`OneEuroFilter`, the causal landmark filter.
* :mod:`~nlo_lab.live.holistic`: :class:`HolisticTracker` (MediaPipe Holistic in video mode), :class:`FrameLandmarks`.
* :mod:`~nlo_lab.live.causal_reader`: :class:`CausalReader`, the ``.pose`` reader's geometry from the present and the past only.
* :mod:`~nlo_lab.live.motion_limits`: :class:`MotionLimits`, joint limits and rate limiting between successive outputs.
* :mod:`~nlo_lab.live.retargeter`: :class:`LiveRetargeter` (``.step(image, t)`` -> :class:`LiveFrame`).
* :mod:`~nlo_lab.live.frame_message`: a camera frame from the page (JPEG over the comm), checked and decoded.
* :mod:`~nlo_lab.live.camera_view`: :class:`CameraView`, the browser's camera driving the robot (anywidget).
* :mod:`~nlo_lab.live.controls`: :class:`LiveControls`, sliders (loss weights, iterations, filter) acting on the running stream.
* :mod:`~nlo_lab.live.plots`: :func:`plot_latency`, where each frame's latency went.
* :mod:`~nlo_lab.live.recording`: :class:`LiveRecording` (a session as a ``.pose`` file and a trajectory), :func:`landmarks_from_pose`.

mediapipe (the ``video`` extra) is imported when the first frame is processed.
"""

from nlo_lab.live.camera_view import FRAME_SIZE, JPEG_QUALITY, SPLIT, WINDOW_SECONDS, CameraView
from nlo_lab.live.causal_reader import HISTORY_SECONDS, POSE_INDEX, SPIKE_SPEED, UP_SECONDS, CausalReader, FilterSettings
from nlo_lab.live.controls import WEIGHT_SLIDERS, LiveControls
from nlo_lab.live.frame_message import MAX_FRAME_BYTES, FrameMessage, FrameMessageError, decode_frame_message, encode_frame
from nlo_lab.live.holistic import FrameLandmarks, HolisticTracker
from nlo_lab.live.motion_limits import MotionLimits, ease_toward
from nlo_lab.live.one_euro import OneEuroFilter
from nlo_lab.live.plots import plot_latency
from nlo_lab.live.recording import LiveRecording, landmarks_from_pose
from nlo_lab.live.retargeter import TIMINGS, LiveFrame, LiveRetargeter

__all__ = [
    "OneEuroFilter",
    "FrameLandmarks", "HolisticTracker",
    "CausalReader", "FilterSettings", "HISTORY_SECONDS", "UP_SECONDS", "SPIKE_SPEED", "POSE_INDEX",
    "MotionLimits", "ease_toward",
    "LiveFrame", "LiveRetargeter", "TIMINGS",
    "LiveRecording", "landmarks_from_pose",
    "FrameMessage", "FrameMessageError", "decode_frame_message", "encode_frame", "MAX_FRAME_BYTES",
    "LiveControls", "WEIGHT_SLIDERS", "plot_latency",
    "CameraView", "FRAME_SIZE", "JPEG_QUALITY", "SPLIT", "WINDOW_SECONDS",
]

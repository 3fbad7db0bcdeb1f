"""MediaPipe Holistic on a live stream: one instance in video (tracking) mode, one frame at a time.

The offline reader runs Holistic through pose-format on whole videos
(:mod:`nlo_lab.human.readers.video`); a camera gives one frame at a time, so this module
calls mediapipe directly, with the same model (:data:`~nlo_lab.human.readers.video.MODEL_COMPLEXITY`,
the pose model the mediapipe wheel carries: nothing is downloaded) and the same settings
(``static_image_mode=False``: after the first detection MediaPipe tracks the person from frame
to frame and smooths its landmarks). Its native log lines ("INFO: Created TensorFlow Lite
XNNPACK delegate", absl's warnings) are silenced while it starts and runs.

:class:`FrameLandmarks` holds one frame's landmarks in pose-format's conventions (the ones
:mod:`nlo_lab.human.readers.pose` reads): image landmarks as ``(x * width, y * height, z)``, the world
landmarks in metres, each hand's 21 points, the face mesh; :meth:`FrameLandmarks.pose_arrays`
lays them out as a ``.pose`` file's frame (:mod:`nlo_lab.live.recording`).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

import numpy as np

from nlo_lab.errors import InstallationError
from nlo_lab.human.readers.video import MODEL_COMPLEXITY, native_output_silenced

__all__ = ["BODY_POINTS", "FACE_POINTS", "HAND_POINTS", "COMPONENTS", "FrameLandmarks", "HolisticTracker", "mediapipe_module"]

BODY_POINTS = 33  # MediaPipe's pose landmarks (PoseLandmark), image and world
HAND_POINTS = 21  # per hand (HandLandmark)
FACE_POINTS = 468  # the face mesh without irises (Holistic's default, refine_face_landmarks=False)
# The components of a Holistic frame in pose-format's order (pose_format.utils.holistic.holistic_components):
COMPONENTS = (("POSE_LANDMARKS", BODY_POINTS), ("FACE_LANDMARKS", FACE_POINTS), ("LEFT_HAND_LANDMARKS", HAND_POINTS),
              ("RIGHT_HAND_LANDMARKS", HAND_POINTS), ("POSE_WORLD_LANDMARKS", BODY_POINTS))


def mediapipe_module(name: str = "mediapipe"):
    """Import ``name`` of the ``video`` extra; its absence is one :class:`~nlo_lab.errors.InstallationError` line."""
    try:
        return importlib.import_module(name)
    except ImportError as err:
        raise InstallationError(f"live retargeting needs the video extra: pip install \"nlo_lab[video]\" ({err})") from None


@dataclass(frozen=True)
class FrameLandmarks:
    """MediaPipe Holistic's landmarks of one frame (pose-format's conventions; None: not seen).

    Attributes:
        width, height: the image's size [px].
        pose: ``(33, 3)`` image landmarks ``(x * width, y * height, z)``; ``pose_visibility`` ``(33,)``.
        world: ``(33, 3)`` world landmarks [m] (MediaPipe's: about the hips; x right, y down, z away from the camera).
        hands: ``{"left": (21, 3), "right": (21, 3)}`` image landmarks of each hand seen (the person's left and right).
        face: ``(468, 3)`` the face mesh's image landmarks.
    """

    width: int
    height: int
    pose: np.ndarray | None = None
    pose_visibility: np.ndarray | None = None
    world: np.ndarray | None = None
    hands: dict | None = None
    face: np.ndarray | None = None

    @property
    def found(self) -> bool:
        """A person was seen (the body's landmarks, image and world)."""
        return self.pose is not None and self.world is not None

    def pose_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """``(data (543, 3), confidence (543,))``: the frame as pose-format's Holistic writes it (:data:`COMPONENTS`
        in order; the world landmarks scaled by the image size like pose-format's; zeros and confidence 0 where unseen)."""
        parts = []
        hands = self.hands or {}
        scale = np.array([self.width, self.height, 1.0])
        for name, n in COMPONENTS:
            values, conf = {
                "POSE_LANDMARKS": (self.pose, self.pose_visibility),
                "FACE_LANDMARKS": (self.face, None),
                "LEFT_HAND_LANDMARKS": (hands.get("left"), None),
                "RIGHT_HAND_LANDMARKS": (hands.get("right"), None),
                "POSE_WORLD_LANDMARKS": (None if self.world is None else self.world * scale, self.pose_visibility),
            }[name]
            if values is None:
                parts.append((np.zeros((n, 3)), np.zeros(n)))
            else:
                parts.append((np.asarray(values, np.float64), np.ones(n) if conf is None else np.asarray(conf, np.float64)))
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def _points(landmarks, scale: np.ndarray) -> np.ndarray | None:
    if landmarks is None:
        return None
    return np.array([(p.x, p.y, p.z) for p in landmarks.landmark], dtype=np.float64) * scale


class HolisticTracker:
    """One MediaPipe Holistic instance in video mode: :meth:`process` one RGB frame after the other.

    Args:
        smooth_landmarks: MediaPipe's own smoothing of the pose landmarks across frames (its default, as offline).
        min_detection_confidence, min_tracking_confidence: MediaPipe's thresholds (its defaults).

    Raises:
        InstallationError: mediapipe (the ``video`` extra) is not installed.
    """

    def __init__(self, smooth_landmarks: bool = True, min_detection_confidence: float = 0.5, min_tracking_confidence: float = 0.5):
        mp = mediapipe_module()
        # absl's "WARNING: All log messages before absl::InitializeLog() ...", and TensorFlow Lite's "INFO: Created
        # TensorFlow Lite XNNPACK delegate for CPU." that MediaPipe's graph threads print while they load the models:
        # the graph is started and run once on a blank frame in one silenced block, so no line escapes between two.
        with native_output_silenced():
            self._holistic = mp.solutions.holistic.Holistic(
                static_image_mode=False, model_complexity=MODEL_COMPLEXITY, smooth_landmarks=smooth_landmarks,
                min_detection_confidence=min_detection_confidence, min_tracking_confidence=min_tracking_confidence)
            self._holistic.process(np.full((256, 256, 3), 255, np.uint8))

    def process(self, image: np.ndarray) -> FrameLandmarks:
        """The landmarks of one ``(H, W, 3)`` RGB ``uint8`` frame (the next of the stream)."""
        if self._holistic is None:
            raise RuntimeError("this HolisticTracker was closed")
        h, w = image.shape[:2]
        with native_output_silenced():  # TensorFlow Lite's delegate line on the first frame
            result = self._holistic.process(np.ascontiguousarray(image))
        image_scale = np.array([w, h, 1.0])
        pose = _points(result.pose_landmarks, image_scale)
        visibility = None if pose is None else np.array([p.visibility for p in result.pose_landmarks.landmark], np.float64)
        hands = {side: pts for side, pts in (("left", _points(result.left_hand_landmarks, image_scale)),
                                             ("right", _points(result.right_hand_landmarks, image_scale))) if pts is not None}
        return FrameLandmarks(width=w, height=h, pose=pose, pose_visibility=visibility,
                              world=_points(result.pose_world_landmarks, np.ones(3)), hands=hands,
                              face=_points(result.face_landmarks, image_scale))

    def close(self) -> None:
        """Release MediaPipe's graph (its threads and models)."""
        if self._holistic is not None:
            self._holistic.close()
            self._holistic = None

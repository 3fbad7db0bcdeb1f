"""Reader of videos (``.mp4``, ``.mov``, ``.webm``, ``.avi``): MediaPipe Holistic through pose-format.

The pipeline is video -> MediaPipe Holistic (pose-format's
:func:`pose_format.utils.holistic.load_holistic`, which keeps the world landmarks as
the ``POSE_WORLD_LANDMARKS`` component) -> a ``.pose`` recording -> the ``.pose``
reader (:func:`nlo_lab.human.io_pose.load_pose`). So a video and the ``.pose`` saved
from it give the same :class:`Demonstration`, and every convention of the ``.pose``
reader (body frame, metres, gap filling, masks) applies.

Needs the ``video`` extra (``pip install "nlo_lab[video]"``: mediapipe 0.10.21, the
last release whose wheel bundles the Holistic models, and opencv, which comes with
it). Frames are read by :mod:`nlo_lab.human.video_frames`, the landmarks estimated by
:mod:`nlo_lab.human.pose_estimation` (on every core available, the same landmarks for any number).

Faults end in :class:`~nlo_lab.errors.DemonstrationError` naming the file: missing
or empty file, contents that are not a video container, a video no frame of which
decodes, a truncated video (fewer frames decode than its header announces), no
person in any frame. Hands never seen are not an error: a :class:`VideoWarning`
says so and the fingers are masked.
"""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

from nlo_lab.errors import DemonstrationError
from nlo_lab.human.demonstration import Demonstration
from nlo_lab.human.io_pose import load_pose
from nlo_lab.human.pose_estimation import MODEL_COMPLEXITY, SEGMENT_FRAMES, VideoPose, estimate_pose, pose_workers
from nlo_lab.human.video_frames import VIDEO_SUFFIXES, read_video_frames, video_info

__all__ = [
    "VIDEO_SUFFIXES",
    "MODEL_COMPLEXITY",
    "SEGMENT_FRAMES",
    "VideoWarning",
    "VideoPose",
    "pose_workers",
    "video_info",
    "read_video_frames",
    "estimate_pose",
    "pose_to_demonstration",
    "load_video",
]

_HANDS = ("left", "right")


class VideoWarning(UserWarning):
    """Something about a video the user should know that does not stop the retargeting."""


def pose_to_demonstration(video: VideoPose) -> Demonstration:
    """The :class:`Demonstration` of a video's landmarks: exactly what the ``.pose`` reader makes of them.

    The landmarks are written to a private temporary ``.pose`` file and read back with
    :func:`nlo_lab.human.io_pose.load_pose`, so the result equals reading the file that
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
        DemonstrationError: see :func:`estimate_pose` and :func:`nlo_lab.human.io_pose.load_pose`.
    """
    video = estimate_pose(path, threads=threads, progress=progress)
    demo = pose_to_demonstration(video)
    if save_pose is not None:
        from nlo_lab.atomic_files import atomic_write_bytes

        atomic_write_bytes(save_pose, video.to_bytes())
    return demo

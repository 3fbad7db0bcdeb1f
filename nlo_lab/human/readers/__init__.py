"""The readers of human demonstrations, one module per format, and the one entry point that dispatches on the extension.

- :mod:`~nlo_lab.human.readers.pose`: MediaPipe Holistic recordings (``.pose``, pose-format),
- :mod:`~nlo_lab.human.readers.video`: videos (frames, MediaPipe Holistic, then the ``.pose`` reader),
- :mod:`~nlo_lab.human.readers.h5`: the HDF5 layout of the paper's authors,
- :mod:`~nlo_lab.human.readers.npz`: the package's own archive (and its writer, :func:`save_npz`).

Every reader checks its file first with the one shared input-file check,
:mod:`nlo_lab.files` (a regular file within the format's limit, checked before it is
opened), and reads only what it was named: readers never write anything.
"""

from __future__ import annotations

from nlo_lab.errors import DemonstrationError
from nlo_lab.files import as_path
from nlo_lab.human.demonstration import Demonstration
from nlo_lab.human.readers.h5 import load_h5_first, load_h5_sequences
from nlo_lab.human.readers.npz import load_npz, save_npz
from nlo_lab.human.readers.pose import load_pose
from nlo_lab.human.readers.video import (
    VIDEO_SUFFIXES,
    VideoPose,
    VideoWarning,
    estimate_pose,
    estimate_segment,
    join_segments,
    load_video,
    pose_to_demonstration,
    read_video_frames,
    segment_bounds,
    video_info,
)

__all__ = [
    "SUFFIXES",
    "VIDEO_SUFFIXES",
    "load_demonstration",
    "load_pose",
    "load_video",
    "load_npz",
    "save_npz",
    "load_h5_sequences",
    "load_h5_first",
    "estimate_pose",
    "pose_to_demonstration",
    "read_video_frames",
    "video_info",
    "segment_bounds",
    "estimate_segment",
    "join_segments",
    "VideoPose",
    "VideoWarning",
]

SUFFIXES = {".npz": load_npz, ".pose": load_pose, ".h5": load_h5_first, ".hdf5": load_h5_first,
            **{suffix: load_video for suffix in VIDEO_SUFFIXES}}


def load_demonstration(path) -> Demonstration:
    """Read a demonstration, choosing the reader by the file extension.

    - ``.npz``: the package's own archive (:func:`save_npz`);
    - ``.pose``: a MediaPipe Holistic recording (:func:`~nlo_lab.human.readers.pose.load_pose`);
    - ``.h5`` / ``.hdf5``: the authors' HDF5 layout; returns the FIRST sequence
      (sorted group names) only; use :func:`load_h5_sequences` for all of them;
    - ``.mp4`` / ``.mov`` / ``.webm`` / ``.avi``: a video, through MediaPipe Holistic
      (:func:`~nlo_lab.human.readers.video.load_video`; needs the ``video`` extra).

    Readers never write anything.

    Args:
        path: the file.

    Returns:
        The :class:`Demonstration`, in the body frame, in metres.

    Raises:
        DemonstrationError: unknown extension, or any problem the reader finds
            (the message names the file, and the frame and field where they apply).
        SettingsTypeError, SettingsError: ``path`` is not a file path.
    """
    path = as_path(path)
    reader = SUFFIXES.get(path.suffix.lower())
    if reader is None:
        raise DemonstrationError(
            f"unknown demonstration file extension {path.suffix!r}; expected one of {sorted(SUFFIXES)}", path=path
        )
    return reader(path)

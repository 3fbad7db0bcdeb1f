"""Reading and writing demonstrations: one entry point that dispatches on the file extension."""

from __future__ import annotations

from nlo_lab.errors import DemonstrationError
from nlo_lab.files import as_path
from nlo_lab.human.demonstration import Demonstration
from nlo_lab.human.io_h5 import load_h5_first, load_h5_sequences
from nlo_lab.human.io_npz import load_npz, save_npz
from nlo_lab.human.io_pose import load_pose
from nlo_lab.human.io_video import VIDEO_SUFFIXES, load_video

__all__ = ["SUFFIXES", "load_demonstration", "save_npz", "load_h5_sequences"]

SUFFIXES = {".npz": load_npz, ".pose": load_pose, ".h5": load_h5_first, ".hdf5": load_h5_first,
            **{suffix: load_video for suffix in VIDEO_SUFFIXES}}


def load_demonstration(path) -> Demonstration:
    """Read a demonstration, choosing the reader by the file extension.

    - ``.npz``: the package's own archive (:func:`save_npz`);
    - ``.pose``: a MediaPipe Holistic recording (:func:`nlo_lab.human.io_pose.load_pose`);
    - ``.h5`` / ``.hdf5``: the authors' HDF5 layout; returns the FIRST sequence
      (sorted group names) only; use :func:`load_h5_sequences` for all of them;
    - ``.mp4`` / ``.mov`` / ``.webm`` / ``.avi``: a video, through MediaPipe Holistic
      (:func:`nlo_lab.human.io_video.load_video`; needs the ``video`` extra).

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

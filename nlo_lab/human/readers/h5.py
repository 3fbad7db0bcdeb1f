"""Reader of the HDF5 layout of the paper's authors (the paper's data set).

One group per sequence (word or sentence); per side ``s`` in ``l``/``r``:

- ``{s}_up_pos``, ``{s}_fr_pos``, ``{s}_hd_pos`` ``(T, 3)``: shoulder, elbow, wrist [m] (required);
- ``{s}_up_quat``, ``{s}_fr_quat``, ``{s}_hd_quat`` ``(T, 4)``: orientations ``(x, y, z, w)``
  (only ``hd_quat`` is used; the others are checked when present);
- ``{s}_glove_angle`` ``(T, 14)`` finger joint angles [deg] (checked, not used: the
  finger points come from ``glove_pos``);
- optional ``{s}_glove_pos`` ``(T, 16, 3)`` finger points [m], in the layout
  :data:`GLOVE_POINTS`: point 0 the wrist, then per finger (thumb, index, middle,
  ring, pinky) three points base, middle, tip.

Assumptions (the dataset is not public, so these are documented choices):

- The capture frame's +Z is up. The body frame is rebuilt per frame: origin at the
  shoulder midpoint, Y from the right to the left shoulder, Z = capture +Z made
  orthogonal to Y, X = Y x Z (forward).
- ``glove_pos`` is expressed with the capture frame's axes in metres; the hand is
  translated so that its wrist point coincides with ``{s}_hd_pos`` (the same rule as
  the ``.pose`` reader), so absolute and wrist-relative glove points both work.
- The wrist orientation comes from ``glove_pos`` when present (wrist, index base,
  middle base, pinky base, see :func:`wrist_frame_from_hand`); otherwise from
  ``{s}_hd_quat``, assuming the quaternion's frame already follows our wrist
  convention (x along the hand, y pinky -> index), rotated into the body frame.
  Without either the orientation is masked; without ``glove_pos`` the fingers are masked.
- fps: attribute ``fps`` on the group, else on the file, else :data:`DEFAULT_FPS`.
- A group is a sentence when its name contains :data:`SENTENCE_MARKER` (case-insensitive).

Only the file named is read. Refused before any data is read: links to other files
(external links), virtual datasets (their data lives in other files), datasets stored
in external raw files, any storage not inside the file, compression filters other than
HDF5's own (deflate, shuffle, Fletcher-32, scale-offset, n-bit; and LZF), chunks larger
than :data:`MAX_CHUNK_BYTES`, a file of more than :data:`MAX_H5_BYTES`, more than
:data:`MAX_GROUPS` entries at its root, and more than
:data:`~nlo_lab.human.demonstration.MAX_FRAMES` frames in all its sequences together.

The HDF5 library runs in a process of its own (:mod:`nlo_lab.human.readers.h5_extract`, given the open file):
some corrupt files keep libhdf5 looping for ever, out of reach of anything in the same process, or crash it.
Such a file is refused after :data:`H5_CPU_SECONDS` of CPU time or when the library dies.
"""

from __future__ import annotations

import io
import json
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np

from nlo_lab.errors import DemonstrationError
from nlo_lab.files import as_path, open_input
from nlo_lab.human.demonstration import FPS_RANGE, MAX_FRAMES, Demonstration
from nlo_lab.human.transforms import body_frame_from_shoulders, check_arm_lengths, quat_to_matrix, wrist_frame_from_hand

__all__ = ["DEFAULT_FPS", "SENTENCE_MARKER", "GLOVE_POINTS", "GLOVE_FINGER_POINTS", "MAX_H5_BYTES", "MAX_GROUPS",
           "MAX_CHUNK_BYTES", "H5_CPU_SECONDS", "load_h5_sequences", "load_h5_first"]

MAX_H5_BYTES = 4 << 30  # the file
MAX_GROUPS = 100_000  # entries at the file's root (the authors' data set: hundreds of words and sentences)
MAX_CHUNK_BYTES = 64 << 20  # one chunk of a dataset, inflated: HDF5 inflates a whole chunk to read any part of it
H5_CPU_SECONDS = 30  # the HDF5 process's CPU time: a legitimate file of MAX_FRAMES frames reads in a few seconds
H5_WALL_SECONDS = 600  # and its wall time, for a read that waits instead (a stalled disk)
_EXTRACT = Path(__file__).with_name("h5_extract.py")

DEFAULT_FPS = 15.0  # the authors' released samples run at about 15 Hz
SENTENCE_MARKER = "sentence"
GLOVE_POINTS = ("wrist",) + tuple(
    f"{f}_{p}" for f in ("thumb", "index", "middle", "ring", "pinky") for p in ("base", "middle", "tip")
)
GLOVE_FINGER_POINTS = tuple((1 + 3 * f, 3 + 3 * f) for f in range(5))  # (base, tip) index per finger, thumb..pinky
_GLOVE_WRIST, _GLOVE_INDEX, _GLOVE_MIDDLE, _GLOVE_PINKY = 0, 4, 7, 13
_PREFIX = {"left": "l", "right": "r"}
_KEYS = tuple(f"{s}_{k}" for s in _PREFIX.values() for k in ("up_pos", "up_quat", "fr_pos", "fr_quat", "hd_pos", "hd_quat", "glove_angle", "glove_pos"))
_UP = np.array([0.0, 0.0, 1.0])


def _extract(handle, path: Path, first_only: bool) -> tuple[dict, dict[str, np.ndarray]]:
    """What :mod:`~nlo_lab.human.readers.h5_extract` reads of the open file ``handle``: its manifest and arrays."""
    settings = {"first_only": first_only, "max_groups": MAX_GROUPS, "max_chunk_bytes": MAX_CHUNK_BYTES,
                "max_frames": MAX_FRAMES, "fps_range": list(FPS_RANGE), "cpu_seconds": H5_CPU_SECONDS}
    fd = handle.fileno()
    proc = subprocess.Popen([sys.executable, "-I", str(_EXTRACT), str(fd), json.dumps(settings)], pass_fds=(fd,),
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        out, err = proc.communicate(timeout=H5_WALL_SECONDS)
    except subprocess.TimeoutExpired:
        raise DemonstrationError(f"reading it took more than {H5_WALL_SECONDS:g} s (a corrupt HDF5 structure?)", path=path) from None
    finally:
        if proc.poll() is None:  # a timeout, or an interrupt of this process
            proc.kill()
            proc.wait()
    if proc.returncode in (-signal.SIGXCPU, -signal.SIGKILL):
        raise DemonstrationError(f"reading it took more than {H5_CPU_SECONDS:g} s of CPU time: libhdf5 loops on some corrupt "
                                 "files, this may be one", path=path)
    if proc.returncode != 0:
        cause = f"signal {-proc.returncode}" if proc.returncode < 0 else f"exit status {proc.returncode}"
        last = err.decode(errors="replace").strip().splitlines()[-1:] or [""]
        raise DemonstrationError(f"the HDF5 library failed on it ({cause}{': ' + last[0][:200] if last[0] else ''})", path=path)
    with np.load(io.BytesIO(out), allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    return json.loads(arrays.pop("manifest").tobytes()), arrays


def _refused(entry: dict, path: Path) -> DemonstrationError:
    return DemonstrationError(entry["message"], path=path, field=entry["field"], frame=entry["frame"])


def _read_group(name: str, fps, data: dict[str, np.ndarray | None], path: Path) -> Demonstration:
    """One group's demonstration from its datasets (``data``: every key of the layout, None where absent) and its fps
    entry (the manifest's: a number, None for :data:`DEFAULT_FPS`, or a refusal, raised where the fps is used)."""
    lengths = {k: v.shape[0] for k, v in data.items() if v is not None}
    T = lengths["l_up_pos"]
    for key, n in lengths.items():
        if n != T:
            raise DemonstrationError(f"has {n} frames but l_up_pos has {T}", path=path, field=f"{name}/{key}")
    for s in _PREFIX.values():
        q = data[f"{s}_hd_quat"]
        if q is not None:
            small = np.linalg.norm(q, axis=-1) < 1e-6
            if small.any():
                raise DemonstrationError("zero quaternion", path=path, frame=int(np.argmax(small)), field=f"{name}/{s}_hd_quat")

    origin, R_src_body = body_frame_from_shoulders(data["l_up_pos"], data["r_up_pos"], _UP)  # (T, 3), (T, 3, 3)
    undefined = ~np.isfinite(R_src_body).all(axis=(1, 2))
    if undefined.any():
        raise DemonstrationError(
            "cannot build the body frame (shoulders coincide or lie on the vertical)",
            path=path, frame=int(np.argmax(undefined)), field=f"{name}/l_up_pos",
        )
    R_body_src = np.swapaxes(R_src_body, 1, 2)

    def to_body(p: np.ndarray) -> np.ndarray:  # (T, ..., 3) capture frame -> body frame
        extra = p.ndim - 2
        R = R_body_src.reshape((T,) + (1,) * extra + (3, 3))
        o = origin.reshape((T,) + (1,) * extra + (3,))
        return np.einsum("...ij,...j->...i", R, p - o)

    arms = np.empty((T, 2, 3, 3))
    rots = np.full((T, 2, 3, 3), np.nan)
    wrist_mask = np.zeros((T, 2), dtype=bool)
    fingers = np.full((T, 2, 5, 2, 3), np.nan)
    finger_mask = np.zeros((T, 2, 5), dtype=bool)
    for si, s in enumerate(_PREFIX.values()):
        for j, part in enumerate(("up", "fr", "hd")):
            arms[:, si, j] = to_body(data[f"{s}_{part}_pos"])
        glove = data[f"{s}_glove_pos"]
        if glove is not None:
            # Rotate the hand into the body frame and pin its wrist point on the arm's wrist.
            rel = np.einsum("tij,tpj->tpi", R_body_src, glove - glove[:, :1])  # (T, 16, 3)
            pts = arms[:, si, 2][:, None] + rel
            for f, (b, t) in enumerate(GLOVE_FINGER_POINTS):
                fingers[:, si, f, 0], fingers[:, si, f, 1] = pts[:, b], pts[:, t]
            finger_mask[:, si] = True
            R = wrist_frame_from_hand(pts[:, _GLOVE_WRIST], pts[:, _GLOVE_INDEX], pts[:, _GLOVE_PINKY], pts[:, _GLOVE_MIDDLE])
            ok = np.isfinite(R).all(axis=(1, 2))
            rots[:, si], wrist_mask[:, si] = R, ok
        elif data[f"{s}_hd_quat"] is not None:
            rots[:, si] = R_body_src @ quat_to_matrix(data[f"{s}_hd_quat"])
            wrist_mask[:, si] = True
    meta = {
        "source": path.name,
        "format": "hdf5-authors",
        "group": name,
        "is_sentence": SENTENCE_MARKER in name.lower(),
        "wrist_orientation_from": {side: ("glove_pos" if data[f"{s}_glove_pos"] is not None
                                          else "hd_quat" if data[f"{s}_hd_quat"] is not None else "none")
                                   for side, s in _PREFIX.items()},
    }
    if isinstance(fps, dict):
        raise _refused(fps, path)
    demo = Demonstration.from_arrays(
        DEFAULT_FPS if fps is None else fps, arms, np.ones((T, 2, 3), dtype=bool), rots, wrist_mask, fingers, finger_mask,
        name=name, meta=meta, path=path,
    )
    check_arm_lengths(demo, path=path)
    return demo




def load_h5_sequences(path) -> list[Demonstration]:
    """Every sequence of an HDF5 file in the authors' layout, one per group, in sorted group order.

    Each demonstration's ``meta`` records ``group`` (its group name) and
    ``is_sentence`` (whether the name contains :data:`SENTENCE_MARKER`).

    Args:
        path: the ``.h5`` / ``.hdf5`` file.

    Returns:
        A list of :class:`Demonstration` (at least one).

    Raises:
        DemonstrationError: unreadable file, no groups, a missing or malformed dataset
            (named by group/dataset), NaN or inf (with the frame), fps <= 0,
            an arm of zero length.
    """
    return _read_groups(as_path(path), first_only=False)


def load_h5_first(path) -> Demonstration:
    """The first sequence (sorted group names) of an HDF5 file in the authors' layout."""
    return _read_groups(as_path(path), first_only=True)[0]


def _read_groups(path: Path, first_only: bool) -> list[Demonstration]:
    """The sequence groups of ``path`` in sorted order (only the first when ``first_only``)."""
    with open_input(path, kind="HDF5", max_bytes=MAX_H5_BYTES, error=DemonstrationError) as handle:
        manifest, arrays = _extract(handle, path, first_only)
    demos = []
    for i, (name, fps, keys) in enumerate(manifest["groups"]):  # the groups read whole, then the refusal if any
        data = {key: (arrays[f"{i}:{key}"] if key in keys else None) for key in _KEYS}
        demos.append(_read_group(name, fps, data, path))
    if manifest["error"] is not None:
        raise _refused(manifest["error"], path)
    return demos

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
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from nlo_lab.errors import DemonstrationError
from nlo_lab.files import as_path, format_size, open_input
from nlo_lab.human.demonstration import FPS_RANGE, MAX_FRAMES, Demonstration
from nlo_lab.human.transforms import body_frame_from_shoulders, check_arm_lengths, quat_to_matrix, wrist_frame_from_hand

__all__ = ["DEFAULT_FPS", "SENTENCE_MARKER", "GLOVE_POINTS", "GLOVE_FINGER_POINTS", "MAX_H5_BYTES", "MAX_GROUPS",
           "MAX_CHUNK_BYTES", "load_h5_sequences", "load_h5_first"]

MAX_H5_BYTES = 4 << 30  # the file
MAX_GROUPS = 100_000  # entries at the file's root (the authors' data set: hundreds of words and sentences)
MAX_CHUNK_BYTES = 64 << 20  # one chunk of a dataset, inflated: HDF5 inflates a whole chunk to read any part of it
_FILTERS = {h5py.h5z.FILTER_DEFLATE, h5py.h5z.FILTER_SHUFFLE, h5py.h5z.FILTER_FLETCHER32, h5py.h5z.FILTER_SCALEOFFSET,
            h5py.h5z.FILTER_NBIT, 32000}  # HDF5's own and h5py's LZF; another id would load a plugin

DEFAULT_FPS = 15.0  # the authors' released samples run at about 15 Hz
SENTENCE_MARKER = "sentence"
GLOVE_POINTS = ("wrist",) + tuple(
    f"{f}_{p}" for f in ("thumb", "index", "middle", "ring", "pinky") for p in ("base", "middle", "tip")
)
GLOVE_FINGER_POINTS = tuple((1 + 3 * f, 3 + 3 * f) for f in range(5))  # (base, tip) index per finger, thumb..pinky
_GLOVE_WRIST, _GLOVE_INDEX, _GLOVE_MIDDLE, _GLOVE_PINKY = 0, 4, 7, 13
_PREFIX = {"left": "l", "right": "r"}
_UP = np.array([0.0, 0.0, 1.0])


def _dataset(group: h5py.Group, key: str, shape_tail: tuple[int, ...], path, required: bool) -> np.ndarray | None:
    field = f"{group.name.lstrip('/')}/{key}"
    if key not in group:
        if required:
            raise DemonstrationError("missing dataset", path=path, field=field)
        return None
    obj = _member(group, key, path, field)
    if not isinstance(obj, h5py.Dataset):
        raise DemonstrationError("expected a dataset, found a group", path=path, field=field)
    # dtype and shape come from the header: checked before a byte of data is read
    if obj.dtype.kind not in "iuf":
        raise DemonstrationError(f"expected real numbers, got dtype {obj.dtype}", path=path, field=field)
    if obj.shape is None or len(obj.shape) != 1 + len(shape_tail) or tuple(obj.shape[1:]) != shape_tail:
        raise DemonstrationError(f"expected shape (T, {', '.join(map(str, shape_tail))}), got {obj.shape}", path=path, field=field)
    if obj.shape[0] == 0:
        raise DemonstrationError("no frames", path=path, field=field)
    if obj.shape[0] > MAX_FRAMES:
        raise DemonstrationError(f"declares {obj.shape[0]} frames, more than the {MAX_FRAMES} this nlo_lab reads", path=path, field=field)
    _check_storage(obj, path, field)
    try:
        value = np.asarray(obj[()], dtype=np.float64)
    except (OSError, ValueError, TypeError) as err:
        raise DemonstrationError(f"unreadable dataset ({err})", path=path, field=field) from None
    bad = ~np.isfinite(value)
    if bad.any():
        raise DemonstrationError("NaN or inf", path=path, frame=int(np.argwhere(bad)[0][0]), field=field)
    return value


def _check_storage(obj: h5py.Dataset, path, field: str) -> None:
    """The dataset's bytes are inside this file, stored the ways HDF5 itself reads, in bounded chunks."""
    plist = obj.id.get_create_plist()
    layout = plist.get_layout()
    if layout == h5py.h5d.VIRTUAL:
        raise DemonstrationError("is a virtual dataset: its data lives in other files, which are not read", path=path, field=field)
    if plist.get_external_count() > 0:
        raise DemonstrationError("is stored in an external raw file, which is not read", path=path, field=field)
    if layout not in (h5py.h5d.COMPACT, h5py.h5d.CONTIGUOUS, h5py.h5d.CHUNKED):
        raise DemonstrationError(f"has a storage layout ({layout}) that is not inside the file", path=path, field=field)
    for i in range(plist.get_nfilters()):
        code = plist.get_filter(i)[0]
        if code not in _FILTERS:
            raise DemonstrationError(f"uses the filter {code}, not one of HDF5's own (a plugin would be loaded)", path=path, field=field)
    if obj.chunks is not None:
        chunk = int(np.prod(obj.chunks, dtype=np.int64)) * obj.dtype.itemsize
        if chunk > MAX_CHUNK_BYTES:
            raise DemonstrationError(f"has chunks of {format_size(chunk)}, more than {format_size(MAX_CHUNK_BYTES)}",
                                     path=path, field=field)


def _member(group: h5py.Group, key: str, path, field: str):
    """``group[key]``, refusing links that leave the file or lead nowhere."""
    link = group.get(key, getlink=True)
    if isinstance(link, h5py.ExternalLink):
        raise DemonstrationError("is a link to another file (external links are not followed)", path=path, field=field)
    try:
        return group[key]
    except (KeyError, OSError, RuntimeError, ValueError):
        raise DemonstrationError("is a link that leads nowhere", path=path, field=field) from None


def _fps(group: h5py.Group, root: h5py.File, path) -> float:
    for holder in (group, root):
        if "fps" in holder.attrs:
            field = f"{holder.name}:fps"
            try:
                info = h5py.h5a.open(holder.id, b"fps")
                shape, dtype = info.shape, info.dtype
            except (OSError, TypeError, ValueError) as err:
                raise DemonstrationError(f"unreadable fps attribute ({err})", path=path, field=field) from None
            if shape is None or int(np.prod(shape, dtype=np.int64)) != 1 or dtype.kind not in "iuf":  # before reading it
                raise DemonstrationError(f"fps must be one real number, got dtype {dtype} shape {shape}", path=path, field=field)
            try:
                raw = np.asarray(holder.attrs["fps"])
            except (OSError, TypeError, ValueError) as err:
                raise DemonstrationError(f"unreadable fps attribute ({err})", path=path, field=field) from None
            if raw.size != 1 or raw.dtype.kind not in "iuf":
                raise DemonstrationError(f"fps must be one real number, got dtype {raw.dtype} shape {raw.shape}", path=path, field=field)
            fps = float(raw.reshape(()))
            if not FPS_RANGE[0] <= fps <= FPS_RANGE[1]:
                raise DemonstrationError(f"fps must be in [{FPS_RANGE[0]:g}, {FPS_RANGE[1]:g}], got {fps:g}", path=path, field=field)
            return fps
    return DEFAULT_FPS


def _read_group(group: h5py.Group, root: h5py.File, path: Path) -> Demonstration:
    name = group.name.lstrip("/")
    data = {}
    for s in _PREFIX.values():
        for part in ("up", "fr", "hd"):
            data[f"{s}_{part}_pos"] = _dataset(group, f"{s}_{part}_pos", (3,), path, required=True)
            data[f"{s}_{part}_quat"] = _dataset(group, f"{s}_{part}_quat", (4,), path, required=False)
        data[f"{s}_glove_angle"] = _dataset(group, f"{s}_glove_angle", (14,), path, required=False)
        data[f"{s}_glove_pos"] = _dataset(group, f"{s}_glove_pos", (16, 3), path, required=False)
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
    demo = Demonstration.from_arrays(
        _fps(group, root, path), arms, np.ones((T, 2, 3), dtype=bool), rots, wrist_mask, fingers, finger_mask,
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
        try:
            f = h5py.File(handle, "r")
        except (OSError, ValueError) as err:
            raise DemonstrationError(f"not a readable HDF5 file ({err})", path=path) from None
        with f:
            try:
                if len(f) > MAX_GROUPS:
                    raise DemonstrationError(f"the file's root holds {len(f)} entries, more than {MAX_GROUPS}", path=path)
                # hard links only: a soft or external link at the root is not a sequence of this file
                names = sorted(k for k in f.keys() if isinstance(f.get(k, getlink=True), h5py.HardLink) and isinstance(f[k], h5py.Group))
                if not names:
                    raise DemonstrationError("the file holds no sequence group", path=path)
                demos, frames = [], 0
                for n in names[: 1 if first_only else None]:
                    demos.append(_read_group(f[n], f, path))
                    frames += len(demos[-1])
                    if frames > MAX_FRAMES:
                        raise DemonstrationError(f"its sequences hold more than {MAX_FRAMES} frames together", path=path, field=n)
                return demos
            except DemonstrationError:
                raise
            except (OSError, KeyError, RuntimeError, ValueError, TypeError) as err:  # truncated / corrupt storage
                raise DemonstrationError(f"unreadable HDF5 content ({err})", path=path) from None

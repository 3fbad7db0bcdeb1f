"""The HDF5 side of :mod:`nlo_lab.human.readers.h5`, run as a process of its own.

libhdf5 does not stop on every corrupt file: a 10 kB file whose object header loops (found by ``make fuzz``,
``tests/fuzz/corpus/h5/found-4939c48c205e.h5``) keeps it busy for ever, holding Python's lock, so nothing in
the same process can interrupt it, and a corrupt file may crash it outright. So the reader hands the open file to
this script, which reads the datasets and attributes the layout names under a CPU-time limit, and the reader
builds the demonstration from what it sends back. It imports numpy and h5py alone (nlo_lab's imports would bring
torch: a second to start), and it is started with ``python -I``.

    python -I h5_extract.py FD SETTINGS_JSON

``FD``: the reader's open descriptor of the file (inherited: only the file named is read). ``SETTINGS_JSON``:
``first_only``, ``max_groups``, ``max_chunk_bytes``, ``max_frames``, ``fps_range``, ``cpu_seconds``. It writes
to stdout an ``.npz`` (no pickles): ``manifest``, a JSON (UTF-8 bytes) ``{"groups": [[name, fps, [keys]], ...],
"error": refusal or null}``, and each group's datasets as ``"{i}:{key}"`` float64 arrays. A group's ``fps`` is
its attribute's value, else the file's, else null, or the refusal of the attribute; a refusal is ``{"message",
"field", "frame"}``. Reading stops at the first refusal, after the groups read whole: the reader builds those
first, so its errors come in the order of a reader in one process.
"""

from __future__ import annotations

import io
import json
import os
import resource
import sys

import h5py
import numpy as np

FILTERS = {h5py.h5z.FILTER_DEFLATE, h5py.h5z.FILTER_SHUFFLE, h5py.h5z.FILTER_FLETCHER32, h5py.h5z.FILTER_SCALEOFFSET,
           h5py.h5z.FILTER_NBIT, 32000}  # HDF5's own and h5py's LZF; another id would load a plugin
# (key, its shape after T, required), in the order the reader has always read them (its errors come in this order)
DATASETS = [entry for s in "lr" for entry in (
    *[item for part in ("up", "fr", "hd") for item in ((f"{s}_{part}_pos", (3,), True), (f"{s}_{part}_quat", (4,), False))],
    (f"{s}_glove_angle", (14,), False), (f"{s}_glove_pos", (16, 3), False))]


class Refused(Exception):
    """The file is refused: ``message``, and where (``field``: group/dataset, ``frame``)."""

    def __init__(self, message: str, field: str | None = None, frame: int | None = None):
        super().__init__(message)
        self.message, self.field, self.frame = message, field, frame


def size(n: int) -> str:
    """``n`` bytes as ``nlo_lab.files.format_size`` writes them (tested equal)."""
    if n < 1024:
        return f"{n} bytes"
    value = n / 1024
    for unit in ("KiB", "MiB", "GiB"):
        if value < 1024:
            return f"{value:.1f} {unit}"
        value /= 1024
    return f"{value:.1f} TiB"


def member(group: h5py.Group, key: str, field: str):
    """``group[key]``, refusing links that leave the file or lead nowhere."""
    if isinstance(group.get(key, getlink=True), h5py.ExternalLink):
        raise Refused("is a link to another file (external links are not followed)", field)
    try:
        return group[key]
    except (KeyError, OSError, RuntimeError, ValueError):
        raise Refused("is a link that leads nowhere", field) from None


def check_storage(obj: h5py.Dataset, field: str, max_chunk_bytes: int) -> None:
    """The dataset's bytes are inside this file, stored the ways HDF5 itself reads, in bounded chunks."""
    plist = obj.id.get_create_plist()
    layout = plist.get_layout()
    if layout == h5py.h5d.VIRTUAL:
        raise Refused("is a virtual dataset: its data lives in other files, which are not read", field)
    if plist.get_external_count() > 0:
        raise Refused("is stored in an external raw file, which is not read", field)
    if layout not in (h5py.h5d.COMPACT, h5py.h5d.CONTIGUOUS, h5py.h5d.CHUNKED):
        raise Refused(f"has a storage layout ({layout}) that is not inside the file", field)
    for i in range(plist.get_nfilters()):
        code = plist.get_filter(i)[0]
        if code not in FILTERS:
            raise Refused(f"uses the filter {code}, not one of HDF5's own (a plugin would be loaded)", field)
    if obj.chunks is not None:
        chunk = int(np.prod(obj.chunks, dtype=np.int64)) * obj.dtype.itemsize
        if chunk > max_chunk_bytes:
            raise Refused(f"has chunks of {size(chunk)}, more than {size(max_chunk_bytes)}", field)


def dataset(group: h5py.Group, key: str, shape_tail: tuple[int, ...], required: bool, settings: dict) -> np.ndarray | None:
    field = f"{group.name.lstrip('/')}/{key}"
    if key not in group:
        if required:
            raise Refused("missing dataset", field)
        return None
    obj = member(group, key, field)
    if not isinstance(obj, h5py.Dataset):
        raise Refused("expected a dataset, found a group", field)
    # dtype and shape come from the header: checked before a byte of data is read
    if obj.dtype.kind not in "iuf":
        raise Refused(f"expected real numbers, got dtype {obj.dtype}", field)
    if obj.shape is None or len(obj.shape) != 1 + len(shape_tail) or tuple(obj.shape[1:]) != shape_tail:
        raise Refused(f"expected shape (T, {', '.join(map(str, shape_tail))}), got {obj.shape}", field)
    if obj.shape[0] == 0:
        raise Refused("no frames", field)
    if obj.shape[0] > settings["max_frames"]:
        raise Refused(f"declares {obj.shape[0]} frames, more than the {settings['max_frames']} this nlo_lab reads", field)
    check_storage(obj, field, settings["max_chunk_bytes"])
    try:
        value = np.asarray(obj[()], dtype=np.float64)
    except (OSError, ValueError, TypeError) as err:
        raise Refused(f"unreadable dataset ({err})", field) from None
    bad = ~np.isfinite(value)
    if bad.any():
        raise Refused("NaN or inf", field, int(np.argwhere(bad)[0][0]))
    return value


def fps(holder, settings: dict) -> float | None:
    """The ``fps`` attribute of a group or the file, checked before and after it is read; None without one."""
    if "fps" not in holder.attrs:
        return None
    field = f"{holder.name}:fps"
    try:
        info = h5py.h5a.open(holder.id, b"fps")
        shape, dtype = info.shape, info.dtype
    except (OSError, TypeError, ValueError) as err:
        raise Refused(f"unreadable fps attribute ({err})", field) from None
    if shape is None or int(np.prod(shape, dtype=np.int64)) != 1 or dtype.kind not in "iuf":  # before reading it
        raise Refused(f"fps must be one real number, got dtype {dtype} shape {shape}", field)
    try:
        raw = np.asarray(holder.attrs["fps"])
    except (OSError, TypeError, ValueError) as err:
        raise Refused(f"unreadable fps attribute ({err})", field) from None
    if raw.size != 1 or raw.dtype.kind not in "iuf":
        raise Refused(f"fps must be one real number, got dtype {raw.dtype} shape {raw.shape}", field)
    value = float(raw.reshape(()))
    lo, hi = settings["fps_range"]
    if not lo <= value <= hi:
        raise Refused(f"fps must be in [{lo:g}, {hi:g}], got {value:g}", field)
    return value


def refusal(err: Refused) -> dict:
    return {"message": err.message, "field": err.field, "frame": err.frame}


def group_fps(group: h5py.Group, root: h5py.File, settings: dict):
    """The group's fps entry: its attribute's value, else the file's, else None; or the refusal of the attribute."""
    try:
        value = fps(group, settings)
        return fps(root, settings) if value is None else value
    except Refused as err:
        return refusal(err)


def extract(handle, settings: dict) -> tuple[dict, dict[str, np.ndarray]]:
    """The manifest and the arrays of the file open as ``handle`` (the module's docstring)."""
    groups: list = []
    arrays: dict[str, np.ndarray] = {}
    try:
        try:
            f = h5py.File(handle, "r")
        except (OSError, ValueError) as err:
            raise Refused(f"not a readable HDF5 file ({err})") from None
        with f:
            try:
                if len(f) > settings["max_groups"]:
                    raise Refused(f"the file's root holds {len(f)} entries, more than {settings['max_groups']}")
                # hard links only: a soft or external link at the root is not a sequence of this file
                names = sorted(k for k in f.keys() if isinstance(f.get(k, getlink=True), h5py.HardLink) and isinstance(f[k], h5py.Group))
                if not names:
                    raise Refused("the file holds no sequence group")
                frames = 0
                for i, name in enumerate(names[: 1 if settings["first_only"] else None]):
                    group, read = f[name], {}
                    for key, tail, required in DATASETS:
                        value = dataset(group, key, tail, required, settings)
                        if value is not None:
                            read[f"{i}:{key}"] = value
                    arrays.update(read)
                    groups.append([name, group_fps(group, f, settings), [k.partition(":")[2] for k in read]])
                    frames += len(read[f"{i}:l_up_pos"])
                    if frames > settings["max_frames"]:
                        raise Refused(f"its sequences hold more than {settings['max_frames']} frames together", name)
            except Refused:
                raise
            except (OSError, KeyError, RuntimeError, ValueError, TypeError) as err:  # truncated / corrupt storage
                raise Refused(f"unreadable HDF5 content ({err})") from None
    except Refused as err:
        return {"groups": groups, "error": refusal(err)}, arrays
    return {"groups": groups, "error": None}, arrays


def main(argv: list[str]) -> int:
    fd, settings = int(argv[0]), json.loads(argv[1])
    seconds = int(settings["cpu_seconds"])
    resource.setrlimit(resource.RLIMIT_CPU, (seconds, seconds + 1))  # SIGXCPU, then SIGKILL: a loop in libhdf5 ends
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))  # and leaves no core file behind
    with os.fdopen(fd, "rb", closefd=False) as handle:
        manifest, arrays = extract(handle, settings)
    buffer = io.BytesIO()
    np.savez(buffer, manifest=np.frombuffer(json.dumps(manifest).encode(), dtype=np.uint8), **arrays)
    sys.stdout.buffer.write(buffer.getbuffer())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

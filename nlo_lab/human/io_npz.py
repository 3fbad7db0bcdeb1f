"""The package's own demonstration file: a ``.npz`` archive.

Keys: ``format`` (the string ``"nlo_lab.demonstration"``), ``format_version``
(int, :data:`NPZ_FORMAT_VERSION`), ``fps``, the six arrays of
:class:`Demonstration` under their field names (NaN where masked), ``name`` and
``meta_json`` (the meta dict as JSON). Written without pickles, read with
``allow_pickle=False``.
"""

from __future__ import annotations

import json
import zipfile
import zlib
from pathlib import Path

import numpy as np

from nlo_lab.atomic_files import atomic_path
from nlo_lab.errors import DemonstrationError
from nlo_lab.human.demonstration import MAX_FRAMES, Demonstration
from nlo_lab.human.transforms import check_arm_lengths

__all__ = ["NPZ_FORMAT", "NPZ_FORMAT_VERSION", "save_npz", "load_npz"]

NPZ_FORMAT = "nlo_lab.demonstration"
NPZ_FORMAT_VERSION = 1
_ARRAYS = ("arm_positions", "arm_mask", "wrist_rotations", "wrist_mask", "finger_positions", "finger_mask")


def save_npz(demo: Demonstration, path) -> Path:
    """Write ``demo`` to ``path`` (``.npz``), atomically.

    The archive is written to a temporary file in the same folder and renamed, so
    a failed write leaves nothing behind and never a half-written file.

    Args:
        demo: the demonstration.
        path: the target file; the suffix ``.npz`` is required.

    Returns:
        The path written.

    Raises:
        DemonstrationError: wrong suffix, meta not JSON-serialisable, or the write failed.
    """
    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise DemonstrationError("a demonstration archive must end in .npz", path=path)
    demo.validate(path=path)
    try:
        meta_json = json.dumps(demo.meta, allow_nan=True, sort_keys=True)
    except (TypeError, ValueError) as err:
        raise DemonstrationError(f"meta is not JSON-serialisable: {err}", path=path, field="meta") from None
    arrays = {name: getattr(demo, name) for name in _ARRAYS}
    try:
        with atomic_path(path) as tmp, open(tmp, "wb") as f:  # a file object: np.savez adds no suffix
            np.savez(
                f,
                format=np.array(NPZ_FORMAT),
                format_version=np.array(NPZ_FORMAT_VERSION),
                fps=np.array(demo.fps, dtype=np.float64),
                name=np.array(demo.name),
                meta_json=np.array(meta_json),
                **arrays,
            )
    except OSError as err:
        raise DemonstrationError(f"could not write the archive: {err}", path=path) from None
    return path


_SCALARS = ("format", "format_version", "fps", "name", "meta_json")
_MAX_TEXT = {"format": 64, "name": 4096, "meta_json": 1 << 20}  # characters
_MAX_META_DEPTH = 64  # nesting of meta_json's objects and lists
_FLOATS_PER_FRAME = 2 * 5 * 2 * 3  # the largest array, finger_positions, per frame


def _read_member(zf: zipfile.ZipFile, key: str, path: Path) -> np.ndarray:
    """One ``.npy`` member, its header checked before any data is read."""
    with zf.open(key + ".npy") as fh:
        try:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
            elif version == (2, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
            else:
                raise ValueError(f"unsupported .npy version {version}")
        except (ValueError, EOFError, SyntaxError) as err:
            raise DemonstrationError(f"not a readable array ({err})", path=path, field=key) from None
        if dtype.hasobject:
            raise DemonstrationError("holds Python objects (pickles are refused)", path=path, field=key)
        if key in _SCALARS:
            if shape != ():
                raise DemonstrationError(f"must be a scalar, got shape {shape}", path=path, field=key)
            if dtype.kind == "U" and dtype.itemsize // 4 > _MAX_TEXT.get(key, 0):
                raise DemonstrationError(f"text of {dtype.itemsize // 4} characters is too long", path=path, field=key)
        limit = MAX_FRAMES * _FLOATS_PER_FRAME if key not in _SCALARS else 1
        count = int(np.prod(shape, dtype=np.int64)) if shape else 1
        if count > limit or count < 0:
            raise DemonstrationError(f"declares {shape} elements, more than a recording of {MAX_FRAMES} frames holds",
                                     path=path, field=key)
        nbytes = count * dtype.itemsize
        raw = fh.read(nbytes)
        if len(raw) != nbytes:
            raise DemonstrationError("truncated array", path=path, field=key)
    return np.frombuffer(raw, dtype=dtype).reshape(shape, order="F" if fortran else "C").copy()


def _read_members(fh, path: Path) -> dict[str, np.ndarray]:
    """The known members of an open archive; unknown ones are never read."""
    with zipfile.ZipFile(fh) as zf:
        present = {n[: -len(".npy")] for n in zf.namelist() if n.endswith(".npy")}
        return {key: _read_member(zf, key, path) for key in _SCALARS + _ARRAYS if key in present}


def _depth(value, limit: int) -> int:
    stack, deepest = [(value, 1)], 0
    while stack:
        v, d = stack.pop()
        if isinstance(v, (dict, list)):
            deepest = max(deepest, d)
            if deepest > limit:
                break
            stack.extend((c, d + 1) for c in (v.values() if isinstance(v, dict) else v))
    return deepest


def _text(content: dict, key: str, path: Path) -> str:
    value = content[key]
    if value.dtype.kind != "U":
        raise DemonstrationError(f"must be text, got dtype {value.dtype}", path=path, field=key)
    return str(value[()])


def load_npz(path) -> Demonstration:
    """Read a demonstration written by :func:`save_npz`.

    Only the archive's known members are read, each after its header (dtype,
    shape) was checked: unknown members are skipped unread, arrays larger than a
    recording of :data:`~nlo_lab.human.demonstration.MAX_FRAMES` frames and
    Python objects (pickles) are refused, ``meta_json`` may nest at most 64 deep.

    Raises:
        DemonstrationError: unreadable or truncated file, another format or version,
            missing keys, wrong shapes or dtypes, NaN/inf where the mask says valid,
            fps outside :data:`~nlo_lab.human.demonstration.FPS_RANGE`, an arm of zero length.
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            if not zipfile.is_zipfile(fh):
                raise DemonstrationError("not a readable .npz archive (no zip directory)", path=path)
            content = _read_members(fh, path)
    except FileNotFoundError:
        raise DemonstrationError("no such file", path=path) from None
    except IsADirectoryError:
        raise DemonstrationError("is a folder, not a file", path=path) from None
    except (OSError, EOFError, ValueError, zlib.error, zipfile.BadZipFile, NotImplementedError, RuntimeError) as err:
        raise DemonstrationError(f"not a readable .npz archive ({type(err).__name__}: {err})", path=path) from None
    if "format" not in content or _text(content, "format", path) != NPZ_FORMAT:
        raise DemonstrationError(f"not an nlo_lab demonstration archive (no format '{NPZ_FORMAT}')", path=path, field="format")
    version = content.get("format_version", np.array(-1))
    if version.dtype.kind not in "iu":
        raise DemonstrationError(f"format_version must be a whole number, got dtype {version.dtype}", path=path, field="format_version")
    if int(version) != NPZ_FORMAT_VERSION:
        raise DemonstrationError(
            f"unsupported format version {int(version)} (this nlo_lab reads {NPZ_FORMAT_VERSION})", path=path, field="format_version"
        )
    for key in ("fps", "name", "meta_json") + _ARRAYS:
        if key not in content:
            raise DemonstrationError("missing entry", path=path, field=key)
    try:
        meta = json.loads(_text(content, "meta_json", path))
    except RecursionError:
        raise DemonstrationError(f"meta nests deeper than {_MAX_META_DEPTH}", path=path, field="meta_json") from None
    except ValueError as err:
        raise DemonstrationError(f"meta is not valid JSON: {err}", path=path, field="meta_json") from None
    if not isinstance(meta, dict):
        raise DemonstrationError("meta must be a JSON object", path=path, field="meta_json")
    if _depth(meta, _MAX_META_DEPTH) > _MAX_META_DEPTH:
        raise DemonstrationError(f"meta nests deeper than {_MAX_META_DEPTH}", path=path, field="meta_json")
    demo = Demonstration.from_arrays(
        content["fps"], *(content[k] for k in _ARRAYS), name=_text(content, "name", path), meta=meta, path=path
    )
    check_arm_lengths(demo, path=path)
    return demo

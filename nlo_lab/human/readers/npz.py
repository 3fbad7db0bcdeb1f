"""The package's own demonstration file: a ``.npz`` archive.

Keys: ``format`` (the string ``"nlo_lab.demonstration"``), ``format_version``
(int, :data:`NPZ_FORMAT_VERSION`), ``fps``, the six arrays of
:class:`Demonstration` under their field names (NaN where masked), ``name`` and
``meta_json`` (the meta dict as JSON). Written without pickles, read with
``allow_pickle=False``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from nlo_lab.atomic_files import atomic_path
from nlo_lab.errors import DemonstrationError
from nlo_lab.files import as_path
from nlo_lab.human.demonstration import MAX_FRAMES, Demonstration
from nlo_lab.human.transforms import check_arm_lengths
from nlo_lab.npz_archive import Member, read_npz_members

__all__ = ["NPZ_FORMAT", "NPZ_FORMAT_VERSION", "MAX_NPZ_BYTES", "MAX_NPZ_INFLATED", "save_npz", "load_npz"]

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
    path = as_path(path)
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
_MAX_META_DEPTH = 64  # nesting of meta_json's objects and lists
MAX_NPZ_BYTES = 512 << 20  # the file (an archive of MAX_FRAMES frames is 380 MB uncompressed)
_PER_FRAME = {"arm_positions": 18, "arm_mask": 6, "wrist_rotations": 18, "wrist_mask": 2, "finger_positions": 60, "finger_mask": 10}
LAYOUT = {
    "format": Member("U", max_chars=64),
    "format_version": Member("iuf"),  # a float is named as such by load_npz
    "fps": Member("iufb"),  # a bool is named as such by Demonstration
    "name": Member("U", max_chars=4096),
    "meta_json": Member("U", max_chars=1 << 20),
    **{key: Member("iufb", ndim=None, max_elements=MAX_FRAMES * n) for key, n in _PER_FRAME.items()},
}
# every member at its largest (text: 4 bytes a character, numbers: 8 bytes): what an archive may inflate to, 398 MB
MAX_NPZ_INFLATED = sum(m.max_elements * (4 * m.max_chars if m.kinds == "U" else 8) for m in LAYOUT.values())


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
    path = as_path(path)
    content = read_npz_members(path, LAYOUT, kind="demonstration archive", max_bytes=MAX_NPZ_BYTES,
                               max_inflated=MAX_NPZ_INFLATED, error=DemonstrationError)
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

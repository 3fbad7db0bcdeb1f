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
from pathlib import Path

import numpy as np

from nlo_lab._atomic import atomic_path
from nlo_lab.errors import DemonstrationError
from nlo_lab.human.demonstration import Demonstration
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


def load_npz(path) -> Demonstration:
    """Read a demonstration written by :func:`save_npz`.

    Raises:
        DemonstrationError: unreadable or truncated file, another format or version,
            missing keys, wrong shapes, NaN/inf where the mask says valid, fps <= 0,
            an arm of zero length.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            content = {key: data[key] for key in data.files}
    except FileNotFoundError:
        raise DemonstrationError("no such file", path=path) from None
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as err:
        raise DemonstrationError(f"not a readable .npz archive ({type(err).__name__}: {err})", path=path) from None
    if "format" not in content or str(content["format"]) != NPZ_FORMAT:
        raise DemonstrationError(f"not an nlo_lab demonstration archive (no format '{NPZ_FORMAT}')", path=path, field="format")
    version = int(content.get("format_version", -1))
    if version != NPZ_FORMAT_VERSION:
        raise DemonstrationError(
            f"unsupported format version {version} (this nlo_lab reads {NPZ_FORMAT_VERSION})", path=path, field="format_version"
        )
    for key in ("fps", "name", "meta_json") + _ARRAYS:
        if key not in content:
            raise DemonstrationError("missing entry", path=path, field=key)
    try:
        meta = json.loads(str(content["meta_json"]))
    except ValueError as err:
        raise DemonstrationError(f"meta is not valid JSON: {err}", path=path, field="meta_json") from None
    if not isinstance(meta, dict):
        raise DemonstrationError("meta must be a JSON object", path=path, field="meta_json")
    fps = content["fps"]
    if fps.shape != ():
        raise DemonstrationError(f"fps must be a scalar, got shape {fps.shape}", path=path, field="fps")
    demo = Demonstration.from_arrays(
        float(fps), *(content[k] for k in _ARRAYS), name=str(content["name"]), meta=meta, path=path
    )
    check_arm_lengths(demo, path=path)
    return demo

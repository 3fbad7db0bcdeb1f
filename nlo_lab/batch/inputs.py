"""The inputs of a batch: files, folders searched recursively, manifests; their output folders and content hashes.

An INPUT is a file (any extension: the reader decides), a folder (searched recursively
for :data:`SUFFIXES`; hidden files and folders and the output folder itself are passed
over) or a manifest ``.txt`` (one path per line, relative to the manifest's folder; blank
lines and lines starting with ``#`` are ignored). A path a manifest names that does not
exist is still an input (its row says ``file not found``); a path on the command line that
does not exist is a usage error. Each input writes ``OUT/<its path relative to the inputs'
common folder, without suffix>/``.

Nothing here imports torch or dask: a resumed run decides what to do without them.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from nlo_lab.errors import NloLabError

__all__ = ["SUFFIXES", "MANIFEST_SUFFIX", "RESULTS_FILE", "BatchInput", "InputError", "find_inputs", "file_sha256"]

SUFFIXES = (".pose", ".h5", ".npz", ".mp4", ".mov", ".webm", ".avi")  # what a folder search picks up
MANIFEST_SUFFIX = ".txt"
RESULTS_FILE = "results.csv"  # in the output folder; no input may write a folder of that name
_HASH_BLOCK = 1 << 20


class InputError(NloLabError, ValueError):
    """The batch's inputs cannot be gathered (a missing path, no input at all, two inputs for one folder)."""


@dataclass(frozen=True)
class BatchInput:
    """One input of a batch.

    Attributes:
        path: the file, as given (a manifest's entries joined to the manifest's folder).
        name: its output folder relative to the batch's output folder (POSIX separators).
    """

    path: Path
    name: str

    @property
    def is_video(self) -> bool:
        return self.path.suffix.lower() in (".mp4", ".mov", ".webm", ".avi")


def _search(folder: Path, skip: Path | None) -> list[Path]:
    """Files below ``folder`` with one of :data:`SUFFIXES`, sorted; hidden entries and ``skip`` passed over."""
    found = []
    for root, dirs, files in os.walk(folder):
        here = Path(root)
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and (skip is None or (here / d).resolve() != skip))
        found += [here / f for f in sorted(files) if not f.startswith(".") and Path(f).suffix.lower() in SUFFIXES]
    return found


def _manifest(path: Path) -> list[Path]:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError(f"manifest {path}: not UTF-8 text") from None
    entries = []
    for number, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        entry = Path(line).expanduser()
        entry = entry if entry.is_absolute() else path.parent / entry
        if entry.suffix.lower() == MANIFEST_SUFFIX:
            raise InputError(f"manifest {path}, line {number}: a manifest may not name another manifest ({line})")
        entries.append(entry)
    return entries


def find_inputs(inputs, out=None) -> list[BatchInput]:
    """Gather the batch's input files in the order given (folders sorted), each once.

    Args:
        inputs: paths (``str`` or ``Path``): files, folders, manifest ``.txt`` files.
        out: the batch's output folder: never searched for inputs.

    Returns:
        One :class:`BatchInput` per distinct file.

    Raises:
        InputError: a path given that does not exist, a manifest that cannot be read,
            no input found, or two inputs that would write the same output folder.
    """
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    skip = Path(out).resolve() if out is not None else None
    files: list[Path] = []
    for given in inputs:
        path = Path(given).expanduser()
        if path.is_dir():
            found = _search(path, skip)
            if not found:
                raise InputError(f"no inputs in folder {path} (searched for {' '.join(SUFFIXES)})")
            files += found
        elif path.suffix.lower() == MANIFEST_SUFFIX and path.is_file():
            for entry in _manifest(path):
                files += _search(entry, skip) if entry.is_dir() else [entry]
        elif path.is_file():
            files.append(path)
        else:
            raise InputError(f"input not found: {path}")
    unique: dict[Path, Path] = {}
    for f in files:
        unique.setdefault(Path(os.path.abspath(f)), f)
    if not unique:
        raise InputError("no inputs: the manifests list no files")
    return _named(unique)


def _named(files: dict[Path, Path]) -> list[BatchInput]:
    """Output folder names: each path relative to the common folder, without suffix."""
    absolute = list(files)
    common = Path(os.path.commonpath([p.parent for p in absolute]))
    out, seen = [], {}
    for absolute_path, given in files.items():
        name = absolute_path.relative_to(common).with_suffix("").as_posix()
        if name in seen or name == RESULTS_FILE:
            other = seen.get(name, RESULTS_FILE)
            raise InputError(f"{given} and {other} would both write the output folder {name!r}; "
                             "give them in separate runs (different --out) or rename one")
        seen[name] = given
        out.append(BatchInput(given, name))
    for name, given in seen.items():  # a folder may hold files only: x/ cannot also hold the folder x/y/
        parent = name.rpartition("/")[0]
        while parent:
            if parent in seen:
                raise InputError(f"{seen[parent]} and {given} cannot both be written: the output folder {parent!r} "
                                 f"would hold the folder {name!r}; give them in separate runs (different --out)")
            parent = parent.rpartition("/")[0]
    return out


def file_sha256(path) -> str:
    """The SHA-256 of a file's contents (hex)."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(_HASH_BLOCK):
            digest.update(block)
    return digest.hexdigest()

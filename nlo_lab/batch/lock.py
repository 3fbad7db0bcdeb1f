"""One batch at a time per output folder: ``OUT/.nlo-lab-batch.lock``, held while the run lasts.

Two runs writing one ``results.csv`` would each drop the other's rows. The lock is an
advisory ``flock`` on a file in the output folder: the system releases it when the process
ends, however it ends, so a killed run never leaves the folder locked.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

from nlo_lab.atomic_files import writable_place
from nlo_lab.errors import OutputError

__all__ = ["LOCK_FILE", "run_lock", "check_out_place"]

LOCK_FILE = ".nlo-lab-batch.lock"


def check_out_place(out) -> Path:
    """The batch's output folder, checked before any input is read; returns it as a Path.

    Refused: an empty path (it would be the current folder), an existing entry that is not a
    folder, a path below a file, a place we may not write in.

    Raises:
        OutputError: naming the folder and the reason.
    """
    if not isinstance(out, (str, os.PathLike)) or not os.fspath(out) or "\x00" in os.fspath(out):
        raise OutputError(f"the output folder must be a non-empty path, got {out!r}")
    path = Path(out).expanduser()
    if os.path.lexists(path) and not path.is_dir():
        raise OutputError(f"{path} exists and is not a folder")
    writable_place(path, str(path))
    return path


@contextlib.contextmanager
def run_lock(out: Path) -> Iterator[Path]:
    """Create the output folder if needed and hold its lock for the block.

    Raises:
        OutputError: ``out`` is not a folder or cannot be written, or another batch holds it.
    """
    if os.path.lexists(out) and not out.is_dir():
        raise OutputError(f"{out} exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd = os.open(out / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as err:
        raise OutputError(f"cannot write in {out}: {err.strerror or err}") from None
    try:
        try:
            # lazy: POSIX only
            import fcntl

            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except ImportError:  # not POSIX: no lock
            pass
        except OSError:
            raise OutputError(f"{out} is in use by another nlo-lab batch (wait for it to end, or choose another folder)") from None
        yield out
    finally:
        os.close(fd)

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

from nlo_lab.errors import OutputError

__all__ = ["LOCK_FILE", "run_lock"]

LOCK_FILE = ".nlo-lab-batch.lock"


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

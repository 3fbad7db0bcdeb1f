"""The first check of every recording or video file: it exists, is a file, can be read and is not empty."""

from __future__ import annotations

import os
from pathlib import Path

from nlo_lab.errors import DemonstrationError

__all__ = ["read_head"]


def read_head(path: Path, n: int, kind: str) -> tuple[bytes, int]:
    """The first ``n`` bytes of a file and its size in bytes, before any parser sees it.

    Args:
        path: the file.
        n: bytes to read from its start.
        kind: what the file should be, for the message about a folder (``"video"``, ``".pose"``).

    Raises:
        DemonstrationError: missing, a folder, unreadable, or empty (one line naming the file).
    """
    try:
        with path.open("rb") as f:
            size = os.fstat(f.fileno()).st_size
            head = f.read(n)
    except FileNotFoundError:
        raise DemonstrationError("no such file", path=path) from None
    except IsADirectoryError:
        raise DemonstrationError(f"is a folder, not a {kind} file", path=path) from None
    except OSError as err:
        raise DemonstrationError(f"cannot read the file ({err.strerror or err})", path=path) from None
    if not head:
        raise DemonstrationError("the file is empty", path=path)
    return head, size

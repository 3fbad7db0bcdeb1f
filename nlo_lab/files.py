"""Input files: a regular file of bounded size, checked before it is opened.

Whatever nlo_lab reads (recordings, videos, robot specs, URDFs, meshes, checkpoints,
trajectories) passes :func:`check_input_file` first. It refuses, with one line that names
the file and what is wrong with it:

- a path that does not exist, a dangling symbolic link, a path below a file;
- a folder;
- anything that is not a regular file, also behind a symbolic link: a FIFO (named
  pipe) would block the reader forever, a device such as ``/dev/zero`` never ends,
  a socket cannot be read;
- an empty file, and a file larger than its format's limit (each reader states its own,
  e.g. :data:`nlo_lab.human.readers.pose.MAX_POSE_BYTES`).

The check looks at the path with ``stat`` and never opens it (opening a FIFO blocks).
:func:`open_input` then opens the file without blocking and checks the opened file
again, so a FIFO or a larger file swapped in between is refused too; and
:func:`read_input_bytes` never reads more than the limit, even from a file that grows.
The error is the reader's own class (``error=``, e.g. :class:`~nlo_lab.errors.DemonstrationError`),
built as ``error(message, path=path)``.
"""

from __future__ import annotations

import contextlib
import os
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

from nlo_lab.errors import NloLabError, SettingsError, SettingsTypeError

__all__ = ["InputFileError", "as_path", "format_size", "check_input_file", "open_input", "read_input_bytes"]


class InputFileError(NloLabError, ValueError):
    """An input file that cannot be read (the default ``error=`` of this module's checks)."""


def as_path(value, name: str = "path") -> Path:
    """``value`` as a :class:`~pathlib.Path`: a ``str`` or ``os.PathLike``, not empty, without NUL characters.

    Raises:
        SettingsTypeError: not a path (a number, None, bytes ...).
        SettingsError: an empty path, or one holding a NUL character (no file system has such a name).
    """
    if not isinstance(value, (str, os.PathLike)):
        raise SettingsTypeError(f"{name} must be a file path (str or os.PathLike), got {type(value).__name__}")
    text = os.fspath(value)
    if not isinstance(text, str):
        raise SettingsTypeError(f"{name} must be a file path (str or os.PathLike of str), got {type(text).__name__}")
    if not text:
        raise SettingsError(f"{name} is empty: name a file")
    if "\x00" in text:
        raise SettingsError(f"{name} holds a NUL character: no file has that name")
    return Path(text)


def format_size(n: int) -> str:
    """``n`` bytes for a message: ``"512 bytes"``, ``"1.5 MiB"``, ``"6.0 GiB"``."""
    if n < 1024:
        return f"{n} bytes"
    for unit in ("KiB", "MiB", "GiB", "TiB"):
        n /= 1024
        if n < 1024 or unit == "TiB":
            return f"{n:.1f} {unit}"
    raise AssertionError("unreachable")


_KINDS = (
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def _check_stat(st: os.stat_result, path: Path, kind: str, max_bytes: int, error) -> int:
    if stat.S_ISDIR(st.st_mode):
        raise error(f"is a folder, not a {kind} file", path=path)
    if not stat.S_ISREG(st.st_mode):
        what = next((name for test, name in _KINDS if test(st.st_mode)), "not a regular file")
        via = " (behind a symbolic link)" if path.is_symlink() else ""
        raise error(f"is {what}{via}, not a regular file: nlo_lab reads a {kind} only from a regular file", path=path)
    if st.st_size == 0:
        raise error("the file is empty", path=path)
    if st.st_size > max_bytes:
        raise error(f"the file is {format_size(st.st_size)}, more than the {format_size(max_bytes)} a {kind} file may be",
                    path=path)
    return st.st_size


def check_input_file(path, *, kind: str, max_bytes: int, error: type[NloLabError] = InputFileError) -> int:
    """Check that ``path`` is a regular, non-empty file of at most ``max_bytes``, without opening it.

    Args:
        path: the file (``str`` or ``os.PathLike``).
        kind: what the file should hold, for the messages (``".pose"``, ``"robot spec"``).
        max_bytes: the largest size the format allows.
        error: the exception class to raise, called as ``error(message, path=path)``.

    Returns:
        The file's size in bytes.

    Raises:
        error: missing, a folder, not a regular file (FIFO, device, socket, also behind a
            symbolic link), empty, or larger than ``max_bytes``.
        SettingsTypeError, SettingsError: ``path`` is not a path (see :func:`as_path`).
    """
    path = as_path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        dangling = os.path.lexists(path)
        raise error("a symbolic link to a file that does not exist" if dangling else "no such file", path=path) from None
    except NotADirectoryError:
        raise error("no such file (a part of the path is a file, not a folder)", path=path) from None
    except PermissionError:
        raise error("no permission to reach the file", path=path) from None
    except OSError as err:  # a loop of symbolic links, a name too long, an I/O error
        raise error(f"cannot reach the file ({err.strerror or err})", path=path) from None
    return _check_stat(st, path, kind, max_bytes, error)


@contextlib.contextmanager
def open_input(path, *, kind: str, max_bytes: int, error: type[NloLabError] = InputFileError) -> Iterator[BinaryIO]:
    """Open a checked input file (:func:`check_input_file`) for reading in binary mode.

    The file is opened without blocking and checked again through its descriptor, so a
    FIFO or a device swapped in after the first check never blocks the reader.
    """
    check_input_file(path, kind=kind, max_bytes=max_bytes, error=error)
    path = Path(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except PermissionError:
        raise error("no permission to read the file", path=path) from None
    except OSError as err:
        raise error(f"cannot open the file ({err.strerror or err})", path=path) from None
    try:
        _check_stat(os.fstat(fd), path, kind, max_bytes, error)
        os.set_blocking(fd, True)
        handle = os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise
    with handle:
        yield handle


def read_input_bytes(path, *, kind: str, max_bytes: int, error: type[NloLabError] = InputFileError) -> bytes:
    """The whole content of a checked input file (:func:`check_input_file`), never more than ``max_bytes``.

    Raises:
        error: as :func:`check_input_file`; a file that grows beyond ``max_bytes`` while it is
            read; a read error (an I/O error of the disk).
    """
    with open_input(path, kind=kind, max_bytes=max_bytes, error=error) as f:
        try:
            data = f.read(max_bytes + 1)
        except OSError as err:
            raise error(f"cannot read the file ({err.strerror or err})", path=path) from None
    if len(data) > max_bytes:
        raise error(f"the file grew beyond the {format_size(max_bytes)} a {kind} file may be while it was read", path=path)
    if not data:
        raise error("the file is empty", path=path)
    return data

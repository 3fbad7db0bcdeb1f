"""Atomic writes: a temporary file (or folder, for a set of files) beside the target, renamed over it on success.

A reader never sees half a file, a failed write leaves nothing behind (and an
older file at the target untouched), and the file gets the mode a plain
``open(path, "w")`` would give it (``0o666 & ~umask``), not ``tempfile``'s 0600.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import re
import secrets
import shutil
import signal
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path

from nlo_lab.errors import OutputError

__all__ = [
    "atomic_path",
    "atomic_write_bytes",
    "current_umask",
    "check_output_place",
    "check_output_file",
    "writable_place",
    "output_set",
    "stale_temp_folders",
    "stale_temp_folders_in",
]


def current_umask() -> int:
    """The process umask, read without changing it where Linux tells it (``/proc/self/status``)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)  # elsewhere: set and restore (not thread-safe, but brief)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path in ``path``'s folder; on success it becomes ``path``.

    Write the content to the yielded path inside the ``with`` block. On normal exit
    the file is flushed to disk, given mode ``0o666 & ~umask`` and renamed over
    ``path``; on any exception it is removed and the exception propagates.

    Args:
        path: the target file; its folder must exist.

    Raises:
        OSError: the folder does not exist or is not writable, the disk is full, or the
            rename failed; its ``filename`` is ``path`` (never our temporary file).
    """
    target = Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    try:
        fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=folder)
    except OSError as err:
        raise _naming(err, target) from None
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:  # the content is on disk before the rename makes it visible
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~current_umask())
        os.replace(tmp, target)
    except BaseException as err:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if type(err) in _OS_ERRORS:  # a full disk, no permission: name the user's file, not our temporary one
            raise _naming(err, target) from None
        raise


_OS_ERRORS = (OSError, PermissionError, FileNotFoundError, IsADirectoryError, NotADirectoryError, FileExistsError)


def _naming(err: OSError, target: Path) -> OSError:
    """The same error (type, errno, reason) about ``target``."""
    return type(err)(err.errno, err.strerror or str(err), str(target)) if err.errno else type(err)(f"{err}: {target}")


def atomic_write_bytes(path: str | os.PathLike, payload: bytes) -> Path:
    """Write ``payload`` to ``path`` atomically (see :func:`atomic_path`); returns the path."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(payload)
    return Path(path)


# ----------------------------------------------------------------------------- output sets
# A set of files (e.g. trajectory.npz, .csv, viewer.html) that must appear together or
# not at all. It is built in a temporary folder beside the target folder and swapped in
# with renames: a reader of the target sees the whole old set or the whole new one.
TEMP_TAG = ".nlo-lab-tmp-"  # temporary folders are named .{target}.nlo-lab-tmp-{pid}-{random}
_TEMP_RE = re.compile(r"^\.(?P<target>.*)\.nlo-lab-tmp-(?P<pid>\d+)-[0-9a-f]{8}$")
_RENAME_EXCHANGE = 2  # linux/fs.h


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    return True


def stale_temp_folders_in(folder: str | os.PathLike) -> list[Path]:
    """Temporary folders in ``folder``, of any target, whose writer is gone (killed, e.g. by SIGKILL)."""
    found = []
    try:
        with os.scandir(folder) as it:
            entries = list(it)
    except OSError:
        return []
    for entry in entries:
        m = _TEMP_RE.match(entry.name)
        if m and int(m["pid"]) != os.getpid() and not _alive(int(m["pid"])) and entry.is_dir(follow_symlinks=False):
            found.append(Path(entry.path))
    return found


def stale_temp_folders(target: str | os.PathLike) -> list[Path]:
    """Temporary folders of ``target`` whose writer is gone (killed, e.g. by SIGKILL)."""
    target = Path(os.path.abspath(target))
    return [p for p in stale_temp_folders_in(target.parent) if _TEMP_RE.match(p.name)["target"] == target.name]


def check_output_place(target: str | os.PathLike, names: tuple[str, ...]) -> Path:
    """Refuse a target folder that cannot take the set ``names``; returns its absolute path.

    Refused: an empty path; a target that exists but is not a folder (a file, ``/dev/null``),
    a path below a file, the root, the current folder or one of its parents, a folder holding
    an entry of the set that is not a plain file or holding a sub-folder or other non-file (the
    swap carries plain files over; it cannot carry folders), an existing folder owned by
    another user or without write permission for its owner (the swap replaces the folder as a
    whole: a folder someone made read-only, or someone else's, is not ours to replace), or a
    place we may not write in. Checked before any input is read.

    Raises:
        OutputError: naming the target and the reason.
    """
    if not isinstance(target, (str, os.PathLike)) or not os.fspath(target):
        raise OutputError(f"the output folder must be a non-empty path, got {target!r}")
    raw = Path(target)
    if "\x00" in str(raw):
        raise OutputError(f"the output folder {str(raw)!r} holds a NUL character")
    target = Path(os.path.realpath(raw))
    if target == Path(target.anchor):
        raise OutputError(f"{raw} is the root folder")
    if Path(os.getcwd()).is_relative_to(target):
        raise OutputError(f"{raw} is the current folder or one of its parents; choose a folder of its own")
    if os.path.lexists(target):
        if not target.is_dir():
            raise OutputError(f"{raw} exists and is not a folder")
        st = os.stat(target)
        if hasattr(os, "geteuid") and st.st_uid != os.geteuid():
            raise OutputError(f"{raw} belongs to another user (uid {st.st_uid}); nlo-lab replaces its output folder "
                              "as a whole, so it writes only into a folder of your own or a new one")
        if not st.st_mode & stat.S_IWUSR or not os.access(target, os.W_OK | os.X_OK):
            raise OutputError(f"{raw} is read-only (mode {stat.S_IMODE(st.st_mode):o}); make it writable or choose another folder")
        with os.scandir(target) as entries:
            blocking = sorted(e.name for e in entries if not e.is_file(follow_symlinks=False))
        if blocking:
            what = "an entry of the output set" if blocking[0] in names else "an entry the swap cannot carry over"
            raise OutputError(f"{raw} holds {blocking[0]!r}, {what}: it is not a plain file")
    writable_place(target.parent, str(raw))
    return target


def writable_place(path: str | os.PathLike, what: str) -> Path:
    """The nearest existing entry at or above ``path``, which must be a folder we may write in; returns it.

    Where a new output goes is decided by the first folder that exists on its path: the
    folders below it are made, so it is the one that must take them. ``what`` names the output
    in the message (``"out"``, ``"--save-pose out.pose"``).

    Raises:
        OutputError: the entry is not a folder (the path lies below a file), or it cannot be written.
    """
    place = Path(path)
    while not os.path.lexists(place):
        place = place.parent
    if not place.is_dir():
        raise OutputError(f"{what} lies below {place}, which is not a folder")
    if not os.access(place, os.W_OK | os.X_OK):
        raise OutputError(f"{what}: no permission to write in {place}")
    return place


def check_output_file(target: str | os.PathLike, *, what: str = "the output file", suffix: str | None = None,
                      parents: bool = False) -> Path:
    """Refuse a file path that cannot take an output (checked before any input is read); returns it.

    Refused: an empty path, one without ``suffix`` (when given), an existing entry that is not a
    plain file (a folder, a FIFO, a device), a file of another user or made read-only, a path
    below a file, a missing folder (unless ``parents``: then the nearest existing one), a folder
    we may not write in. ``what`` names the output in the message (``"--save-pose"``).

    Raises:
        OutputError: naming the path and the reason.
    """
    if not isinstance(target, (str, os.PathLike)) or not os.fspath(target) or "\x00" in os.fspath(target):
        raise OutputError(f"{what} must be a non-empty file path, got {target!r}")
    path = Path(target)
    if suffix is not None and path.suffix.lower() != suffix:
        raise OutputError(f"{what} {path} must end in {suffix}")
    if os.path.lexists(path):
        st = os.stat(path) if path.exists() else os.lstat(path)
        if not stat.S_ISREG(st.st_mode):
            raise OutputError(f"{what} {path} exists and is not a plain file")
        if hasattr(os, "geteuid") and st.st_uid != os.geteuid():
            raise OutputError(f"{what} {path} belongs to another user (uid {st.st_uid}); it is not replaced")
        if not st.st_mode & stat.S_IWUSR:
            raise OutputError(f"{what} {path} is read-only (mode {stat.S_IMODE(st.st_mode):o}); it is not replaced")
    folder = path.parent if str(path.parent) else Path(".")
    if not parents and not folder.is_dir():
        raise OutputError(f"{what} {path}: the folder {folder} does not exist")
    writable_place(folder, f"{what} {path}")
    return path


def _fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths in one step (Linux ``renameat2(RENAME_EXCHANGE)``); False where unsupported."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    AT_FDCWD = -100
    if renameat2(AT_FDCWD, os.fsencode(a), AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP):  # old kernel, or a file system without it
        return False
    raise OSError(err, os.strerror(err), str(b))


def _commit(tmp: Path, target: Path, names: tuple[str, ...]) -> None:
    """Make ``tmp`` (holding the new set) the target folder, keeping the target's files not in ``names``."""
    for name in os.listdir(tmp):
        with open(tmp / name, "rb") as fh:
            os.fsync(fh.fileno())
    _fsync_dir(tmp)
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.rename(tmp, target)  # no target yet (or an empty one): one rename
        _fsync_dir(target.parent)
        return
    except OSError as err:
        if err.errno not in (errno.EEXIST, errno.ENOTEMPTY):
            raise
    with os.scandir(target) as entries:  # carry the other plain files over (hard links: no copy)
        others = [e.path for e in entries if e.name not in names and e.is_file(follow_symlinks=False)]
    for other in others:
        try:
            os.link(other, tmp / os.path.basename(other))
        except OSError:
            shutil.copy2(other, tmp / os.path.basename(other))
    if not _exchange(tmp, target):  # no atomic swap here: the target is briefly absent, never mixed
        aside = target.parent / f".{target.name}{TEMP_TAG}{os.getpid()}-{secrets.token_hex(4)}"
        os.rename(target, aside)
        try:
            os.rename(tmp, target)
        except BaseException:
            os.rename(aside, target)  # the old set goes back: never a stale folder holding it
            raise
        tmp = aside
    _fsync_dir(target.parent)
    shutil.rmtree(tmp, ignore_errors=True)  # the old set


@contextlib.contextmanager
def output_set(target: str | os.PathLike, names: tuple[str, ...], replaces: tuple[str, ...] = ()) -> Iterator[Path]:
    """Yield an empty temporary folder; on success its files replace the set in ``target``.

    Write every file of the set (``names``) into the yielded folder. On normal exit
    the folder is swapped in with renames: ``target`` then holds the new set and the
    other plain files it held before, except those named in ``replaces`` (files of an
    older, larger set: ``batch`` without ``--viewer`` drops an older ``viewer.html``). On any exception (including
    ``KeyboardInterrupt``) the temporary folder is removed and nothing changes.
    Signals are blocked while the swap runs, so an interrupt lands before or after
    it, never half-way. Temporary folders of ``target`` left by a killed run are
    removed first.

    Raises:
        OutputError: see :func:`check_output_place`.
        OSError: writing failed (full disk, permissions); nothing is left behind.
    """
    target = check_output_place(target, names + tuple(replaces))
    for stale in stale_temp_folders(target):
        shutil.rmtree(stale, ignore_errors=True)
    parent = target.parent
    tmp = parent / f".{target.name}{TEMP_TAG}{os.getpid()}-{secrets.token_hex(4)}"
    try:
        parent.mkdir(parents=True, exist_ok=True)
        os.mkdir(tmp)
    except OSError as err:  # read-only file system, no permission, full disk: name the place, not our temp folder
        raise OutputError(f"cannot write in {parent}: {err.strerror or err}") from None
    try:
        try:
            yield tmp
        except OSError as err:  # name the user's target, not our temporary folder
            name = Path(err.filename).name if err.filename else ""
            where = target / name if name else target
            raise OutputError(f"cannot write {where}: {err.strerror or err}") from None
        missing = [n for n in names if not (tmp / n).is_file()]
        if missing:
            raise RuntimeError(f"the output set lacks {missing}")  # a bug of the caller
        blocked = _block_signals()
        try:
            _commit(tmp, target, names + tuple(n for n in replaces if n not in names))
        finally:
            _unblock_signals(blocked)
    finally:
        blocked = _block_signals()
        try:
            shutil.rmtree(tmp, ignore_errors=True)
        finally:
            _unblock_signals(blocked)


_BLOCKED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def _block_signals():
    if hasattr(signal, "pthread_sigmask"):
        return signal.pthread_sigmask(signal.SIG_BLOCK, _BLOCKED)
    return None


def _unblock_signals(previous) -> None:
    if previous is not None:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)

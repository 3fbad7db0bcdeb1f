"""The package's own exceptions.

Every error raised for bad input derives from :class:`NloLabError`, so callers
(and the command line, which turns them into exit status 2) can catch one type.
Messages name what is wrong and where: file, frame, field, link or joint.
"""

from __future__ import annotations

__all__ = [
    "NloLabError",
    "RobotDescriptionError",
    "UnknownRobotError",
    "DemonstrationError",
    "CheckpointError",
    "SettingsError",
    "OutputError",
    "Interrupted",
    "escape",
]


class NloLabError(Exception):
    """Base class of every error nlo_lab raises on purpose."""


class RobotDescriptionError(NloLabError):
    """A URDF or robot spec file is missing, malformed or inconsistent."""


class UnknownRobotError(RobotDescriptionError):
    """A robot name that is neither a bundled robot nor a spec file."""


class DemonstrationError(NloLabError):
    """A human demonstration that cannot be read or is not valid.

    Args:
        message: what is wrong.
        path: the file, when there is one.
        frame: the first offending frame index, when it applies.
        field: the offending field (e.g. ``"right/wrist"``), when it applies.
    """

    def __init__(self, message: str, *, path=None, frame: int | None = None, field: str | None = None):
        self.path = None if path is None else str(path)
        self.frame = frame
        self.field = field
        where = []
        if self.path is not None:
            where.append(f"file {self.path}")
        if frame is not None:
            where.append(f"frame {frame}")
        if field is not None:
            where.append(f"field {field}")
        super().__init__(f"{message} ({', '.join(where)})" if where else message)


class CheckpointError(NloLabError):
    """A checkpoint that is missing, corrupt, or made for another robot or format."""


class SettingsError(NloLabError, ValueError):
    """A setting out of range (a negative weight, zero iterations, an unknown init)."""


class OutputError(NloLabError):
    """An output place that cannot take the results (a file, blocking entries, no permission)."""


class Interrupted(KeyboardInterrupt):
    """A termination signal (SIGTERM, SIGHUP) turned into an exception, so clean-up code runs.

    A ``KeyboardInterrupt`` (what SIGINT raises), so every ``except KeyboardInterrupt``
    and ``finally`` that cleans up after Ctrl-C also cleans up after ``kill``.
    """

    def __init__(self, signum: int):
        self.signum = int(signum)
        super().__init__(f"signal {self.signum}")


def escape(text) -> str:
    """``text`` with every character a terminal could act on written as an escape.

    Names taken from files (HDF5 groups, ``.pose`` points, file names) reach error
    messages; escaped, a crafted name can neither add lines nor send terminal codes.
    """
    out = []
    for ch in str(text):
        if ch.isprintable():
            out.append(ch)
        else:
            code = ord(ch)
            out.append({"\n": "\\n", "\r": "\\r", "\t": "\\t"}.get(ch) or (f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"))
    return "".join(out)

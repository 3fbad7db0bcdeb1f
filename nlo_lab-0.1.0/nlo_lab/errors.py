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

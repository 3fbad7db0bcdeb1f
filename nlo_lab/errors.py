"""The package's own exceptions.

Every error raised for bad input derives from :class:`NloLabError`, so callers
(and the command line, which turns them into exit status 2) can catch one type.
Each class ALSO derives from the built-in exception a Python user would expect
there, so an ``except ValueError`` (or ``TypeError``, ``OSError``, ``LookupError``)
written before nlo_lab had its own classes keeps working::

    NloLabError
    ├── SettingsError            ValueError   a setting or argument out of its range
    │   └── SettingsTypeError    TypeError    ... or of the wrong type (LossWeights(ee="5"))
    ├── DemonstrationError       ValueError   a recording that cannot be read or is not valid
    ├── RobotDescriptionError    ValueError   a robot spec or URDF (and its meshes)
    │   └── UnknownRobotError    LookupError  a name that is no bundled robot and no spec file
    ├── CheckpointError          ValueError   a model checkpoint
    ├── TrajectoryError          ValueError   a robot trajectory (nlo_lab.inference)
    ├── OutputError              OSError      an output place that cannot take the results
    └── InstallationError        ImportError  a missing extra (JupyterLab, MediaPipe) or a damaged installation

Messages name what is wrong and where: file, frame, field, link or joint. An input
file that is missing, not a regular file or too large is reported by the reader's own
class (a bad ``.pose`` file is a :class:`DemonstrationError`, a bad URDF a
:class:`RobotDescriptionError`): :mod:`nlo_lab.files` checks every input first.
"""

from __future__ import annotations

import os

__all__ = [
    "NloLabError",
    "RobotDescriptionError",
    "UnknownRobotError",
    "DemonstrationError",
    "CheckpointError",
    "SettingsError",
    "SettingsTypeError",
    "OutputError",
    "InstallationError",
    "Interrupted",
    "escape",
]


class NloLabError(Exception):
    """Base class of every error nlo_lab raises on purpose.

    Args:
        message: what is wrong.
        path: the file it concerns, when there is one.
        frame: the first offending frame index, when it applies.
        field: the offending field (``"right/wrist"``, an archive member, a dataset), when it applies.

    The message ends with where, in parentheses: ``"NaN or inf (file x.npz, frame 7, field arm_positions)"``;
    :attr:`path`, :attr:`frame` and :attr:`field` keep the parts. The message is one line: what came
    from a file (a group name, a point name, a file name) is escaped (:func:`escape`).
    """

    def __init__(self, message: str = "", *, path: str | os.PathLike | None = None, frame: int | None = None,
                 field: str | None = None):
        where = [f"{label} {value}" for label, value in (("file", path), ("frame", frame), ("field", field)) if value is not None]
        super().__init__(escape(f"{message} ({', '.join(where)})" if where else message))
        self.path = None if path is None else str(path)
        self.frame = frame
        self.field = field


class RobotDescriptionError(NloLabError, ValueError):
    """A URDF, mesh or robot spec file is missing, malformed or inconsistent."""


class UnknownRobotError(RobotDescriptionError, LookupError):
    """A robot name that is neither a bundled robot nor a spec file."""


class DemonstrationError(NloLabError, ValueError):
    """A human demonstration that cannot be read or is not valid (file, frame and field named where they apply)."""


class CheckpointError(NloLabError, ValueError):
    """A checkpoint that is missing, corrupt, or made for another robot or format."""


class SettingsError(NloLabError, ValueError):
    """A setting or argument out of range (a negative weight, zero iterations, an unknown init)."""


class SettingsTypeError(SettingsError, TypeError):
    """A setting or argument of the wrong type (a string where a number goes, an int where a path goes)."""


class OutputError(NloLabError, OSError):
    """An output place that cannot take the results (a file, blocking entries, no permission)."""


class InstallationError(NloLabError, ImportError):
    """A missing extra (``pip install "nlo_lab[lab]"``) or a bundled file gone from a damaged installation."""


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

"""The ``nlo-lab`` command (README.md, "Command line": a contract).

One error path: every failure the command meets (input files, flags, output
places, disk, permissions, memory) ends with exit status 2 and one line on stderr
that names what is wrong and where, with names taken from files escaped
(:func:`nlo_lab.errors.escape`). Only a bug of nlo_lab itself gives a traceback
(exit 1). Warnings, ours and the libraries', go through one channel: one line
each (``nlo-lab: warning: ...``), silenced by ``--quiet``. SIGTERM, SIGHUP and
SIGINT end the run with exit 128+signal after the clean-up ran: the outputs of
``retarget --out`` appear as a whole set or not at all (:func:`nlo_lab.atomic_files.output_set`).

The package: :mod:`~nlo_lab.cli.program` (the entry point :func:`main`, which takes the signals of the
process's first and last instants; the program's very first lines are :mod:`nlo_lab.__main__`'s), :mod:`~nlo_lab.cli.app` (the registry of commands, :func:`build_parser`, the run
and its error path), :mod:`~nlo_lab.cli.run_guard` (how a run ends: error line, warnings,
signals), :mod:`~nlo_lab.cli.flags` (ranges, flag types, the parser class), and one module
per command: :mod:`~nlo_lab.cli.retarget`, :mod:`~nlo_lab.cli.train`, :mod:`~nlo_lab.cli.evaluate`,
:mod:`~nlo_lab.cli.demo`, :mod:`~nlo_lab.cli.lab`, :mod:`~nlo_lab.cli.batch`, :mod:`~nlo_lab.cli.robot`.
"""

import importlib

# the command line's entry points, then the stated ranges of its numeric flags (docs/ARCHITECTURE.md)
__all__ = ["main", "build_parser", "COMMANDS", "UsageError", "OUTPUT_FILES", "DEMO_CLIP",
           "MAX_SEED", "ITERS_RANGE", "EPOCHS_RANGE", "LIMIT_RANGE", "THREADS_RANGE", "BATCH_RANGE", "LATENT_RANGE", "WEIGHT_RANGE"]  # fmt: skip


def __getattr__(name: str):
    """The public names, imported from their module on first use: ``python -m nlo_lab.cli`` imports this package
    before its ``__main__``, whose first act is to take the signals (:mod:`nlo_lab.__main__`)."""
    homes = {
        "main": "nlo_lab.cli.program",
        "build_parser": "nlo_lab.cli.app",
        "COMMANDS": "nlo_lab.cli.app",
        "DEMO_CLIP": "nlo_lab.cli.demo",
        "OUTPUT_FILES": "nlo_lab.cli.retarget",
        **{flag: "nlo_lab.cli.flags" for flag in ("UsageError", "MAX_SEED", "ITERS_RANGE", "EPOCHS_RANGE", "LIMIT_RANGE",
                                                 "THREADS_RANGE", "BATCH_RANGE", "LATENT_RANGE", "WEIGHT_RANGE")},
    }
    if name not in homes:
        raise AttributeError(f"module 'nlo_lab.cli' has no attribute {name!r}")
    value = getattr(importlib.import_module(homes[name]), name)
    globals()[name] = value
    return value

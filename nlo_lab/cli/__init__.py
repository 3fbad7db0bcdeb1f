"""The ``nlo-lab`` command (README.md, "Command line": a contract).

One error path: every failure the command meets (input files, flags, output
places, disk, permissions, memory) ends with exit status 2 and one line on stderr
that names what is wrong and where, with names taken from files escaped
(:func:`nlo_lab.errors.escape`). Only a bug of nlo_lab itself gives a traceback
(exit 1). Warnings, ours and the libraries', go through one channel: one line
each (``nlo-lab: warning: ...``), silenced by ``--quiet``. SIGTERM, SIGHUP and
SIGINT end the run with exit 128+signal after the clean-up ran: the outputs of
``retarget --out`` appear as a whole set or not at all (:func:`nlo_lab.atomic_files.output_set`).

The package: :mod:`~nlo_lab.cli.app` (the registry of commands, :func:`build_parser`, :func:`main`
and its error path), :mod:`~nlo_lab.cli.run_guard` (how a run ends: error line, warnings,
signals), :mod:`~nlo_lab.cli.flags` (ranges, flag types, the parser class), and one module
per command: :mod:`~nlo_lab.cli.retarget`, :mod:`~nlo_lab.cli.train`, :mod:`~nlo_lab.cli.evaluate`,
:mod:`~nlo_lab.cli.demo`, :mod:`~nlo_lab.cli.lab`, :mod:`~nlo_lab.cli.batch`.
"""

from nlo_lab.cli.app import COMMANDS, build_parser, main
from nlo_lab.cli.demo import DEMO_CLIP
from nlo_lab.cli.flags import (
    BATCH_RANGE,
    EPOCHS_RANGE,
    ITERS_RANGE,
    LATENT_RANGE,
    LIMIT_RANGE,
    MAX_SEED,
    THREADS_RANGE,
    WEIGHT_RANGE,
    UsageError,
)
from nlo_lab.cli.retarget import OUTPUT_FILES

# the command line's entry points, then the stated ranges of its numeric flags (docs/ARCHITECTURE.md)
__all__ = ["main", "build_parser", "COMMANDS", "UsageError", "OUTPUT_FILES", "DEMO_CLIP",
           "MAX_SEED", "ITERS_RANGE", "EPOCHS_RANGE", "LIMIT_RANGE", "THREADS_RANGE", "BATCH_RANGE", "LATENT_RANGE", "WEIGHT_RANGE"]  # fmt: skip

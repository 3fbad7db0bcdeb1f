"""The one parser of ``nlo-lab`` and the one error path around every command.

:data:`COMMANDS` is the registry: each command is a module of this package with
``add_parser(subparsers)`` (its flags) and ``run(args) -> int`` (its work, which
imports what it needs when it runs, so that ``--help`` and a bad flag never wait
for torch); a module with ``NEEDS_TORCH = False`` runs without torch imported here. Adding a command is one module plus one line here (CONTRIBUTING.md).
"""

from __future__ import annotations

import argparse
import signal

from nlo_lab.cli import batch, demo, evaluate, lab, retarget, robot, train
from nlo_lab.cli.flags import Parser
from nlo_lab.cli.run_guard import (
    error_line,
    interrupted_line,
    one_warning_channel,
    os_error_text,
    pending_signal,
    raise_pending_signal,
    signals_raise,
)
from nlo_lab.errors import Interrupted, NloLabError

__all__ = ["COMMANDS", "build_parser", "run"]

# command name -> its module, in the order `nlo-lab --help` lists them
COMMANDS = {
    "retarget": retarget,
    "train": train,
    "evaluate": evaluate,
    "demo": demo,
    "lab": lab,
    "batch": batch,
    "robot": robot,
}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``nlo-lab`` (exposed for the docs and the tests); the only one of nlo_lab."""
    parser = Parser(prog="nlo-lab", description="Kinematic motion retargeting by neural latent optimisation.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for module in COMMANDS.values():
        module.add_parser(sub)
    return parser


def run(argv: list[str] | None = None) -> int:
    """Parse ``argv`` and run its command inside the one error path; returns the exit status.

    The entry point is :func:`nlo_lab.cli.program.main` (``nlo_lab.cli.main``), which also
    takes the signals of the process's first and last instants.
    """
    with signals_raise():
        try:
            args = build_parser().parse_args(argv)
            with one_warning_channel(getattr(args, "quiet", False)):
                if getattr(COMMANDS[args.command], "NEEDS_TORCH", True):  # batch's own process does without it
                    import torch  # here, not at the top: `--help` and a bad flag never wait for it

                    from nlo_lab.threads import default_threads

                    torch.set_num_threads(default_threads())  # see nlo_lab.threads: one thread unless NLO_LAB_THREADS says otherwise
                status = COMMANDS[args.command].run(args)
                raise_pending_signal()
                return status
        except BaseException as exc:  # noqa: BLE001 - the one error path: each kind below, a bug re-raised
            return ending(exc)


def ending(exc: BaseException) -> int:
    """The exit status of a run that raised ``exc``, its one line printed; a bug of nlo_lab is raised again (a traceback).

    A signal may surface as another exception: raised inside a C extension's import it becomes an
    ImportError, and a reader may name what it became. Once a signal came, the run ends as interrupted.
    """
    signum = pending_signal()
    if signum is not None:
        return interrupted_line(signum)
    if isinstance(exc, Interrupted):
        return interrupted_line(exc.signum)
    if isinstance(exc, KeyboardInterrupt):
        return interrupted_line(signal.SIGINT)
    if isinstance(exc, NloLabError):
        return error_line(exc)
    if isinstance(exc, FileNotFoundError):
        return error_line(f"file not found: {exc.filename}")
    if isinstance(exc, MemoryError):
        return error_line("out of memory (the input is too large for this machine; try a shorter recording)")
    if isinstance(exc, OSError):  # disk full, permissions, I/O errors: the environment, not a bug
        return error_line(os_error_text(exc))
    raise exc

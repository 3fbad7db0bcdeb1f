"""The one parser of ``nlo-lab`` and the one error path around every command.

:data:`COMMANDS` is the registry: each command is a module of this package with
``add_parser(subparsers)`` (its flags) and ``run(args) -> int`` (its work, which
imports what it needs when it runs, so that ``--help`` and a bad flag never wait
for torch); a module with ``NEEDS_TORCH = False`` runs without torch imported here. Adding a command is one module plus one line here (CONTRIBUTING.md).
"""

from __future__ import annotations

import argparse
import signal
import sys

from nlo_lab.cli import batch, demo, evaluate, lab, retarget, train
from nlo_lab.cli.flags import Parser
from nlo_lab.cli.run_guard import error_line, one_warning_channel, os_error_text, raise_pending_signal, signals_raise
from nlo_lab.errors import Interrupted, NloLabError

__all__ = ["COMMANDS", "build_parser", "main"]

# command name -> its module, in the order `nlo-lab --help` lists them
COMMANDS = {
    "retarget": retarget,
    "train": train,
    "evaluate": evaluate,
    "demo": demo,
    "lab": lab,
    "batch": batch,
}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``nlo-lab`` (exposed for the docs and the tests); the only one of nlo_lab."""
    parser = Parser(prog="nlo-lab", description="Kinematic motion retargeting by neural latent optimisation.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for module in COMMANDS.values():
        module.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``nlo-lab``; returns the exit status (0 ok, 2 bad input or a fault, 128+N on signal N)."""
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
        except NloLabError as exc:
            return error_line(exc)
        except FileNotFoundError as exc:
            return error_line(f"file not found: {exc.filename}")
        except MemoryError:
            return error_line("out of memory (the input is too large for this machine; try a shorter recording)")
        except OSError as exc:  # disk full, permissions, I/O errors: the environment, not a bug
            return error_line(os_error_text(exc))
        except Interrupted as exc:
            name = signal.Signals(exc.signum).name
            print(f"nlo-lab: interrupted by {name}", file=sys.stderr)
            return 128 + exc.signum
        except KeyboardInterrupt:
            print("nlo-lab: interrupted by SIGINT", file=sys.stderr)
            return 128 + signal.SIGINT

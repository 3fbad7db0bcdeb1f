"""The ``nlo-lab`` program: its entry point, which takes the signals of the process's first and last instants.

Run as the program (the console script, ``python -m nlo_lab.cli``), :func:`main` takes SIGTERM,
SIGHUP and SIGINT from its first line to the process's last instant: during the imports and the
run they end it with exit status 128 + N and at most one line, after the clean-up
(:mod:`nlo_lab.cli.run_guard`); once the run is over, its output is flushed and the process ends
at once (``os._exit``: Python's own teardown would put the default handlers back, and a signal
would then kill the process raw); a signal in between ends it with 128 + N and no line. This
module imports nothing heavy, so the handlers are in place a few milliseconds after Python hands
over to nlo_lab; a signal during Python's own start, before that, is Python's to handle.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading

from nlo_lab.cli.run_guard import TERMINATING, cancel_retry, clear, interrupted_line, on_signal, pending_signal, raise_pending_signal
from nlo_lab.errors import Interrupted

__all__ = ["main"]


def _exit_now(signum, frame):
    os._exit(128 + signum)  # the run is over and its output flushed: nothing left to clean up


def _install(handler) -> None:
    for name in TERMINATING:
        if hasattr(signal, name) and signal.getsignal(getattr(signal, name)) is not signal.SIG_IGN:  # nohup's SIGHUP stays ignored
            signal.signal(getattr(signal, name), handler)


def _flush() -> None:
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()


def main(argv: list[str] | None = None) -> int:
    """Run ``nlo-lab``; returns the exit status (0 ok, 2 bad input or a fault, 128+N on signal N).

    Args:
        argv: the arguments; None: the program's own (``sys.argv``): the signal handlers are
            installed first and the process ends when the run does (see the module docstring;
            this function then does not return). Given ``argv`` (a test, a script), the
            handlers are restored and the status is returned.
    """
    program = argv is None and threading.current_thread() is threading.main_thread()
    clear()
    status: int | None = None
    try:
        if program:
            _install(on_signal)  # before the imports below: numpy and the parser take a few hundred ms
        try:
            from nlo_lab.cli.app import run

            raise_pending_signal()  # one that came inside the import above (on_signal defers it)
            status = run(argv)
        except BaseException:  # during the imports (a signal there may surface as an ImportError), or a bug
            signum = pending_signal()
            if signum is None:
                raise
            status = interrupted_line(signum)
        if program:
            _flush()
            _install(_exit_now)
            cancel_retry()
    except Interrupted as exc:  # right after the handlers went in (no line yet), or in the run's last instants
        if program:
            _install(_exit_now)
            cancel_retry()
        status = interrupted_line(exc.signum) if status is None else 128 + exc.signum
    if program:
        _flush()
        os._exit(status)  # no interpreter teardown: everything the run wrote is closed and flushed
    return status

"""``nlo-lab`` (the console script's entry point) and ``python -m nlo_lab``: the program's first lines.

Before this module, Python runs its own start: the interpreter, ``site`` with the installed
packages' ``.pth`` files, the console script's ``import sys``, then ``nlo_lab/__init__.py`` (a
table of names). A signal in that window is Python's: SIGTERM and SIGHUP end the process by the
signal itself, SIGINT gives Python's ``KeyboardInterrupt`` traceback (docs/DESIGN.md, "Signals",
measures the window). This module's first act, before any other import, is to take SIGTERM,
SIGHUP and SIGINT: until the entry point puts in the handlers of the run
(:func:`nlo_lab.cli.program.main`, once its modules are imported, a few milliseconds later), a
signal ends the process at once with status 128 + N and the one line ``nlo-lab: interrupted by
SIGx``: nothing has been read or written yet, so there is nothing to clean up. A signal the
program was started with ignored (``nohup nlo-lab ...`` ignores SIGHUP) stays ignored, here and in
the run.

Only the program imports this module: importing it takes the signals of the process.
"""

import os
import signal


def _interrupted(signum, frame):
    try:
        os.write(2, f"nlo-lab: interrupted by {signal.Signals(signum).name}\n".encode())
    except OSError:  # no stderr: the status still says it
        pass
    os._exit(128 + signum)


for _name in ("SIGTERM", "SIGHUP", "SIGINT"):  # nlo_lab.cli.run_guard.TERMINATING, not imported yet
    # one ignored when the program starts stays ignored (`nohup nlo-lab ...`: SIGHUP; `nlo-lab ... &` in a script: SIGINT)
    if hasattr(signal, _name) and signal.getsignal(getattr(signal, _name)) is not signal.SIG_IGN:
        signal.signal(getattr(signal, _name), _interrupted)

import sys  # noqa: E402  (after the handlers: every import below is inside the covered window)

from nlo_lab.cli.program import main  # noqa: E402

__all__ = ["main"]

if __name__ == "__main__":
    sys.exit(main())

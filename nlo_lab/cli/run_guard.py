"""How a run of ``nlo-lab`` ends: one error line, one warning channel, signals that clean up.

* The entry point, :func:`nlo_lab.cli.program.main`, installs these handlers before any heavy
  import and ends the process when the run ends (signals at any instant).
* :func:`signals_raise`: SIGTERM, SIGHUP and SIGINT raise :class:`~nlo_lab.errors.Interrupted`
  (once: a second signal during the clean-up is recorded, not raised), so ``finally`` blocks
  (the temporary output folder of ``retarget --out``) run; :func:`raise_pending_signal`
  re-raises one that some library's ``except BaseException`` swallowed.
* :func:`one_warning_channel`: the run's warnings, ours and the libraries', as one line each.
* :func:`error_line`: the one line on stderr and exit status 2; :func:`os_error_text` names an
  ``OSError``'s reason and file.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
import warnings

from nlo_lab.errors import Interrupted, escape

__all__ = ["signals_raise", "raise_pending_signal", "one_warning_channel", "error_line", "os_error_text",
           "interrupted_line", "pending_signal", "on_signal", "cancel_retry", "clear", "TERMINATING"]

TERMINATING = ("SIGTERM", "SIGHUP", "SIGINT")
_pending: list[int] = []  # signals received, even those some library's `except BaseException` swallowed
_said: list[str] = []  # the lines this run printed on stderr: an interrupted run adds its line only to none


RETRY_SECONDS = 0.02  # how soon a signal that came inside an import is raised again (once the import is over)


def _inside_import(frame) -> bool:
    """Whether ``frame`` runs (directly or not) inside an ``import``."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib._bootstrap"):
            return True
        frame = frame.f_back
    return False


def on_signal(signum, frame):
    """The handler of a run: record the signal; raise :class:`Interrupted` for the first one.

    Not inside an import: a C extension's initialisation may call Python code from C++ (torch's
    ``torch.distributed`` does), and an exception raised there aborts the process (``terminate
    called after throwing an instance of 'pybind11::error_already_set'``, exit by SIGABRT). The
    signal is then raised by a SIGALRM every :data:`RETRY_SECONDS` once the import is over. One
    raised where Python cannot propagate it (a weakref callback) is raised again the same way.
    """
    _pending.append(signum)
    if len(_pending) != 1:  # a second signal while the first one's clean-up runs is recorded, not raised
        return
    _catch_swallowed()
    if _inside_import(frame):
        _retry_later()
        return
    raise Interrupted(signum)


_alarm_before: list = []  # SIGALRM's handler before a retry took it
_hook_before: list = []  # sys.unraisablehook before a signal came


def _swallowed(info) -> None:
    """sys.unraisablehook once a signal came: an Interrupted raised where Python cannot propagate it
    (a ``__del__``, a weakref callback: "Exception ignored in ...") is raised again soon, unprinted."""
    if isinstance(info.exc_value, Interrupted):
        _retry_later()
        return
    (_hook_before[0] if _hook_before else sys.__unraisablehook__)(info)


def _catch_swallowed() -> None:
    if sys.unraisablehook is not _swallowed:
        _hook_before[:] = [sys.unraisablehook]
        sys.unraisablehook = _swallowed


def _release_swallowed() -> None:
    if sys.unraisablehook is _swallowed:
        sys.unraisablehook = _hook_before[0] if _hook_before else sys.__unraisablehook__


def _on_retry(signum, frame):
    if _inside_import(frame):
        signal.setitimer(signal.ITIMER_REAL, RETRY_SECONDS)
        return
    cancel_retry()
    raise Interrupted(_pending[0])


def _retry_later() -> None:
    if hasattr(signal, "setitimer"):
        if signal.getsignal(signal.SIGALRM) is not _on_retry:
            _alarm_before[:] = [signal.signal(signal.SIGALRM, _on_retry)]
        signal.setitimer(signal.ITIMER_REAL, RETRY_SECONDS)


def cancel_retry() -> None:
    """Stop a pending retry and give SIGALRM its handler back (the signal is being raised, or the run is over)."""
    if hasattr(signal, "setitimer") and signal.getsignal(signal.SIGALRM) is _on_retry:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, _alarm_before[0] if _alarm_before and _alarm_before[0] is not None else signal.SIG_DFL)


def clear() -> None:
    """Forget the signals and lines of an earlier run (a new run in this process)."""
    _pending.clear()
    _said.clear()


def _say(line: str) -> None:
    _said.append(line)
    print(line, file=sys.stderr)


def interrupted_line(signum: int) -> int:
    """The line of an interrupted run (unless the run already said something); returns 128 + ``signum``."""
    if not _said:
        _say(f"nlo-lab: interrupted by {signal.Signals(signum).name}")
    return 128 + signum


def pending_signal() -> int | None:
    """The first signal this run received (None: none)."""
    return _pending[0] if _pending else None


def raise_pending_signal() -> None:
    if _pending:
        cancel_retry()
        raise Interrupted(_pending[0])


@contextlib.contextmanager
def signals_raise():
    """SIGTERM, SIGHUP and SIGINT raise :class:`Interrupted` (so ``finally`` blocks clean up); an ignored one stays ignored."""
    if threading.current_thread() is not threading.main_thread():  # handlers only install there
        yield
        return
    previous = {}
    for name in TERMINATING:
        if hasattr(signal, name):
            sig = getattr(signal, name)
            if signal.getsignal(sig) is not signal.SIG_IGN:  # one the process was told to ignore (nohup's SIGHUP) stays so
                previous[sig] = signal.signal(sig, on_signal)
    own_run = on_signal not in previous.values()  # not under the program's handlers (nlo_lab.cli.program)
    if own_run:
        _pending.clear()
    try:
        yield
    finally:
        if own_run:  # its retry and hook end with it
            cancel_retry()
            _release_swallowed()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@contextlib.contextmanager
def one_warning_channel(quiet: bool):
    """Collect the run's warnings; print each distinct one as one line when the run succeeds.

    A failed run prints its error line only (the one line the error path promises).
    Python's default filters apply (deprecations inside libraries are not the user's business).
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.resetwarnings()
        warnings.simplefilter("ignore" if quiet else "default")
        for category in (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning):
            warnings.filterwarnings("ignore", category=category)
        yield
    seen = set()
    for w in caught:
        line = f"nlo-lab: warning: {escape(w.message)}"
        if line not in seen:
            seen.add(line)
            _say(line)


def error_line(message) -> int:
    _say(f"nlo-lab: error: {escape(message)}")
    return 2


def os_error_text(exc: OSError) -> str:
    reason = exc.strerror or str(exc) or type(exc).__name__
    where = exc.filename if exc.filename is not None else None
    return f"{reason}: {where}" if where is not None else reason

"""How many CPU threads torch and numpy's BLAS use for our (small) problems.

Retargeting is hundreds of tiny tensor operations per iteration. With more
than one intra-op thread, each operation hands work to a thread pool; on a
2-core machine with anything else running, those hand-offs spin and wait and
a 1.5 s job can take a minute (measured: FK of 133 frames of YuMi, 1.5 ms on
one thread against 95 ms on two, with a second process busy). So the command
line, the notebooks and :func:`nlo_lab.pipeline.retarget` use one thread.

numpy's BLAS (OpenBLAS in numpy's wheels) keeps its own pool, one thread per core, which
torch's setting does not reach: the numpy forms of the decoder, FK and the objective
(:mod:`nlo_lab.inference.fast_paths`) then spent 15-20 ms in one 30 us product now and
then on a busy machine. :func:`single_thread` limits that pool too (threadpoolctl).

``NLO_LAB_THREADS`` is validated like the ``--threads`` flag: a whole number in
:data:`THREADS_RANGE` (1..256), else a :class:`~nlo_lab.errors.SettingsError` naming the
variable (exit status 2 on the command line). torch crashes (SIGSEGV) when asked for 100,000
threads, so a bad value is refused before any thread is made.
"""

from __future__ import annotations

import contextlib
import functools
import os
from collections.abc import Iterator

from nlo_lab.errors import SettingsError
from nlo_lab.settings import check_int

__all__ = ["THREADS_RANGE", "check_threads", "env_threads", "single_thread", "default_threads"]

THREADS_RANGE = (1, 256)  # torch threads or pose-estimation processes: the --threads flag's range too
ENV = "NLO_LAB_THREADS"


def check_threads(name: str, value) -> int:
    """A thread count: a whole number in :data:`THREADS_RANGE`."""
    return check_int(name, value, *THREADS_RANGE)


def env_threads() -> int | None:
    """``NLO_LAB_THREADS`` as a whole number in :data:`THREADS_RANGE`; None when it is unset or empty.

    Raises:
        SettingsError: any other value (a word, 0, 100000, a 20-digit number), naming the variable.
    """
    text = os.environ.get(ENV, "").strip()
    if not text:
        return None
    lo, hi = THREADS_RANGE
    if len(text) > 40:  # int() of a huge digit string is slow, and its echo floods the line
        raise SettingsError(f"{ENV} must be a whole number in [{lo}, {hi}], got {len(text)} characters")
    try:
        value = int(text)
    except ValueError:
        raise SettingsError(f"{ENV} must be a whole number in [{lo}, {hi}], got {text!r}") from None
    if not lo <= value <= hi:
        raise SettingsError(f"{ENV} must be a whole number in [{lo}, {hi}], got {text}")
    return value


def default_threads() -> int:
    """Threads for our work: ``NLO_LAB_THREADS`` if set (validated, :func:`env_threads`), else 1."""
    return env_threads() or 1


@contextlib.contextmanager
def single_thread(n: int | None = None) -> Iterator[None]:
    """Run the block with ``n`` torch and BLAS threads (default :func:`default_threads`), then restore."""
    # lazy: torch: the command line's --help and bad flags do not wait for it
    import torch

    n = default_threads() if n is None else check_threads("threads", n)
    previous = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        with _blas().limit(limits=n, user_api="blas"):  # about 10 us to enter and leave
            yield
    finally:
        torch.set_num_threads(previous)


@functools.cache
def _blas():
    """The loaded BLAS libraries' thread pools (threadpoolctl; found once, the search takes about 0.5 ms)."""
    # lazy: only when threads are set
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()

"""How many CPU threads torch uses for our (small) problems.

Retargeting is hundreds of tiny tensor operations per iteration. With more
than one intra-op thread, each operation hands work to a thread pool; on a
2-core machine with anything else running, those hand-offs spin and wait and
a 1.5 s job can take a minute (measured: FK of 133 frames of YuMi, 1.5 ms on
one thread against 95 ms on two, with a second process busy). So the command
line, the notebooks and :func:`nlo_lab.inference.retarget` use one thread.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

import torch

__all__ = ["single_thread", "default_threads"]


def default_threads() -> int:
    """Threads for our work: ``NLO_LAB_THREADS`` if set, else 1."""
    try:
        return max(1, int(os.environ.get("NLO_LAB_THREADS", "1")))
    except ValueError:
        return 1


@contextlib.contextmanager
def single_thread(n: int | None = None) -> Iterator[None]:
    """Run the block with ``n`` torch threads (default :func:`default_threads`), then restore."""
    previous = torch.get_num_threads()
    torch.set_num_threads(n or default_threads())
    try:
        yield
    finally:
        torch.set_num_threads(previous)

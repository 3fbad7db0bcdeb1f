"""Run a notebook with nbclient, without the 10-minute stalls (tests/notebooks, tools/docs.py, nbconvert in tests).

nbclient waits for a cell's ``execute_reply`` with one poll of the whole cell timeout (600 s in the
tests) on jupyter_client's asyncio shell socket. pyzmq wakes such a poll through the socket's
edge-triggered file descriptor, and now and then (on a loaded machine, a few times per ``make test``)
that wake-up is lost although the reply has arrived: kernel and client then sit idle until the poll
times out, when pyzmq polls the socket itself, finds the reply and the run goes on and passes, one
timeout later. Seen in CI as ``tests/notebooks/test_work_folder.py`` idle about 10 minutes inside a
notebook (py-spy: the kernel idle in its event loop, no cell running; the client in nbclient's wait).

:class:`PatientKernelManager`'s clients wait in polls of at most :data:`POLL_SECONDS`, each ending in
that real poll of the socket, so a message is read at most :data:`POLL_SECONDS` late; the timeouts
mean what they meant (the slices add up to them). Use it with
``NotebookClient(..., kernel_manager_class=PatientKernelManager)``, or :func:`notebook_client`.
"""

from __future__ import annotations

import time
from queue import Empty
from typing import Any

from jupyter_client.asynchronous import AsyncKernelClient
from jupyter_client.channels import AsyncZMQSocketChannel
from jupyter_client.manager import AsyncKernelManager
from traitlets import Type, default

__all__ = ["Empty", "POLL_SECONDS", "PatientChannel", "PatientKernelClient", "PatientKernelManager", "notebook_client"]

POLL_SECONDS = 1.0  # a lost wake-up costs at most this


class PatientChannel(AsyncZMQSocketChannel):
    """A channel whose ``get_msg(timeout)`` polls in slices of at most :data:`POLL_SECONDS` (None: no end)."""

    async def get_msg(self, timeout: float | None = None) -> dict[str, Any]:
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            left = POLL_SECONDS if deadline is None else max(0.0, deadline - time.monotonic())
            try:
                return await super().get_msg(timeout=min(POLL_SECONDS, left))
            except Empty:
                if deadline is not None and time.monotonic() >= deadline:
                    raise


class PatientKernelClient(AsyncKernelClient):
    """jupyter_client's asyncio client with :class:`PatientChannel` for every ZMQ channel."""

    shell_channel_class = Type(PatientChannel)  # type: ignore[assignment]
    iopub_channel_class = Type(PatientChannel)  # type: ignore[assignment]
    stdin_channel_class = Type(PatientChannel)  # type: ignore[assignment]
    control_channel_class = Type(PatientChannel)  # type: ignore[assignment]


class PatientKernelManager(AsyncKernelManager):
    """The kernel manager nbclient uses, handing out :class:`PatientKernelClient` clients."""

    @default("client_factory")
    def _client_factory_default(self) -> type:
        return PatientKernelClient


def notebook_client(nb, **kwargs):
    """``nbclient.NotebookClient(nb, **kwargs)`` whose kernel's client is a :class:`PatientKernelClient`."""
    from nbclient import NotebookClient

    return NotebookClient(nb, kernel_manager_class=PatientKernelManager, **kwargs)

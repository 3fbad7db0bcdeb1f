"""The live meshcat viewer: a server on 127.0.0.1 owned by this process.

:class:`Viewer` starts :mod:`nlo_lab.viz._meshcat_server` in a subprocess
(loopback only), connects a meshcat ``Visualizer`` to it, and stops it on
``close()``, on leaving a ``with`` block, at interpreter exit (atexit) and, when
the owner is killed outright (nbval kills kernels with SIGKILL), by the server
itself, which watches its parent pid.

:func:`live_viewer` returns a reachable :class:`Viewer` or ``None``; notebooks
then fall back to the static view (:func:`show`).
"""

from __future__ import annotations

import atexit
import contextlib
import io
import os
import selectors
import subprocess
import sys
import time
import urllib.request
import weakref
from typing import Any

from nlo_lab.errors import NloLabError

__all__ = ["Viewer", "ViewerError", "live_viewer", "static_viewer_requested", "show", "STATIC_ENV"]

STATIC_ENV = "NLO_LAB_STATIC_VIEWER"  # set to 1 to never start a live server (CI, Binder)


class ViewerError(NloLabError):
    """The live viewer server could not be started or reached."""


def _stop_process(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=3)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=3)
    for stream in (proc.stdout, proc.stderr):
        if stream is not None:
            stream.close()


def _read_lines(proc: subprocess.Popen, wanted: tuple[str, ...], deadline: float) -> dict[str, str]:
    """``key=value`` lines the server prints at start, read unbuffered (select + os.read) until all ``wanted`` keys are seen."""
    fd = proc.stdout.fileno()
    buf, found = b"", {}
    sel = selectors.DefaultSelector()
    sel.register(fd, selectors.EVENT_READ)
    try:
        while len(found) < len(wanted):
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                key, sep, value = line.decode("utf-8", "replace").strip().partition("=")
                if sep and key in wanted:
                    found[key] = value
            if len(found) == len(wanted):
                break
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise ViewerError("the viewer server did not start in time")
            if sel.select(timeout=min(0.2, remaining)):
                chunk = os.read(fd, 4096)
                if not chunk:
                    raise ViewerError(f"the viewer server exited early (status {proc.wait(timeout=5)})")
                buf += chunk
    finally:
        sel.close()
    return found


class Viewer:
    """A live meshcat viewer whose server listens on 127.0.0.1 and dies with its owner.

    Args:
        timeout: seconds to wait for the server to start [s].

    Attributes:
        vis: the meshcat ``Visualizer`` connected to the server.
        url: the viewer's web address (``http://127.0.0.1:PORT/static/``).
        zmq_url: the command socket (``tcp://127.0.0.1:PORT``).
        pid: the server's process id.
    """

    def __init__(self, timeout: float = 15.0):
        import meshcat
        import zmq
        from meshcat.visualizer import ViewerWindow

        cmd = [sys.executable, "-u", "-m", "nlo_lab.viz._meshcat_server", "--parent-pid", str(os.getpid())]
        # Own session: an interrupted notebook cell must not take the server down; the parent watch does.
        self._proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, start_new_session=True)
        self._finalizer = weakref.finalize(self, _stop_process, self._proc)  # runs at close(), GC, or exit
        atexit.register(self._finalizer)
        try:
            lines = _read_lines(self._proc, ("zmq_url", "web_url"), time.monotonic() + timeout)
            self.zmq_url, self.url = lines["zmq_url"], lines["web_url"]
            with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints the URL
                window = ViewerWindow(zmq_url=self.zmq_url, start_server=False, server_args=[])
            for sock in (window.zmq_socket,):
                sock.setsockopt(zmq.RCVTIMEO, int(timeout * 1000))  # never block forever on a dead server
                sock.setsockopt(zmq.SNDTIMEO, int(timeout * 1000))
                sock.setsockopt(zmq.LINGER, 0)
            self._window = window
            self.vis = meshcat.Visualizer(window=window)
        except BaseException:
            self.close()
            raise

    @property
    def pid(self) -> int:
        return self._proc.pid

    @property
    def alive(self) -> bool:
        return self._proc.poll() is None

    def reachable(self, timeout: float = 2.0) -> bool:
        """True if the web page answers on 127.0.0.1."""
        try:
            with urllib.request.urlopen(self.url, timeout=timeout) as resp:
                return resp.status == 200
        except OSError:
            return False

    def static_html(self) -> str:
        """The current scene as a self-contained page."""
        return self.vis.static_html()

    def jupyter_cell(self, height: int = 400):
        """An ``IPython.display.HTML`` iframe of the live viewer."""
        return self.vis.jupyter_cell(height=height)

    def close(self) -> None:
        """Stop the server (idempotent). meshcat's own ``Visualizer.close()`` raises in 0.3.2."""
        window = getattr(self, "_window", None)
        if window is not None:
            window.zmq_socket.close(linger=0)
            self._window = None
        self._finalizer()

    def __enter__(self) -> "Viewer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Viewer(url={self.url!r}, alive={self.alive})"


def static_viewer_requested() -> bool:
    """True when the environment asks for the static view (``NLO_LAB_STATIC_VIEWER=1``; Binder; CI)."""
    value = os.environ.get(STATIC_ENV, "").strip().lower()
    if value in ("1", "true", "yes", "on"):
        return True
    return bool(os.environ.get("BINDER_SERVICE_HOST") or os.environ.get("BINDER_REQUEST"))


def live_viewer(timeout: float = 15.0) -> Viewer | None:
    """A running, reachable :class:`Viewer`, or ``None`` (static view requested, or no server possible)."""
    if static_viewer_requested():
        return None
    try:
        viewer = Viewer(timeout=timeout)
    except (ViewerError, OSError, ImportError):
        return None
    if not viewer.reachable():
        viewer.close()
        return None
    return viewer


def show(viewer: Viewer | None, page: str | None = None, height: int = 400) -> Any:
    """What a notebook cell should display: the live viewer's iframe, else the static page inline.

    Args:
        viewer: a live :class:`Viewer` or ``None``.
        page: the static HTML to show when ``viewer`` is ``None`` (e.g. from :func:`nlo_lab.viz.static_html`).
        height: iframe height [px].
    """
    if viewer is not None and viewer.alive:
        return viewer.jupyter_cell(height=height)
    if page is None:
        raise NloLabError("no live viewer and no static page to show")
    from nlo_lab.viz.export import iframe_html

    return iframe_html(page, height=height)

"""JupyterLab in a real browser, for the browser tests (the ``lab_browser`` fixture of tests/conftest.py) and benchmarks/viewer.py.

:class:`Lab` starts JupyterLab (or Notebook 7, ``app="notebook"``) on 127.0.0.1 (a free port, a random token, its own
config, data and runtime folders) over a folder, and stops it. :class:`LabPage` is a
Playwright page in Debian's Chromium (``executable_path``: Playwright cannot download
its own browsers here) that opens a notebook, runs all its cells, moves sliders, and
records what the page sends and receives: every request's address and the bytes of
every WebSocket frame.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
# Software WebGL: with --enable-unsafe-swiftshader Chromium draws WebGL on the CPU; without a GPU it draws nothing.
CHROMIUM_ARGS = ["--no-sandbox", "--enable-unsafe-swiftshader", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]


def browser_missing() -> str | None:
    """Why the real-browser checks cannot run here, or None."""
    if CHROMIUM is None:
        return "Debian's chromium is not installed (apt-get install -y chromium)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "the playwright package is not installed (pip install playwright)"
    return None


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Lab:
    """JupyterLab over ``root`` on 127.0.0.1; ``env`` is added to the kernel's environment."""

    def __init__(self, root: Path, state: Path, env: dict[str, str] | None = None, timeout: float = 90.0,
                 app: str = "jupyterlab", settings: dict[str, dict] | None = None):
        self.root, self.state = Path(root), Path(state)
        self.app = app  # "jupyterlab", or "notebook" (Notebook 7: the same server, a one-notebook page)
        self.port, self.token = free_port(), secrets.token_hex(16)
        self.origin = f"http://127.0.0.1:{self.port}"
        self.log_path = self.state / "jupyterlab.log"
        for sub in ("config", "data", "runtime", "settings", "workspaces"):
            (self.state / sub).mkdir(parents=True, exist_ok=True)
        run_env = dict(os.environ)
        run_env.update(env or {})
        # Every cell in the page (no windowing), no news, no kernel dialog: settings of this lab only.
        # ``settings``: more, as {"@scope/extension/plugin": values}.
        for plugin, values in {
            "@jupyterlab/notebook-extension/tracker": {"windowingMode": "none", "autoStartDefaultKernel": True},
            "@jupyterlab/apputils-extension/notification": {"fetchNews": "false", "checkForUpdates": False},
            **(settings or {}),
        }.items():
            target = self.state / "settings" / f"{plugin}.jupyterlab-settings"
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(json.dumps(values), encoding="utf-8")
        run_env.update(
            JUPYTER_CONFIG_DIR=str(self.state / "config"),
            JUPYTER_RUNTIME_DIR=str(self.state / "runtime"),
            JUPYTERLAB_SETTINGS_DIR=str(self.state / "settings"),
            JUPYTERLAB_WORKSPACES_DIR=str(self.state / "workspaces"),
            PYDEVD_DISABLE_FILE_VALIDATION="1",
        )
        cmd = [
            sys.executable, "-m", app, "--no-browser", "--ServerApp.ip=127.0.0.1", f"--ServerApp.port={self.port}",
            "--ServerApp.port_retries=0", f"--IdentityProvider.token={self.token}", f"--ServerApp.root_dir={self.root}",
            "--LabApp.news_url=", "--LabApp.check_for_updates_class=jupyterlab.NeverCheckForUpdate",
        ] + (["--allow-root"] if hasattr(os, "geteuid") and os.geteuid() == 0 else [])
        self._log = open(self.log_path, "wb")
        self.proc = subprocess.Popen(cmd, env=run_env, stdin=subprocess.DEVNULL, stdout=self._log, stderr=subprocess.STDOUT,
                                     start_new_session=True)
        deadline = time.monotonic() + timeout
        while True:
            try:
                with urllib.request.urlopen(f"{self.origin}/api/status?token={self.token}", timeout=2) as resp:
                    if resp.status == 200:
                        break
            except OSError:
                pass
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.close()
                raise RuntimeError(f"JupyterLab did not start:\n{self.log()[-3000:]}")
            time.sleep(0.3)

    def api(self, method: str, path: str) -> object:
        """A call to the server's REST API (``api/...``): its JSON answer, or None."""
        req = urllib.request.Request(self.url(path), method=method)
        with urllib.request.urlopen(req, timeout=30) as resp:
            body = resp.read()
        return json.loads(body) if body else None

    def url(self, path: str, query: str = "") -> str:
        return f"{self.origin}/{path.lstrip('/')}?token={self.token}{'&' + query if query else ''}"

    def log(self) -> str:
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text(encoding="utf-8", errors="replace")

    def close(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGTERM)  # the server and its kernels (our own process group)
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=5)
        self._log.close()

    def __enter__(self) -> Lab:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class LabPage:
    """One Chromium page on ``lab``, recording requests and WebSocket traffic."""

    def __init__(self, browser, lab: Lab, width: int = 1280, height: int = 900):
        self.lab = lab
        self.page = browser.new_page(viewport={"width": width, "height": height})
        self.requests: list[str] = []
        self.sockets: list[str] = []
        self.received = 0  # WebSocket bytes the page received
        self.sent = 0
        self.console_errors: list[str] = []
        self.page.on("request", lambda r: self.requests.append(r.url))
        self.page.on("websocket", self._on_socket)
        self.page.on("console", lambda m: self.console_errors.append(m.text) if m.type == "error" else None)
        self.page.on("pageerror", lambda e: self.console_errors.append(f"page error: {e}"))

    def _on_socket(self, ws) -> None:
        self.sockets.append(ws.url)
        ws.on("framereceived", lambda payload: self._count("received", payload))
        ws.on("framesent", lambda payload: self._count("sent", payload))

    def _count(self, which: str, payload) -> None:
        n = len(payload.encode("utf-8")) if isinstance(payload, str) else len(payload)
        setattr(self, which, getattr(self, which) + n)

    def foreign_addresses(self) -> list[str]:
        """Requests and sockets that went anywhere but the Jupyter server's own origin (data:/blob: are local)."""
        ws_origin = self.lab.origin.replace("http://", "ws://")
        bad = [u for u in self.requests if not (u.startswith(self.lab.origin + "/") or u.startswith(("data:", "blob:")))]
        return bad + [u for u in self.sockets if not u.startswith(ws_origin + "/")]

    # ---------------------------------------------------------------- notebooks
    def open_notebook(self, name: str, timeout: float = 120.0) -> None:
        if self.lab.app == "notebook":  # Notebook 7: one notebook per page
            self.page.goto(self.lab.url(f"notebooks/{name}"))
        else:
            self.page.goto(self.lab.url(f"lab/tree/{name}", "reset"))  # reset: this notebook alone, no tabs restored
        self.page.locator(".jp-Notebook").first.wait_for(timeout=timeout * 1000)
        # JupyterLab may ask which kernel to start: the notebook's own (python3) is the default choice.
        accept = self.page.locator(".jp-Dialog .jp-mod-accept")
        try:
            accept.wait_for(timeout=8000)
            accept.click()
        except Exception:  # no dialog: the kernel started by itself
            pass
        self.wait_kernel_idle(timeout)

    def kernel_status(self) -> str:
        return self.page.evaluate(
            """() => { const el = document.querySelector('.jp-Notebook-ExecutionIndicator');
                       return el ? (el.getAttribute('data-status') || '') : ''; }""")

    def wait_kernel_idle(self, timeout: float = 120.0, settle: float = 0.5) -> None:
        deadline = time.monotonic() + timeout
        idle_since = None
        while time.monotonic() < deadline:
            if self.kernel_status() == "idle":
                idle_since = idle_since or time.monotonic()
                if time.monotonic() - idle_since >= settle:
                    return
            else:
                idle_since = None
            time.sleep(0.1)
        raise TimeoutError(f"the kernel is still {self.kernel_status()!r} after {timeout:.0f} s")

    def run_all(self, timeout: float = 600.0) -> None:
        """Run > Run All Cells, then wait until every code cell has run."""
        self.page.locator(".lm-MenuBar-itemLabel", has_text=re.compile(r"^Run$")).click()
        self.page.locator(".lm-Menu-itemLabel", has_text=re.compile(r"^Run All Cells$")).click()
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            prompts = self.cells().locator(".jp-InputPrompt").all_text_contents()
            if prompts and all(re.fullmatch(r"\[\d+\]:", p.strip()) for p in prompts):
                self.wait_kernel_idle(timeout)
                return
            if self.kernel_status() == "idle" and self.error_outputs():  # a cell failed: the rest will not run
                raise RuntimeError(f"Run All stopped on an error: {self.error_outputs()[0][-2000:]}")
            time.sleep(0.5)
        raise TimeoutError(f"Run All did not finish in {timeout:.0f} s: prompts {prompts}")

    def error_outputs(self) -> list[str]:
        """Every error or stderr text shown in the notebook, inside widgets too (interact, Output)."""
        return self.page.evaluate(
            """() => Array.from(document.querySelectorAll(
                   '[data-mime-type="application/vnd.jupyter.stderr"], .jp-OutputArea-output.jp-mod-error, .nlo-lab-panel-error'))
                   .map(el => el.textContent.slice(0, 2000))""")

    def view_stats(self) -> dict:
        return self.page.evaluate("() => JSON.parse(JSON.stringify(globalThis.__nloLabView || {}))")

    def view_messages(self) -> list[str]:
        """Texts shown over the 3-D views (errors, no kernel)."""
        return self.page.evaluate(
            """() => Array.from(document.querySelectorAll('.nlo-lab-view-message'))
                   .filter(el => el.style.display !== 'none').map(el => el.textContent)""")

    def wait_views(self, count: int, timeout: float = 60.0, messages: bool = False) -> None:
        """Wait until ``count`` 3-D views drew, none of them with a message over it (unless ``messages``)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if (self.page.locator(".jp-NotebookPanel:not(.lm-mod-hidden) .nlo-lab-view canvas").count() >= count
                    and (messages or not self.view_messages())):
                return
            time.sleep(0.2)
        raise TimeoutError(f"{self.page.locator('.nlo-lab-view canvas').count()} views drew, {count} expected; "
                           f"messages {self.view_messages()}; server log:\n{self.lab.log()[-3000:]}")

    def canvas(self, index: int):
        return self.page.locator(".jp-NotebookPanel:not(.lm-mod-hidden) .nlo-lab-view canvas").nth(index)

    def canvas_image(self, index: int, path: Path) -> np.ndarray:
        """``(H, W, 3)`` RGB in [0, 1] of the ``index``-th 3-D view, as on screen."""
        import matplotlib.image as mimage

        loc = self.canvas(index)
        loc.scroll_into_view_if_needed()
        self.page.wait_for_timeout(400)  # two animation frames at least
        loc.screenshot(path=str(path))
        return mimage.imread(str(path))[..., :3].astype(np.float64)

    def cells(self):
        """The code cells of the notebook on show."""
        return self.page.locator(".jp-NotebookPanel:not(.lm-mod-hidden) .jp-CodeCell")

    def cell_with(self, text: str) -> int:
        """Index of the first code cell whose source contains ``text``."""
        cells = self.cells()
        for i in range(cells.count()):
            if text in cells.nth(i).locator(".jp-InputArea").text_content():
                return i
        raise LookupError(f"no code cell contains {text!r}")

    def slider_handles(self, cell_index: int):
        """The slider handles (noUiSlider) in the output of the ``cell_index``-th code cell."""
        return self.cells().nth(cell_index).locator(".noUi-handle")

    def slider_handle(self, cell_index: int, label: str):
        """The handle of the slider described ``label`` (its ``description``) in the ``cell_index``-th code cell."""
        label_re = re.compile(rf"^\s*{re.escape(label)}\s*$")
        slider = self.cells().nth(cell_index).locator(".widget-slider", has=self.page.locator(".widget-label", has_text=label_re))
        return slider.locator(".noUi-handle").first

    def move_slider(self, handle, key: str = "ArrowRight", settle: float = 0.5, timeout: float = 60.0) -> dict:
        """Press ``key`` on a slider handle; wait until the kernel is idle and the page has received nothing for ``settle`` s.

        Returns:
            ``{"bytes": WebSocket bytes received, "messages": view updates applied,
            "seconds": until the first view update (None without one)}``.
        """
        before_msgs = self.view_stats().get("messages", 0)
        handle.scroll_into_view_if_needed()
        handle.focus()
        received = self.received
        start = time.monotonic()
        handle.press(key)
        first, last_bytes, quiet_since = None, self.received, time.monotonic()
        while time.monotonic() - start < timeout:
            time.sleep(0.03)
            now = time.monotonic()
            if first is None and self.view_stats().get("messages", 0) > before_msgs:
                first = now - start
            if self.received != last_bytes:
                last_bytes, quiet_since = self.received, now
            answered = self.received > received  # the kernel's status messages at least
            if answered and now - quiet_since >= settle and self.kernel_status() == "idle":
                break
        return {"bytes": self.received - received, "messages": self.view_stats().get("messages", 0) - before_msgs, "seconds": first}

def offline_view_shot(page: Path, png: Path, local=None, ready: str | None = None) -> dict[str, list[str]]:
    """Open ``page`` (a file) in Chromium with no network: an address other than ``file:``, ``data:`` or
    ``blob:`` is answered with the file ``local(url)`` returns, or refused. Once the page's first 3-D view
    has run its commands (and the JavaScript condition ``ready`` holds), its canvas goes into ``png``.

    Returns:
        ``{"served": [...], "refused": [...], "errors": [...]}``: the addresses answered and refused, the page's errors.
    """
    import mimetypes

    from playwright.sync_api import sync_playwright

    seen: dict[str, list[str]] = {"served": [], "refused": [], "errors": []}

    def answer(route):
        url = route.request.url
        if url.startswith(("file:", "data:", "blob:")):
            return route.continue_()
        found = local(url) if local is not None else None
        if found is None:
            seen["refused"].append(url)
            return route.abort()
        seen["served"].append(url)
        kind = mimetypes.guess_type(found.name)[0] or "application/octet-stream"
        route.fulfill(status=200, body=found.read_bytes(), headers={"Content-Type": kind, "Access-Control-Allow-Origin": "*"})

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            tab = browser.new_page(viewport={"width": 1000, "height": 800})
            tab.on("pageerror", lambda e: seen["errors"].append(str(e)))
            tab.route("**/*", answer)
            tab.goto(Path(page).resolve().as_uri())
            canvas = tab.locator(".nlo-lab-view canvas").first
            try:
                canvas.wait_for(timeout=90_000)
            except Exception:
                raise AssertionError(f"no 3-D view in {page}; {seen}") from None
            tab.wait_for_function("() => (globalThis.__nloLabView || {}).commands > 0", timeout=30_000)
            if ready:
                tab.wait_for_function(ready, timeout=30_000)
            canvas.scroll_into_view_if_needed()
            tab.wait_for_timeout(500)
            canvas.screenshot(path=str(png))
        finally:
            browser.close()
    return seen


def hue_mask(img: np.ndarray, colour: int, hue_tol: float = 0.03) -> np.ndarray:
    """``(H, W)`` pixels of ``img`` whose hue is that of ``colour`` (saturated, not dark): shading changes brightness, not hue."""
    import matplotlib.colors as mcolors

    hsv = mcolors.rgb_to_hsv(np.clip(img[..., :3], 0, 1))
    target = mcolors.rgb_to_hsv(np.array([(colour >> 16) & 255, (colour >> 8) & 255, colour & 255]) / 255.0)
    dh = np.abs(hsv[..., 0] - target[0])
    dh = np.minimum(dh, 1.0 - dh)
    return (dh < hue_tol) & (hsv[..., 1] > 0.45) & (hsv[..., 2] > 0.2)


def write_json(path: Path, data) -> None:
    path.write_text(json.dumps(data, indent=2), encoding="utf-8")

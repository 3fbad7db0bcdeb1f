"""The camera view's page in Chromium, without Jupyter: its code (camera_view.js) on a stand-in widget model.

Chromium's fake camera (``--use-fake-device-for-media-stream``: a moving test pattern at 30 fps) feeds the
page; the stand-in model answers each frame after a delay, like a kernel that takes that long. Checked: at most
one frame in flight, the camera frames that come meanwhile dropped, not queued (and not when the kernel is fast:
the control), the frames JPEG of the stated size; the messages for a page that is not a secure context, a
refused camera and no camera. The pages are served by Playwright's request routing: nothing listens on a port.
"""

from __future__ import annotations

from pathlib import Path

import pytest

pytestmark = pytest.mark.browser  # skipped, with the reason, where chromium or playwright is missing (conftest.py)

JS = Path(__file__).resolve().parents[2] / "nlo_lab" / "live" / "camera_view.js"
PAGE = """<!doctype html><html><body><script type="module">
import widget from "/camera_view.js";
class Model {
  constructor(state) { this.state = state; this.handlers = {}; this.sent = []; }
  get(k) { return this.state[k]; }
  set(k, v) { this.state[k] = v; }
  save_changes() {}
  on(event, cb) { (this.handlers[event] ??= []).push(cb); }
  off(event, cb) { this.handlers[event] = (this.handlers[event] || []).filter((f) => f !== cb); }
  emit(event, ...args) { for (const cb of this.handlers[event] || []) cb(...args); }
  send(content, callbacks, buffers) {
    const bytes = buffers && buffers[0] ? new Uint8Array(buffers[0]) : null;
    this.sent.push({ content, at: performance.now(), size: bytes ? bytes.length : 0, jpeg: !!bytes && bytes[0] === 0xff && bytes[1] === 0xd8 });
    if (bytes && this.sent.length === 2) {  // the size of one frame as sent
      createImageBitmap(new Blob([bytes], { type: "image/jpeg" })).then((img) => { window.frameSize = [img.width, img.height]; });
    }
    if (content.type === "frame") {
      setTimeout(() => this.emit("msg:custom", { type: "done", seq: content.seq, found: true, points: [[0.5, 0.5]] }), window.DELAY);
    }
  }
}
window.model = new Model({ height: 240, mirror: true, frame_size: 320, jpeg_quality: 0.7, frames_processed: 0, fps: 0,
  latency_ms: 0, found: false, recording: false, error: "", camera: "off", camera_message: "" });
const el = document.createElement("div");
document.body.append(el);
widget.render({ model: window.model, el });
window.ready = true;
</script></body></html>"""
FAKE_CAMERA = ["--use-fake-device-for-media-stream"]
ACCEPT = ["--use-fake-ui-for-media-stream"]


def _open(lab_browser, origin: str, flags: list[str], delay: float, grant: bool = True):
    """A Chromium page at ``origin`` running the view on the stand-in model; returns (playwright, browser, page)."""
    from playwright.sync_api import sync_playwright

    p = sync_playwright().start()
    browser = p.chromium.launch(executable_path=lab_browser.CHROMIUM, args=lab_browser.CHROMIUM_ARGS + flags)
    context = browser.new_context()
    if grant:
        context.grant_permissions(["camera"], origin=origin)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.requests = []
    page.on("request", lambda r: page.requests.append(r.url))

    def serve(route):
        url = route.request.url
        if url.endswith("/camera_view.js"):
            return route.fulfill(status=200, body=JS.read_text(), headers={"Content-Type": "text/javascript"})
        if url.rstrip("/") == origin:
            return route.fulfill(status=200, body=PAGE, headers={"Content-Type": "text/html"})
        return route.abort()  # nothing else may be asked for

    page.route("**/*", serve)
    page.goto(origin + "/")
    page.wait_for_function("() => window.ready === true")
    page.evaluate(f"() => {{ window.DELAY = {delay * 1000}; }}")
    page.errors = errors
    return p, browser, page


def _stream(page, seconds: float) -> dict:
    page.click("button.nlo-lab-camera-button")
    page.wait_for_function("() => window.model.get('camera') !== 'starting' && window.model.get('camera') !== 'off'", timeout=20_000)
    page.wait_for_timeout(seconds * 1000)
    page.click("button.nlo-lab-camera-button")  # Stop
    page.wait_for_timeout(1000)  # the last answer comes back
    return page.evaluate("""() => ({ stats: JSON.parse(JSON.stringify(globalThis.__nloLabLive)), camera: window.model.get('camera'),
        sent: window.model.sent.map((m) => ({ type: m.content.type, seq: m.content.seq, t: m.content.t, size: m.size, jpeg: m.jpeg })),
        frameSize: window.frameSize, button: document.querySelector('button.nlo-lab-camera-button').textContent })""")


@pytest.mark.parametrize("delay", [0.3, 0.0])
def test_one_frame_in_flight_a_slow_kernel_drops_frames(lab_browser, delay):
    p, browser, page = _open(lab_browser, "http://localhost:8888", FAKE_CAMERA + ACCEPT, delay)
    try:
        seconds = 4.0
        out = _stream(page, seconds)
        frames = [m for m in out["sent"] if m["type"] == "frame"]
        stats = out["stats"]
        assert out["camera"] == "off" and out["button"] == "Start" and page.errors == []
        assert {u.split("?")[0] for u in page.requests} <= {"http://localhost:8888/", "http://localhost:8888/camera_view.js"}, page.requests
        assert stats["maxInFlight"] == 1 and stats["inFlight"] == 0 and stats["answered"] == stats["sent"] == len(frames)
        assert all(m["jpeg"] and m["size"] > 500 for m in frames)
        assert max(out["frameSize"]) == 320  # the stated size: the camera's 640x480 shrunk to 320 on its longer side
        assert [m["seq"] for m in frames] == list(range(1, len(frames) + 1))
        assert all(b["t"] > a["t"] for a, b in zip(frames, frames[1:], strict=False))
        if delay:  # a kernel at 0.3 s a frame: about 13 frames in 4 s, the camera's other ~100 dropped
            assert len(frames) <= seconds / delay + 2, len(frames)
            assert stats["dropped"] > 3 * len(frames) and stats["captured"] >= stats["sent"] + stats["dropped"] - 1, stats
        else:  # the control: a kernel that answers at once keeps up with the camera, nearly nothing dropped
            assert len(frames) > 60 and stats["dropped"] < 0.3 * stats["captured"], stats
    finally:
        browser.close()
        p.stop()


def _message_after_start(lab_browser, origin, flags, grant=True) -> tuple[str, str]:
    p, browser, page = _open(lab_browser, origin, flags, 0.0, grant=grant)
    try:
        page.click("button.nlo-lab-camera-button")
        page.wait_for_function("() => window.model.get('camera') === 'failed'", timeout=20_000)
        shown = page.locator(".nlo-lab-camera-message").text_content()
        assert page.errors == [] and page.evaluate("() => window.model.sent.length") == 0
        return shown, page.evaluate("() => window.model.get('camera_message')")
    finally:
        browser.close()
        p.stop()


def test_a_page_that_is_not_a_secure_context_says_so(lab_browser):
    shown, message = _message_after_start(lab_browser, "http://nlo-lab.test", FAKE_CAMERA + ACCEPT, grant=False)
    assert "secure page" in shown and "http://nlo-lab.test" in shown and "https" in shown and "JupyterHub" in shown
    assert message == shown


def test_a_refused_camera_says_so(lab_browser):
    shown, _ = _message_after_start(lab_browser, "http://localhost:8888", FAKE_CAMERA + ["--deny-permission-prompts"], grant=False)
    assert "refused" in shown and "press Start again" in shown


def test_no_camera_says_so(lab_browser):
    shown, _ = _message_after_start(lab_browser, "http://localhost:8888", ACCEPT)
    assert "No camera was found" in shown

"""Notebook 11 in JupyterLab in a real browser, with a fake camera that plays the sample video.

Chromium's ``--use-file-for-fake-video-capture`` plays a ``.y4m`` file as the camera; the test makes it from the
sample video (``assets/recordings/signer_webcam_58f.mp4``, with OpenCV). JupyterLab runs the whole notebook in
test mode, then the test presses the camera cell's Start: through the widget's traits (as the page has them,
synced from the kernel) it checks that frames flowed and were processed, a person was found, the robot's view
moved (its commands arrived and the picture changed), at most one frame was ever in flight, and that nothing went
wrong anywhere: no error output (stderr included: MediaPipe's native log lines are silenced), no console error,
no request to another origin, no traceback in the server's log.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.browser  # skipped, with the reason, where chromium or playwright is missing (conftest.py)
pytest.importorskip("mediapipe", reason="the video extra (mediapipe) is not installed")

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOK = "11_live.ipynb"
VIDEO = ROOT / "assets" / "recordings" / "signer_webcam_58f.mp4"


def write_y4m(path: Path, max_side: int = 480) -> Path:
    """The sample video as a raw YUV 4:2:0 ``.y4m`` file (what Chromium's fake camera plays, in a loop)."""
    import cv2

    from nlo_lab.human import read_video_frames

    frames = read_video_frames(VIDEO, max_side=max_side)
    h, w = frames.shape[1:3]
    with open(path, "wb") as f:
        f.write(f"YUV4MPEG2 W{w} H{h} F30:1 Ip A1:1 C420jpeg\n".encode())
        for rgb in frames:
            f.write(b"FRAME\n" + cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2YUV_I420).tobytes())
    return path


def _changed(a: np.ndarray, b: np.ndarray) -> float:
    return float((np.abs(a - b).max(axis=-1) > 0.1).mean())


def _stats(page) -> dict:
    return page.page.evaluate("() => JSON.parse(JSON.stringify(globalThis.__nloLabLive || {}))")


def test_notebook_11_with_a_fake_camera_in_jupyterlab(tmp_path, lab_browser):
    from playwright.sync_api import sync_playwright

    camera = write_y4m(tmp_path / "signer.y4m")
    (tmp_path / "notebooks").mkdir()
    shutil.copy(ROOT / "notebooks" / NOTEBOOK, tmp_path / "notebooks" / NOTEBOOK)  # the lab writes to its copy only
    flags = ["--use-fake-ui-for-media-stream", "--use-fake-device-for-media-stream", f"--use-file-for-fake-video-capture={camera}"]
    env = {"NLO_LAB_TEST_MODE": "1", "NLO_LAB_WORK": str(tmp_path / "work")}
    with lab_browser.Lab(tmp_path / "notebooks", tmp_path / "state", env=env) as lab, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=lab_browser.CHROMIUM, args=lab_browser.CHROMIUM_ARGS + flags)
        try:
            page = lab_browser.LabPage(browser, lab, width=1280, height=900)  # --use-fake-ui-for-media-stream: the camera allowed
            page.open_notebook(NOTEBOOK)
            page.run_all(timeout=600)
            page.wait_views(1)
            assert page.error_outputs() == [], page.error_outputs()
            before = _stats(page)
            played = before["traits"].get("frames_processed", 0)
            assert played > 0, before  # the sample video went through the same path in the notebook (no camera yet)
            cell = page.cell_with("CameraView(")
            button = page.cells().nth(cell).locator("button.nlo-lab-camera-button")
            assert button.text_content() == "Start"
            view_messages = page.view_stats().get("messages", 0)
            picture = page.canvas_image(0, tmp_path / "before.png")
            button.scroll_into_view_if_needed()
            button.click()
            page.page.wait_for_function(
                f"() => ((globalThis.__nloLabLive || {{}}).traits || {{}}).frames_processed >= {played + 10}", timeout=240_000)
            after = page.canvas_image(0, tmp_path / "after.png")
            stats = _stats(page)
            assert stats["traits"]["camera"] == "on" and button.text_content() == "Stop", stats["traits"]
            button.click()  # Stop
            page.page.wait_for_function("() => (globalThis.__nloLabLive || {}).inFlight === 0", timeout=60_000)
            page.wait_kernel_idle()
            stats = _stats(page)
            traits = stats["traits"]
            print("page:", {k: stats[k] for k in ("captured", "sent", "answered", "dropped", "found", "maxInFlight")}, "traits:", traits)
            # frames flowed: the page sent them, the kernel received and processed each (one at a time)
            assert stats["sent"] >= 10 and stats["answered"] == stats["sent"] and stats["maxInFlight"] == 1
            assert traits["frames_received"] - played == stats["sent"] == traits["frames_processed"] - played, (stats, traits)
            assert traits["frames_rejected"] == 0 and traits["error"] == "" and traits["camera"] == "off"
            assert traits["fps"] > 0 and traits["latency_ms"] > 0
            assert stats["found"] >= 5  # the signer is seen
            assert stats["captured"] > stats["sent"]  # a 30 fps camera and a kernel slower than that: frames dropped
            # the robot moved: view updates arrived and the picture changed
            assert page.view_stats().get("messages", 0) - view_messages >= 5
            assert _changed(picture, after) > 0.002, "the robot's view did not change"
            assert page.error_outputs() == [] and page.console_errors == [] and page.view_messages() == []
            assert page.foreign_addresses() == [], page.foreign_addresses()
        finally:
            browser.close()
        log = lab.log()
    assert "Traceback" not in log, f"the kernel or the server logged an error:\n{log[-4000:]}"

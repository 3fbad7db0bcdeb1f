"""Notebook 09 in JupyterLab in a real browser: the video frame and the 3-D view move together.

Skips with the reason when Debian's chromium or playwright is missing (tests/conftest.py, tools/lab_browser.py).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.browser  # skipped, with the reason, where chromium or playwright is missing (conftest.py)
pytest.importorskip("mediapipe", reason="the video extra (mediapipe) is not installed")

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOK = "09_retarget_your_own_video.ipynb"
EXPECTED_WARNING = "the left hand is never seen"  # the sample's left hand is out of the picture: said, not an error


def _changed(a: np.ndarray, b: np.ndarray) -> float:
    """Fraction of pixels that differ visibly between two pictures of the same size."""
    return float((np.abs(a - b).max(axis=-1) > 0.1).mean())


def _image(page, cell: int, path: Path) -> np.ndarray:
    import matplotlib.image as mimage

    img = page.cells().nth(cell).locator(".jp-Cell-outputArea img").first
    img.scroll_into_view_if_needed()
    page.page.wait_for_timeout(300)
    img.screenshot(path=str(path))
    return mimage.imread(str(path))[..., :3].astype(np.float64)


def test_notebook_09_video_and_view_in_sync(tmp_path, lab_browser):
    from playwright.sync_api import sync_playwright

    (tmp_path / "notebooks").mkdir()
    shutil.copy(ROOT / "notebooks" / NOTEBOOK, tmp_path / "notebooks" / NOTEBOOK)  # the lab writes to its copy only
    with lab_browser.Lab(tmp_path / "notebooks", tmp_path / "state", env={"NLO_LAB_TEST_MODE": "1"}) as lab, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=lab_browser.CHROMIUM, args=lab_browser.CHROMIUM_ARGS)
        try:
            page = lab_browser.LabPage(browser, lab, width=1280, height=900)
            page.open_notebook(NOTEBOOK)
            page.run_all()
            page.wait_views(1)
            errors = [e for e in page.error_outputs() if EXPECTED_WARNING not in e]
            assert errors == [], errors
            assert page.view_messages() == [] and page.console_errors == [] and page.foreign_addresses() == []
            cell = page.cell_with("VideoView(")
            video_before = _image(page, cell, tmp_path / "video-before.png")
            view_before = page.canvas_image(0, tmp_path / "view-before.png")
            assert video_before.std() > 0.05, "the video frame is blank"
            slider = page.cells().nth(cell).locator(".noUi-handle").first
            move = page.move_slider(slider, key="End")  # the last frame
            video_after = _image(page, cell, tmp_path / "video-after.png")
            view_after = page.canvas_image(0, tmp_path / "view-after.png")
            assert move["messages"] == 1, move  # one view update per frame
            assert _changed(video_before, video_after) > 0.01, "the video frame did not change"
            assert _changed(view_before, view_after) > 0.002, "the 3-D view did not change"
            assert [e for e in page.error_outputs() if EXPECTED_WARNING not in e] == []
        finally:
            browser.close()
        log = lab.log()
    assert "Traceback" not in log, f"the kernel or the server logged an error:\n{log[-4000:]}"

"""A real browser draws the exported viewer: headless Chromium screenshots of export_html pages.

Needs Debian's ``chromium`` (``apt-get install -y chromium``); skipped with that
reason when it is not installed. ``--enable-unsafe-swiftshader`` gives WebGL in
software; ``--use-gl=swiftshader`` would give a blank page.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from nlo_lab.robots import load_robot
from nlo_lab.viz import GROUP_COLOURS, export_html, recording_visualizer, style_viewer
from nlo_lab.viz.export import scene_html

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="headless Chromium is not installed (apt-get install -y chromium)")


def _screenshot(html: Path, out: Path, profile: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [
            CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
            "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run",
            f"--user-data-dir={profile}", "--window-size=800,600", "--virtual-time-budget=5000",
            f"--screenshot={out}", html.resolve().as_uri(),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )


def _hue_fraction(png: Path, colour: int, hue_tol: float = 0.03) -> float:
    """Fraction of pixels whose hue is that of ``colour`` (saturated, not dark): shading changes brightness, not hue."""
    import matplotlib.colors as mcolors
    import matplotlib.image as mimage

    img = mimage.imread(str(png))[..., :3].astype(np.float64)  # (H, W, 3) in [0, 1]
    hsv = mcolors.rgb_to_hsv(img)
    target = mcolors.rgb_to_hsv(np.array([(colour >> 16) & 255, (colour >> 8) & 255, colour & 255]) / 255.0)
    dh = np.abs(hsv[..., 0] - target[0])
    dh = np.minimum(dh, 1.0 - dh)
    match = (dh < hue_tol) & (hsv[..., 1] > 0.45) & (hsv[..., 2] > 0.2)
    return float(match.mean())


def test_chromium_draws_the_exported_robot(tmp_path):
    robot = load_robot("yumi")
    lo, hi = robot.lower_limits.double().numpy(), robot.upper_limits.double().numpy()
    q = lo + (hi - lo) * (0.5 + 0.2 * np.sin(np.linspace(0, np.pi, 20)))[:, None]  # (20, n) inside the limits
    page = export_html(tmp_path / "robot.html", robot, q, fps=20)
    # Negative control: the same viewer and background with no robot; the colour test must fail on it.
    vis = recording_visualizer()
    style_viewer(vis)
    empty = tmp_path / "empty.html"
    empty.write_text(scene_html(vis.window.tree), encoding="utf-8")

    jobs = [(_screenshot(p, tmp_path / f"{p.stem}.png", tmp_path / f"profile-{p.stem}"), p.stem) for p in (page, empty)]
    for proc, stem in jobs:
        _, err = proc.communicate(timeout=120)
        assert (tmp_path / f"{stem}.png").is_file(), f"chromium made no screenshot of {stem}.html:\n{err[-2000:]}"

    shot, blank = tmp_path / "robot.png", tmp_path / "empty.png"
    import matplotlib.image as mimage

    img = mimage.imread(str(shot))[..., :3]
    assert img.shape[:2] == (600, 800)
    assert img.std() > 0.02, "the page is blank"
    arm, hand, torso = (_hue_fraction(shot, GROUP_COLOURS[k]) for k in ("arm", "hand", "torso"))
    assert arm > 0.005, f"arm colour covers only {arm:.4%} of the screenshot"
    assert hand > 0.0005, f"hand colour covers only {hand:.4%} of the screenshot"
    assert torso > 0.002, f"torso colour covers only {torso:.4%} of the screenshot"
    for key, fraction in (("arm", 0.005), ("hand", 0.0005), ("torso", 0.002)):  # the thresholds above
        assert _hue_fraction(blank, GROUP_COLOURS[key]) < fraction / 2, f"{key} colour found on the page without a robot"

"""The live 3-D view in a real browser: bytes per slider move, Play's frame rate, re-optimisation time.

JupyterLab on a free port of 127.0.0.1, Debian's chromium driven by Playwright (software WebGL),
one notebook made here: a ``RetargetPanel`` on YuMi with both hands over a 100-frame clip of
the embedded corpus (full budgets, not test mode) and a ``JointPanel`` on YuMi. Then:

* RetargetPanel, a weight slider (ee) moved five steps (PageUp/PageDown) ``--moves`` times: WebSocket bytes the page
  received per move (everything: the scene's transforms, the plot, the status, the kernel's
  own status messages), the time until the view applied the update, and the kernel's
  re-optimisation time of the frame (the panel's status line, ``last_seconds``);
* RetargetPanel, the frame slider moved one step: bytes per move;
* JointPanel, a joint slider moved one step: bytes per move;
* Play on the 100-frame clip: it plays as a meshcat animation in the page (keys on the clip's
  time base, played once); frames the view drew per second while the animation plays (from 0.3 s after
  it arrived to 0.5 s before its end, at most 4 s), and the updates the kernel sent meanwhile; for the
  live view's light tessellation (``SceneWidget(detail="light")``, the default), meshcat's full one
  (``"full"``, a second panel) and the light one multisampled (``antialias=True``, a third panel; the
  default turns multisampling off on a software renderer, as here), in turn ``--rounds`` times each;
* the same scene in a bare meshcat page (meshcat's own page, as ``export_html`` writes it) in the same
  browser, canvas of the same size, light and full (multisampled, as meshcat's page is) and light without
  multisampling, ``--rounds`` times each: frames drawn per second, the browser's own limit for this scene
  (software WebGL here).

The load average is printed beside the frame rates: on a shared machine they follow it.

Targets (issue 13): <= 50 kB per RetargetPanel move, >= 15 frames/s (the default view: light), <= 50 ms median re-optimisation.
Before (the static page re-sent per update): 0.96 MB per JointPanel move, 1.17 MB per RetargetPanel
move, about 2 frames/s.

Run: ``.venv/bin/python benchmarks/viewer.py [--moves 15] [--rounds 2] [--clip NAME]`` (about 3 minutes).
Writes the section ``viewer`` of ``docs/RESULTS.md`` (``--no-write``: print only).
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
sys.path.insert(0, str(ROOT / "benchmarks"))
import results_doc  # noqa: E402
from lab_browser import CHROMIUM, CHROMIUM_ARGS, Lab, LabPage, browser_missing  # noqa: E402


def notebook(clip: str, frames: int) -> dict:
    import nbformat

    cells = [
        "from nlo_lab.lab import setup\nsetup()",
        f"from nlo_lab.corpus import corpus_clip\ndemo = corpus_clip({clip!r}).slice(0, {frames})\nprint(len(demo), 'frames')",
        "from nlo_lab.lab import RetargetPanel\npanel = RetargetPanel(demo, 'yumi')\npanel",
        "from nlo_lab.robot import load_robot\nfrom nlo_lab.lab import JointPanel\njoints = JointPanel(load_robot('yumi'))\njoints",
        "from nlo_lab.viz import SceneWidget\nSceneWidget.default_detail = 'full'  # meshcat's own tessellation\n"
        "full = RetargetPanel(demo, 'yumi')\nfull",
        "SceneWidget.default_detail = 'light'\nSceneWidget.default_antialias = True  # multisampled even here\n"
        "smooth = RetargetPanel(demo, 'yumi')\nsmooth",
    ]
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(c) for c in cells])
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3 (ipykernel)", "language": "python"}
    return nb


def status_ms(page: LabPage, cell: int) -> float | None:
    text = page.cells().nth(cell).text_content()
    found = re.findall(r"in (\d+) ms", text)
    return float(found[-1]) if found else None


BARE_DRAWS = """async () => {
  let draws = 0;
  const render = viewer.render.bind(viewer);
  viewer.render = () => { draws += 1; render(); };
  for (const action of viewer.animator.actions) { action.repetitions = Infinity; action.reset(); }
  viewer.animator.play();
  await new Promise((done) => setTimeout(done, 300));
  const d0 = draws, t0 = performance.now();
  await new Promise((done) => setTimeout(done, 3000));
  return (draws - d0) / ((performance.now() - t0) / 1000);
}"""


# meshcat's page builds a multisampled renderer; this swaps in one without (soft shadows kept, as the widget does)
BARE_SINGLE_SAMPLE = """() => {
  const old = viewer.renderer;
  const renderer = new MeshCat.THREE.WebGLRenderer({ antialias: false, alpha: true });
  renderer.shadowMap.enabled = true;
  renderer.shadowMap.type = old.shadowMap.type;
  renderer.setPixelRatio(window.devicePixelRatio);
  old.domElement.replaceWith(renderer.domElement);
  viewer.renderer = renderer;
  old.dispose();
  old.forceContextLoss();
  viewer.set_3d_pane_size();
  viewer.set_dirty();
}"""


def bare_page_fps(browser, tmp: Path, clip: str, frames: int, size: list[int], detail: str, antialias: bool = True) -> float:
    """Frames/s of the same scene (robot, hands, human, lights) in a bare meshcat page outside Jupyter, same browser."""
    import numpy as np

    from nlo_lab.corpus import corpus_clip
    from nlo_lab.robot import load_robot
    from nlo_lab.viz import RetargetScene, recording_visualizer
    from nlo_lab.viz.export import scene_html

    robot = load_robot("yumi")
    lo, hi = np.asarray(robot.lower_limits, dtype=float), np.asarray(robot.upper_limits, dtype=float)
    angles = np.linspace(0.3 * lo, 0.3 * hi, frames)  # any motion: the cost of a draw does not depend on the pose
    vis = recording_visualizer()
    vis.window.detail = detail  # what export_html draws ("full"), or the live view's "light"
    RetargetScene(vis, robot, angles, demo=corpus_clip(clip).slice(0, frames)).animate(play=True)
    path = tmp / f"bare-{detail}.html"
    path.write_text(scene_html(vis.window.tree), encoding="utf-8")
    page = browser.new_page(viewport={"width": size[0], "height": size[1]})
    page.goto(path.as_uri())
    page.wait_for_function("() => typeof viewer !== 'undefined' && viewer.animator.actions.length > 0", timeout=60000)
    if not antialias:
        page.evaluate(BARE_SINGLE_SAMPLE)
    fps = page.evaluate(BARE_DRAWS)
    page.close()
    return fps


def play_fps(page: LabPage, cell: int, duration: float) -> tuple[float, float]:
    """Press Play of the panel in ``cell`` from frame 0: (frames the view drew per second while the page's animation
    played, kernel updates received per second meanwhile)."""
    frame_slider = page.slider_handle(cell, "frame")
    frame_slider.focus()
    frame_slider.press("Home")
    page.wait_kernel_idle(settle=0.5)
    play = page.cells().nth(cell).locator(".widget-play button").first
    play.scroll_into_view_if_needed()
    before = len(page.view_stats()["arrivals"])
    play.click()
    deadline = time.monotonic() + 60
    while len(page.view_stats()["arrivals"]) == before and time.monotonic() < deadline:
        time.sleep(0.05)
    arrived = page.view_stats()["arrivals"][-1]
    # The recorded duration: the retimed animation lasts at least this long, so the window lies inside it.
    t0, t1 = arrived + 300, arrived + 1000 * min(4.0, duration - 0.5)
    page.page.wait_for_timeout(max(0, t1 - page.page.evaluate("() => performance.now()")) + 200)
    stats = page.view_stats()
    frames = [t for t in stats["draws"] if t0 <= t <= t1]  # the animation redraws every frame it advances
    arrivals = [t for t in stats["arrivals"] if t0 <= t <= t1]
    deadline = time.monotonic() + 120  # let Play reach the last frame (it then stops) before the next measurement
    while frame_slider.get_attribute("aria-valuenow") != frame_slider.get_attribute("aria-valuemax") and time.monotonic() < deadline:
        time.sleep(0.2)
    page.wait_kernel_idle(settle=1.0)
    return len(frames) / ((t1 - t0) / 1000), len(arrivals) / ((t1 - t0) / 1000)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--moves", type=int, default=15, help="slider moves per measurement")
    parser.add_argument("--clip", default="hospital_02", help="corpus clip (its first --frames frames)")
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=2, help="Play measurements per detail (alternating light, full)")
    parser.add_argument("--no-write", action="store_true", help="print only; leave the results file alone")
    args = parser.parse_args(argv)
    missing = browser_missing()
    if missing:
        print(f"cannot run: {missing}", file=sys.stderr)
        return 2
    import nbformat
    from playwright.sync_api import sync_playwright

    from nlo_lab.corpus import corpus_clip

    duration = args.frames / corpus_clip(args.clip).fps  # the page's animation plays the clip once

    with tempfile.TemporaryDirectory(prefix="nlo-lab-viewer-bench-") as tmp:
        tmp = Path(tmp)
        (tmp / "nb").mkdir()
        nbformat.write(notebook(args.clip, args.frames), tmp / "nb" / "bench.ipynb")
        with Lab(tmp / "nb", tmp / "state") as lab, sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
            page = LabPage(browser, lab, width=1280, height=900)
            page.open_notebook("bench.ipynb")
            page.run_all()
            page.wait_views(4)
            print("notebook ran; moving sliders", file=sys.stderr, flush=True)
            panel_cell, joint_cell = 2, 3
            handles = page.slider_handles(panel_cell)
            weight, frame_slider = handles.nth(0), page.slider_handle(panel_cell, "frame")
            results: dict[str, list[float]] = {k: [] for k in ("weight_bytes", "weight_seconds", "reopt_ms", "frame_bytes", "joint_bytes")}
            for i in range(args.moves):
                # PageUp/PageDown: five steps of the log slider (one step often leaves the optimum where it was: nothing to send)
                m = page.move_slider(weight, key="PageUp" if i % 2 == 0 else "PageDown", settle=0.3)
                results["weight_bytes"].append(m["bytes"])
                if m["seconds"] is not None:
                    results["weight_seconds"].append(m["seconds"])
                ms = status_ms(page, panel_cell)
                if ms is not None:
                    results["reopt_ms"].append(ms)
            for _ in range(args.moves):
                results["frame_bytes"].append(page.move_slider(frame_slider, key="ArrowRight", settle=0.3)["bytes"])
            joint = page.slider_handles(joint_cell).nth(1)
            for i in range(args.moves):
                results["joint_bytes"].append(page.move_slider(joint, key="ArrowRight" if i % 2 == 0 else "ArrowLeft", settle=0.3)["bytes"])
            print("playing", file=sys.stderr, flush=True)
            # Play from frame 0. The page animates the clip once, on its time base (meshcat's clock),
            # redrawing every animation frame it shows: count the draws between the animation's arrival
            # and its end (not after it, when nothing moves and nothing is drawn).
            views = {"light": panel_cell, "full": 4, "light, multisampled": 5}
            plays: dict[str, list[tuple[float, float, float]]] = {detail: [] for detail in views}
            for _ in range(args.rounds):
                for detail, cell in views.items():
                    fps, updates = play_fps(page, cell, duration)
                    plays[detail].append((fps, updates, os.getloadavg()[0]))
            render_ms = statistics.median(page.view_stats()["renderMs"][-200:])
            size = page.page.evaluate("() => { const c = document.querySelector('.nlo-lab-view canvas'); return [c.width, c.height]; }")
            canvas = page.page.locator(".nlo-lab-view canvas")
            renderer = canvas.first.get_attribute("data-renderer")
            antialias = [canvas.nth(i).get_attribute("data-antialias") for i in (0, 2, 3)]
            bare: dict[str, list[tuple[float, float]]] = {"light": [], "full": [], "light, not multisampled": []}
            for _ in range(args.rounds):
                for name, detail, smooth in (("light", "light", True), ("full", "full", True),
                                             ("light, not multisampled", "light", False)):
                    fps = bare_page_fps(browser, tmp, args.clip, args.frames, size, detail, smooth)
                    bare[name].append((fps, os.getloadavg()[0]))
            browser.close()

    med = statistics.median
    printed: list[str] = []

    def say(line: str) -> None:  # printed, and kept for the results file
        printed.append(line)
        print(line)

    say(f"live 3-D view in JupyterLab + chromium, YuMi with hands, {args.frames}-frame clip {args.clip!r}, {args.moves} moves each")
    say(f"WebGL renderer: {renderer}; multisampled (light, full, light multisampled): {', '.join(antialias)}")
    say(f"{'measure':52s} {'median':>10s} {'max':>10s}  target")
    rows = [
        ("RetargetPanel weight move, bytes received [kB]", [b / 1000 for b in results["weight_bytes"]], "<= 50"),
        ("RetargetPanel frame move, bytes received [kB]", [b / 1000 for b in results["frame_bytes"]], "<= 50"),
        ("JointPanel joint move, bytes received [kB]", [b / 1000 for b in results["joint_bytes"]], ""),
        ("RetargetPanel weight move, until the view updated [ms]", [s * 1000 for s in results["weight_seconds"]], ""),
        ("re-optimisation of the frame in the kernel [ms]", results["reopt_ms"], "<= 50"),
    ]
    for name, values, target in rows:
        if values:
            say(f"{name:52s} {med(values):10.1f} {max(values):10.1f}  {target}")
    for detail in plays:
        fps = [f for f, _, _ in plays[detail]]
        loads = ", ".join(f"{load:.1f}" for _, _, load in plays[detail])
        say(f"{'Play, frames drawn per second, ' + detail:52s} {med(fps):10.1f} {max(fps):10.1f}  "
              f"{'>= 15' if detail == 'light' else '':5s}  (runs {', '.join(f'{f:.1f}' for f in fps)}; load average {loads})")
    ratio = med([f for f, _, _ in plays["light"]]) / max(med([f for f, _, _ in plays["full"]]), 1e-9)
    say(f"{'Play, light over full':52s} {ratio:10.2f}")
    ratio = med([f for f, _, _ in plays["light"]]) / max(med([f for f, _, _ in plays["light, multisampled"]]), 1e-9)
    say(f"{'Play, light over light multisampled':52s} {ratio:10.2f}")
    for name, runs in bare.items():
        fps = [f for f, _ in runs]
        say(f"{'same scene, bare meshcat page, ' + name:52s} {med(fps):10.1f} {max(fps):10.1f}         "
              f"(runs {', '.join(f'{f:.1f}' for f in fps)}; load average {', '.join(f'{lo:.1f}' for _, lo in runs)}; "
              f"canvas {size[0]}x{size[1]})")
    ratio = med([f for f, _ in bare["light, not multisampled"]]) / max(med([f for f, _ in bare["light"]]), 1e-9)
    say(f"{'bare page, light: not multisampled over multisampled':52s} {ratio:10.2f}")
    updates = [u for detail in plays for _, u, _ in plays[detail]]
    say(f"{'Play on the clip, kernel updates received per second':52s} {max(updates):10.1f}  (max over the runs)")
    say(f"{'one draw of the view in the browser [ms]':52s} {render_ms:10.1f}")
    if not args.no_write:
        body = "\n".join([
            "## Live 3-D view in a real browser", "", results_doc.stamp(), "",
            "JupyterLab and Debian's headless chromium (Playwright), software WebGL: what a learner without a GPU gets. Targets:"
            " <= 50 kB received per RetargetPanel move, >= 15 frames/s for Play of the default (light) view, <= 50 ms median"
            " re-optimisation of the frame in the kernel. Frame rates follow the machine's load (printed beside each); the bare"
            " meshcat page is the browser's own limit for the same scene and canvas. Multisampling is off by default on a"
            " software renderer (the third panel plays the light view multisampled, as before that choice).",
            "", "```", *printed, "```", "",
        ])
        print(f"wrote section viewer of {results_doc.update_section('viewer', body)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""A real browser: the notebooks' live 3-D views in JupyterLab, and the exported viewer page.

Needs Debian's ``chromium`` (``apt-get install -y chromium``; ``make test`` installs it where it
can) and Playwright's Python package, which drives that browser (``executable_path``: Playwright
cannot download its own browsers here). Skipped, with that reason, only where chromium is not
installed. ``--enable-unsafe-swiftshader`` gives WebGL in software.

* JupyterLab on a free port of 127.0.0.1 runs notebooks 01 and 05 (Run All, test mode), then
  moves a slider of each panel: no error output anywhere (widget callbacks included: their
  tracebacks reach the server log, the panels show them), the 3-D canvases show the robots
  (colour checks), a move changes the picture, the page talks to the Jupyter server's origin
  only, and the bytes received per move stay under the bound. About a minute and a half on two cores.
* The exported viewer page (``export_html``): four screenshots, YuMi alone (all group colours,
  framing), NAO beside its human, and two negative controls (no robot: the colour checks fail;
  a far camera: the framing check fails).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from nlo_lab.human import Demonstration
from nlo_lab.robot import load_robot
from nlo_lab.viz import GROUP_COLOURS, RetargetScene, export_html, recording_visualizer, style_viewer
from nlo_lab.viz.export import scene_html

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = pytest.mark.browser  # skipped, with the reason, where chromium or playwright is missing (conftest.py)


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


def _hue_mask(png: Path, colour: int, hue_tol: float = 0.03) -> np.ndarray:
    """``(H, W)`` pixels whose hue is that of ``colour`` (saturated, not dark): shading changes brightness, not hue."""
    import matplotlib.colors as mcolors
    import matplotlib.image as mimage

    img = mimage.imread(str(png))[..., :3].astype(np.float64)  # (H, W, 3) in [0, 1]
    hsv = mcolors.rgb_to_hsv(img)
    target = mcolors.rgb_to_hsv(np.array([(colour >> 16) & 255, (colour >> 8) & 255, colour & 255]) / 255.0)
    dh = np.abs(hsv[..., 0] - target[0])
    dh = np.minimum(dh, 1.0 - dh)
    return (dh < hue_tol) & (hsv[..., 1] > 0.45) & (hsv[..., 2] > 0.2)


def _hue_fraction(png: Path, colour: int, hue_tol: float = 0.03) -> float:
    """Fraction of pixels of ``colour``'s hue."""
    return float(_hue_mask(png, colour, hue_tol).mean())


def _robot_span(png: Path) -> float:
    """How much of the picture the robot spans: the larger of its pixel bounding box's width and height fractions."""
    mask = np.zeros_like(_hue_mask(png, GROUP_COLOURS["arm"]))
    for colour in GROUP_COLOURS.values():
        mask |= _hue_mask(png, colour)
    if mask.sum() < 50:
        return 0.0
    rows, cols = np.nonzero(mask)
    H, W = mask.shape
    return max((cols.max() - cols.min() + 1) / W, (rows.max() - rows.min() + 1) / H)


def _shoot_all(pages: list[Path], tmp_path: Path, parallel: int = 2) -> dict[str, Path]:
    """Screenshots of ``pages`` (a few browsers at a time: many at once starve a 2-core machine)."""
    shots = {}
    for i in range(0, len(pages), parallel):
        jobs = [(_screenshot(p, tmp_path / f"{p.stem}.png", tmp_path / f"profile-{p.stem}"), p.stem) for p in pages[i:i + parallel]]
        for proc, stem in jobs:
            try:
                _, err = proc.communicate(timeout=120)
            except subprocess.TimeoutExpired:
                proc.kill()
                _, err = proc.communicate()
            assert (tmp_path / f"{stem}.png").is_file(), f"chromium made no screenshot of {stem}.html:\n{err[-2000:]}"
            shots[stem] = tmp_path / f"{stem}.png"
    return shots


def _sign_demo(T: int = 10) -> Demonstration:
    """Both arms forward, the hands moving a little; fingers ahead of the wrists [m]."""
    arm = np.zeros((T, 2, 3, 3))
    wave = 0.05 * np.sin(np.linspace(0, np.pi, T))[:, None]
    for s, y in enumerate((0.18, -0.18)):
        arm[:, s, 0] = [0.0, y, 0.0]
        arm[:, s, 1] = [0.05, y, -0.28]
        arm[:, s, 2] = np.array([0.28, y, -0.15]) + wave * [0, 0, 1]
    fingers = np.zeros((T, 2, 5, 2, 3))
    for f in range(5):
        fingers[:, :, f, 0] = arm[:, :, 2] + [0.08, 0.02 * (f - 2), 0]
        fingers[:, :, f, 1] = arm[:, :, 2] + [0.15, 0.02 * (f - 2), 0]
    rot = np.broadcast_to(np.eye(3), (T, 2, 3, 3)).copy()
    return Demonstration(20.0, arm, np.ones((T, 2, 3), bool), rot, np.ones((T, 2), bool), fingers, np.ones((T, 2, 5), bool), name="sign")


def test_chromium_draws_the_exported_robot_and_frames_it(tmp_path):
    yumi = load_robot("yumi")
    lo, hi = yumi.lower_limits.double().numpy(), yumi.upper_limits.double().numpy()
    q = lo + (hi - lo) * (0.5 + 0.2 * np.sin(np.linspace(0, np.pi, 20)))[:, None]  # (20, n) inside the limits
    page = export_html(tmp_path / "robot.html", yumi, q, fps=20)
    # The smallest robot beside its human: the case where a far camera left NAO as a speck.
    nao = load_robot("nao")
    demo = _sign_demo()
    q_nao = np.tile(0.5 * (nao.lower_limits + nao.upper_limits).double().numpy(), (len(demo), 1))
    nao_page = export_html(tmp_path / "nao.html", nao, q_nao, demo=demo, layout="side", play=False)
    # Negative controls: the same viewer and background with no robot (the colour checks must fail on it), and
    # the NAO scene seen from meshcat's default-sized camera 2 m away (the framing check must fail on it).
    vis = recording_visualizer()
    style_viewer(vis)
    empty = tmp_path / "empty.html"
    empty.write_text(scene_html(vis.window.tree), encoding="utf-8")
    vis = recording_visualizer()
    RetargetScene(vis, nao, q_nao, demo=demo)
    style_viewer(vis, camera=(2.0, -0.6, 0.6))
    far = tmp_path / "far.html"
    far.write_text(scene_html(vis.window.tree), encoding="utf-8")

    shots = _shoot_all([page, nao_page, empty, far], tmp_path)
    import matplotlib.image as mimage

    img = mimage.imread(str(shots["robot"]))[..., :3]
    assert img.shape[:2] == (600, 800)
    assert img.std() > 0.02, "the page is blank"
    thresholds = {"arm": 0.005, "hand": 0.0005, "torso": 0.002}
    for key, fraction in thresholds.items():
        found = _hue_fraction(shots["robot"], GROUP_COLOURS[key])
        assert found > fraction, f"{key} colour covers only {found:.4%} of the screenshot"
        assert _hue_fraction(shots["empty"], GROUP_COLOURS[key]) < fraction / 2, f"{key} colour found on the page without a robot"
    for key in ("arm", "torso", "head"):
        assert _hue_fraction(shots["nao"], GROUP_COLOURS[key]) > 0.002, f"NAO's {key} colour is missing"
    # Framing: the robot spans a good part of the picture (and not when the camera stands far away).
    for stem in ("robot", "nao"):
        assert _robot_span(shots[stem]) > 0.3, f"{stem}: the robot spans only {_robot_span(shots[stem]):.0%} of the picture"
    assert _robot_span(shots["far"]) < 0.3, f"the far camera's robot spans {_robot_span(shots['far']):.0%}: the framing check cannot fail"


def test_the_light_view_looks_like_the_full_one(tmp_path):
    """The live view's light tessellation against meshcat's own, same scene and camera: the same robot and
    human, a thin seam of pixels along the curved outlines. A coarse control (4 x 3 spheres, 4-sided
    cylinders) must differ clearly, or the check could not fail."""
    from nlo_lab.viz.tracks import SEGMENTS

    yumi = load_robot("yumi")
    lo, hi = yumi.lower_limits.double().numpy(), yumi.upper_limits.double().numpy()
    q = lo + (hi - lo) * (0.5 + 0.2 * np.sin(np.linspace(0, np.pi, 4)))[:, None]
    pages = []
    for detail, segments in (("full", SEGMENTS["full"]), ("light", SEGMENTS["light"]), ("coarse", (4, 3, 4))):
        vis = recording_visualizer()
        vis.window.detail = "light"
        old, SEGMENTS["light"] = SEGMENTS["light"], segments
        try:
            RetargetScene(vis, yumi, q, demo=_sign_demo(4))
        finally:
            SEGMENTS["light"] = old
        page = tmp_path / f"{detail}.html"
        page.write_text(scene_html(vis.window.tree), encoding="utf-8")
        pages.append(page)
    shots = _shoot_all(pages, tmp_path, parallel=3)
    import matplotlib.image as mimage

    img = {k: mimage.imread(str(v))[..., :3].astype(np.float64) for k, v in shots.items()}
    for key in ("arm", "hand", "torso"):
        full, light = (_hue_fraction(shots[d], GROUP_COLOURS[key]) for d in ("full", "light"))
        assert abs(light - full) <= 0.1 * full, f"{key}: {light:.4%} of the light picture, {full:.4%} of the full one"
    changed = _changed(img["full"], img["light"])
    coarse = _changed(img["full"], img["coarse"])
    print(f"pixels that differ visibly from the full tessellation: light {changed:.3%}, coarse {coarse:.3%}")
    assert changed < 0.01, f"{changed:.2%} of the pixels differ between the light and the full view"
    assert coarse > 2 * changed, f"the coarse control differs by only {coarse:.2%}: the check could not fail"


# ------------------------------------------------------------------ the notebooks in JupyterLab
ROOT = Path(__file__).resolve().parents[2]
MOVE_BYTES = 50_000  # the bound for one RetargetPanel move on YuMi with hands [bytes]


@pytest.fixture(scope="module")
def browser(lab_browser):
    """One Chromium for the module's Jupyter tests (Playwright allows one sync session at a time)."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        chromium = p.chromium.launch(executable_path=CHROMIUM, args=lab_browser.CHROMIUM_ARGS)
        try:
            yield chromium
        finally:
            chromium.close()


@pytest.fixture(scope="module")
def lab_page(tmp_path_factory, browser, lab_browser):
    tmp = tmp_path_factory.mktemp("lab")
    (tmp / "notebooks").mkdir()
    for name in ("01_robots_and_kinematics.ipynb", "05_neural_initialisation.ipynb"):
        shutil.copy(ROOT / "notebooks" / name, tmp / "notebooks" / name)  # the lab writes to its copies only
    with lab_browser.Lab(tmp / "notebooks", tmp / "state", env={"NLO_LAB_TEST_MODE": "1"}) as lab:
        page = lab_browser.LabPage(browser, lab, width=1280, height=900)
        try:
            yield page, tmp
        finally:
            page.page.close()
        log = lab.log()
    assert "Traceback" not in log, f"the kernel or the server logged an error:\n{log[-4000:]}"


@pytest.fixture(scope="module")
def robot_colours(lab_browser):
    """``robot_colours(img)``: the fraction of a picture in each robot group's colour."""
    return lambda img: {key: float(lab_browser.hue_mask(img, colour).mean()) for key, colour in GROUP_COLOURS.items()}


def _check_clean(page) -> None:
    assert page.error_outputs() == [], "error output in the notebook"
    assert page.view_messages() == [], "a 3-D view shows a message"
    assert page.console_errors == [], "errors in the browser console"
    assert page.foreign_addresses() == [], "the page talked to another origin"
    server_log = page.lab.log()
    assert "Traceback" not in server_log, f"an error in the kernel (a widget callback?):\n{server_log[-4000:]}"


def _changed(a: np.ndarray, b: np.ndarray) -> float:
    """Fraction of pixels that differ visibly between two pictures of the same size."""
    return float((np.abs(a - b).max(axis=-1) > 0.1).mean())


def _write_notebook(path: Path, cells: list[str]) -> None:
    """A notebook of the code ``cells`` at ``path``, on the python3 kernel: what a test opens in the page."""
    import nbformat

    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(c) for c in cells])
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3 (ipykernel)", "language": "python"}
    nbformat.write(nb, path)


def _run_cells(page, folder: Path, name: str, cells: list[str]) -> None:
    """The code ``cells`` as notebook ``name`` in the lab's ``folder``, opened, run, its one 3-D view drawn."""
    _write_notebook(folder / name, cells)
    page.open_notebook(name)
    page.run_all()
    page.wait_views(1)


def _readouts_visible(page, cell: int) -> list[str]:
    """Slider readouts of a cell's output that something else covers (scrolled into view first)."""
    return page.page.evaluate(
        """(cell) => {
            const out = document.querySelectorAll('.jp-NotebookPanel:not(.lm-mod-hidden) .jp-CodeCell')[cell];
            const hidden = [];
            for (const el of out.querySelectorAll('.widget-readout, .widget-label, .noUi-handle, select, button')) {
                el.scrollIntoView({block: 'center'});
                const r = el.getBoundingClientRect();
                if (r.width === 0 || r.height === 0) continue;
                const top = document.elementFromPoint(r.left + r.width / 2, r.top + r.height / 2);
                if (!(top && (top === el || el.contains(top) || top.contains(el)))) hidden.push(el.textContent || el.className);
            }
            return hidden;
        }""",
        cell,
    )


def _joint_panel_moves_nao(page, view: int, pictures: Path, robot_colours) -> None:
    """The page's ``JointPanel(`` cell on NAO, drawn in 3-D view ``view``: every control visible at 1280 px, NAO
    drawn, and its first slider moved to the end changes the picture in one message under the bound."""
    panel_cell = page.cell_with("JointPanel(")
    assert _readouts_visible(page, panel_cell) == [], "controls covered at 1280 px"
    before = page.canvas_image(view, pictures.with_name(pictures.name + "-before.png"))
    assert robot_colours(before)["arm"] > 0.002, "NAO is not drawn"
    move = page.move_slider(page.slider_handles(panel_cell).first, key="End")
    after = page.canvas_image(view, pictures.with_name(pictures.name + "-after.png"))
    assert move["messages"] == 1, move
    assert move["bytes"] < MOVE_BYTES, move
    assert _changed(before, after) > 0.002, "the joint slider did not change the picture"


def test_notebook_01_views_and_sliders_in_jupyterlab(lab_page, robot_colours):
    page, tmp = lab_page
    page.open_notebook("01_robots_and_kinematics.ipynb")
    page.run_all()
    page.wait_views(2)
    _check_clean(page)
    # multisampling decided in the page: off where WebGL draws on the CPU (SwiftShader here), on with a GPU
    renderer = page.canvas(0).get_attribute("data-renderer")
    software = re.search("swiftshader|llvmpipe|software", renderer, re.I) is not None
    assert page.canvas(0).get_attribute("data-antialias") == str(not software).lower(), renderer
    yumi = page.canvas_image(0, tmp / "01-yumi.png")
    colours = robot_colours(yumi)
    assert colours["arm"] > 0.01 and colours["hand"] > 0.002 and colours["torso"] > 0.005, colours  # YuMi, hands and all
    cells = page.cells()
    _joint_panel_moves_nao(page, 1, tmp / "01-nao", robot_colours)
    # YuMi's own view still shows YuMi (its hands are green; NAO has none)
    assert robot_colours(page.canvas_image(0, tmp / "01-yumi-again.png"))["hand"] > 0.002
    # the interact slider (reads only its own arguments now)
    interact_cell = page.cell_with("@interact")
    text = cells.nth(interact_cell).locator(".jp-Cell-outputArea").text_content()
    handle = page.slider_handles(interact_cell).first
    handle.scroll_into_view_if_needed()
    handle.focus()
    handle.press("End")
    page.wait_kernel_idle()
    page.page.wait_for_timeout(500)
    assert cells.nth(interact_cell).locator(".jp-Cell-outputArea").text_content() != text
    _check_clean(page)


def test_notebook_05_panel_in_jupyterlab(lab_page, robot_colours):
    page, tmp = lab_page
    page.open_notebook("05_neural_initialisation.ipynb")
    page.run_all()
    page.wait_views(1)
    _check_clean(page)
    panel_cell = page.cell_with("RetargetPanel(")
    assert _readouts_visible(page, panel_cell) == [], "controls covered at 1280 px"
    before = page.canvas_image(0, tmp / "05-before.png")
    colours = robot_colours(before)
    assert colours["arm"] > 0.005 and colours["hand"] > 0.001, colours
    handles = page.slider_handles(panel_cell)
    weight = page.move_slider(handles.first, key="ArrowRight")  # the ee weight: re-optimise this frame
    frame = page.move_slider(page.slider_handle(panel_cell, "frame"), key="End")  # the last frame
    after = page.canvas_image(0, tmp / "05-after.png")
    for move in (weight, frame):
        assert move["messages"] == 1, move
        assert move["bytes"] < MOVE_BYTES, move
    assert _changed(before, after) > 0.002, "the frame slider did not change the picture"
    _check_clean(page)


BUSY_SECONDS = 40  # the cell after the view keeps the kernel busy this long


def test_a_view_inside_a_container_draws_while_the_kernel_is_busy(lab_page, robot_colours):
    """A scene widget shown inside a plain VBox (never displayed itself), the next cell busy: the view draws
    the robot from its saved scene while the kernel still runs that cell, and goes live when it answers."""
    import time

    page, tmp = lab_page
    cells = [
        "import ipywidgets\nfrom nlo_lab.lab import show_robot\nfrom nlo_lab.viz import SceneWidget\n"
        "SceneWidget.default_antialias = True  # multisampled, even on a software renderer\n"
        "ipywidgets.VBox([show_robot('yumi')])",
        f"import time\ntime.sleep({BUSY_SECONDS})",
    ]
    _write_notebook(tmp / "notebooks" / "busy.ipynb", cells)
    page.open_notebook("busy.ipynb")
    page.page.locator(".lm-MenuBar-itemLabel", has_text=re.compile(r"^Run$")).click()
    page.page.locator(".lm-Menu-itemLabel", has_text=re.compile(r"^Run All Cells$")).click()
    start, drawn_while_busy = time.monotonic(), None
    while time.monotonic() - start < BUSY_SECONDS - 5 and drawn_while_busy is None:
        page.page.wait_for_timeout(1000)
        if page.canvas(0).count() == 0:
            continue
        colours = robot_colours(page.canvas_image(0, tmp / "busy.png"))
        if colours["arm"] > 0.01 and colours["hand"] > 0.002:
            drawn_while_busy = page.kernel_status()
    assert drawn_while_busy == "busy", f"the view did not draw YuMi while the kernel was busy ({drawn_while_busy})"
    assert page.canvas(0).get_attribute("data-antialias") == "true"
    page.wait_kernel_idle(timeout=BUSY_SECONDS + 60)
    page.wait_views(1, timeout=30)  # answered: no message over the view once the kernel is free
    _check_clean(page)


def test_the_view_and_a_panel_in_notebook_7(tmp_path, browser, lab_browser, robot_colours):
    """Notebook 7 (not JupyterLab): a robot's view and a JointPanel draw, a slider move changes the picture."""
    import nbformat

    pytest.importorskip("notebook", minversion="7", reason="Notebook 7 is not installed (pip install 'notebook>=7')")
    (tmp_path / "nb").mkdir()
    cells = [
        "from nlo_lab.lab import show_robot\nshow_robot('yumi')",
        "from nlo_lab.lab import JointPanel\nfrom nlo_lab.robot import load_robot\nJointPanel(load_robot('nao'))",
    ]
    _write_notebook(tmp_path / "nb" / "views.ipynb", cells)
    saving = {"@jupyter-widgets/jupyterlab-manager/plugin": {"saveState": True}}  # File > Save keeps widget state
    with lab_browser.Lab(tmp_path / "nb", tmp_path / "state", app="notebook", settings=saving) as lab:
        page = lab_browser.LabPage(browser, lab, width=1280, height=900)
        try:
            page.open_notebook("views.ipynb")
            assert "/notebooks/views.ipynb" in page.page.url and "/lab" not in page.page.url  # Notebook 7's own page
            # Notebook 7.6.5 itself throws one page error while it loads any notebook, "1+1" alone too (its
            # shortcut settings, in notebook_core.js), before any cell ran or our view's code was loaded:
            # only errors after that count.
            print("Notebook 7's own errors at load:", page.console_errors)
            page.console_errors.clear()
            page.run_all()
            page.wait_views(2)
            _check_clean(page)
            yumi = robot_colours(page.canvas_image(0, tmp_path / "nb7-yumi.png"))
            assert yumi["arm"] > 0.01 and yumi["hand"] > 0.002, yumi
            _joint_panel_moves_nao(page, 1, tmp_path / "nb7-nao", robot_colours)
            _check_clean(page)
            # Saved, its kernel shut down, opened again (a new kernel, which never made these views): each view
            # draws its saved scene and says that no kernel answers, instead of a blank canvas in silence.
            page.page.keyboard.press("Control+s")
            page.page.wait_for_timeout(2000)
            saved = nbformat.read(tmp_path / "nb" / "views.ipynb", as_version=4)
            assert "application/vnd.jupyter.widget-state+json" in saved.metadata.get("widgets", {}), "widget state not saved"
            for session in lab.api("GET", "api/sessions"):
                lab.api("DELETE", f"api/sessions/{session['id']}")  # shuts its kernel down
            page.open_notebook("views.ipynb")
            page.wait_views(2, messages=True)
            yumi = robot_colours(page.canvas_image(0, tmp_path / "nb7-saved-yumi.png"))
            assert yumi["arm"] > 0.01 and yumi["hand"] > 0.002, yumi  # the saved scene, drawn without its kernel
            page.page.wait_for_function(
                "() => document.querySelectorAll('.nlo-lab-view-message').length === 2 && Array.from("
                "document.querySelectorAll('.nlo-lab-view-message')).every(el => el.style.display !== 'none')",
                timeout=30_000)
            assert all(text.startswith("No kernel answers") for text in page.view_messages()), page.view_messages()
        finally:
            page.page.close()


def test_an_animation_loops_and_its_button_pauses_it(lab_page):
    """show_view's animation (1 s) still plays after two passes; the view's button pauses it (the picture stops) and plays it."""
    page, tmp = lab_page
    cell = ("import numpy as np\nfrom nlo_lab.lab import show_view\nfrom nlo_lab.robot import load_robot\nnao = load_robot('nao')\n"
            "lo, hi = nao.lower_limits.numpy(), nao.upper_limits.numpy()\n"
            "show_view(nao, np.linspace(0.8 * lo + 0.2 * hi, 0.2 * lo + 0.8 * hi, 31))  # 30 steps at 30 fps: 1 s")
    _run_cells(page, tmp / "notebooks", "loop.ipynb", [cell])
    button = page.page.locator(".nlo-lab-play").first
    state = lambda: button.get_attribute("data-state")  # noqa: E731
    page.page.wait_for_timeout(2500)  # two passes and a half
    assert state() == "playing" and button.is_visible()
    a, b = page.canvas_image(0, tmp / "loop-a.png"), page.canvas_image(0, tmp / "loop-b.png")
    assert _changed(a, b) > 0.002, "the animation does not move"
    button.click()
    assert state() == "paused"
    a, b = page.canvas_image(0, tmp / "loop-c.png"), page.canvas_image(0, tmp / "loop-d.png")
    assert _changed(a, b) < 0.0005, "the paused animation still moves"
    button.click()
    assert state() == "playing"
    _check_clean(page)


def test_the_hand_panel_s_preset_button_in_jupyterlab(lab_page, robot_colours):
    """Notebook 12's HandPanel on the letter V: every control visible at 1280 px (the search list and the button
    too), the YuMi hand drawn; its "handshape preset" button selects the preset's fingers in the page, changes the
    readout and the picture, in one view update."""
    page, tmp = lab_page
    source = ("from nlo_lab.corpus.fingerspelling import fingerspelling_demonstration\nfrom nlo_lab.lab import HandPanel\n"
              "from nlo_lab.robot import load_robot\n"
              "panel = HandPanel(fingerspelling_demonstration('V'), load_robot('yumi'), iterations=10)\npanel.widget")
    _run_cells(page, tmp / "notebooks", "hands.ipynb", [source])
    _check_clean(page)
    cell = page.cell_with("HandPanel(")
    assert _readouts_visible(page, cell) == [], "controls covered at 1280 px"
    output = page.cells().nth(cell).locator(".jp-Cell-outputArea")
    before = page.canvas_image(0, tmp / "12-before.png")
    assert robot_colours(before)["hand"] > 0.003, "the close-up shows no hand"
    readout = output.locator(".widget-html-content", has_text="wrist→tip").text_content()
    messages = page.view_stats().get("messages", 0)
    output.get_by_role("button", name="handshape preset").click()
    page.wait_kernel_idle()
    page.page.wait_for_timeout(1000)
    after = page.canvas_image(0, tmp / "12-after.png")
    selected = output.locator("select[multiple]").evaluate("s => Array.from(s.selectedOptions).map(o => o.textContent)")
    assert selected == ["middle", "ring", "pinky"]
    assert output.locator(".widget-html-content", has_text="wrist→tip").text_content() != readout
    assert page.view_stats().get("messages", 0) - messages == 1  # one update for every control the button set
    # the hand fills under 1 % of this view and the preset moves V's fingers by a few hundredths of a radian: 0.06 %
    # of the pixels changed when this test was written
    assert _changed(before, after) > 0.0002, "the preset did not change the picture"
    _check_clean(page)

"""`make docs` (tools/docs.py): a static site of executed notebooks that opens offline, 3-D scenes included.

One small notebook (a plot, an equation, a robot's 3-D view) is built into a site with the README and
RESULTS, in test mode. The site's pages load only files of the site (require.js, the widget manager,
anywidget, MathJax: copied from the npm packages ``make export-js`` installs); in Chromium, from
``file://`` with every other address refused, the view draws the robot and MathJax typesets.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import nbformat
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))
import export_js  # noqa: E402

pytest.importorskip("mkdocs_jupyter", reason="the docs extra is not installed (pip install -e '.[docs]')")
pytestmark = pytest.mark.slow  # the site fixture runs a notebook and mkdocs (about 40 s on 2 cores)


def _docs(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / "tools" / "docs.py"), *args], capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    if export_js.missing(export_js.DOCS_EXTRA):
        pytest.skip(export_js.missing(export_js.DOCS_EXTRA))
    tmp = tmp_path_factory.mktemp("gallery")
    cells = [
        nbformat.v4.new_markdown_cell("# 00. A small page\n\nForward kinematics: $$T_{world,link} = T_{world,parent} \\cdot T_{origin}$$"),
        nbformat.v4.new_code_cell("from nlo_lab.lab import TEST_MODE, setup, show_robot\nsetup()"),
        nbformat.v4.new_code_cell("import matplotlib.pyplot as plt\nplt.plot([0, 1], [1, 0]);"),
        nbformat.v4.new_code_cell("show_robot('nao')"),
        nbformat.v4.new_code_cell("import ipywidgets\nipywidgets.FloatSlider(description='$x$ [m]')  # a control typesets its label"),
    ]
    nb = nbformat.v4.new_notebook(cells=cells)
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3 (ipykernel)", "language": "python"}
    nbformat.write(nb, tmp / "00_small.ipynb")
    run = _docs("--quick", "--notebook", str(tmp / "00_small.ipynb"), "--stage", str(tmp / "stage"), "--site", str(tmp / "site"))
    assert run.returncode == 0, run.stderr[-3000:]
    assert "site: " in run.stdout
    return tmp / "site"


@pytest.mark.slow  # the site fixture runs a notebook and mkdocs: about 15 s on 2 cores
def test_the_site_has_the_readme_results_and_the_executed_notebook(site):
    home = (site / "index.html").read_text(encoding="utf-8")
    assert "Learn and try" in home and "00_small.html" in home  # the README, with the notebook in the navigation
    assert (site / "RESULTS.html").is_file() and any((site / "figures").glob("*.png"))
    page = (site / "00_small.html").read_text(encoding="utf-8")
    assert "test mode on" in page and "data:image/png;base64," in page  # executed: its output and its plot
    state = json.loads(re.search(r'<script type="application/vnd.jupyter.widget-state\+json">(.*?)</script>', page, re.S).group(1))
    scenes = [m for m in state["state"].values() if m["model_module"] == "anywidget"]
    assert len(scenes) == 1 and any(b["path"] == ["_scene"] for b in scenes[0]["buffers"])  # the 3-D scene travels in the page


@pytest.mark.slow
def test_every_script_of_a_page_is_a_file_of_the_site(site):
    page = (site / "00_small.html").read_text(encoding="utf-8")
    sources = re.findall(r'<script[^>]* src="([^"]+)"', page) + re.findall(r"widgetRendererSrc = '([^']+)'", page)
    assert any("require.js" in s for s in sources) and any("embed-amd.js" in s for s in sources) and any("tex-chtml" in s for s in sources)
    for src in sources:
        assert "://" not in src, f"{src} comes from another site"
        assert (site / src).is_file(), f"{src} is missing from the site"
    assert (site / "js" / "anywidget" / "dist" / "index.js").is_file()


def test_a_missing_notebook_is_one_line_exit_2(tmp_path):
    run = _docs("--notebook", str(tmp_path / "nothing.ipynb"), "--stage", str(tmp_path / "s"), "--site", str(tmp_path / "site"))
    assert run.returncode == 2 and run.stderr.count("\n") == 1 and "no such notebook" in run.stderr, run.stderr
    assert not (tmp_path / "site").exists()


@pytest.mark.slow
@pytest.mark.browser
def test_the_page_draws_the_robot_offline(site, tmp_path, lab_browser):
    """Chromium opens the page from file:// with every other address refused: NAO drawn, the equation typeset."""
    import matplotlib.image as mimage

    from nlo_lab.viz import GROUP_COLOURS

    seen = lab_browser.offline_view_shot(site / "00_small.html", tmp_path / "page.png", ready="() => document.querySelector('mjx-container') !== null")
    img = mimage.imread(str(tmp_path / "page.png"))[..., :3].astype(float)
    colours = {key: float(lab_browser.hue_mask(img, colour).mean()) for key, colour in GROUP_COLOURS.items()}
    assert colours["arm"] > 0.002 and colours["torso"] > 0.002, colours  # NAO: arms and torso drawn
    assert seen == {"served": [], "refused": [], "errors": []}, seen

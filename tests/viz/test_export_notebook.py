"""An exported notebook shows its 3-D scene: ``jupyter nbconvert --to html --execute`` saves the widget state.

The page's widget state holds meshcat's bundle once (the :class:`MeshcatBundle` model), and each
view's whole scene (``_scene``, meshcat's commands) with the output that displays it. Opening
the page needs require.js, the widget manager for HTML pages (@jupyter-widgets/html-manager) and
anywidget's front end, which nbconvert's template loads from public CDNs. No CDN is reachable
here: chromium (Playwright) gets them from the npm packages ``make export-js`` installs into the
user cache (tools/export_js.py), every other address is refused, and the 3-D canvas must show
the robot. Skipped, with the reason, without chromium or without those packages (no npm or no
registry). A reader online loads the same addresses from the CDNs.
"""

from __future__ import annotations

import base64
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import nbformat
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))
import export_js  # noqa: E402

from nlo_lab.viz.widget import unpack_commands  # noqa: E402

pytestmark = pytest.mark.slow  # nbconvert executes a notebook first (about 20 s on 2 cores)


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> Path:
    """``view.html``: a notebook showing NAO, executed and exported with its widget state."""
    tmp = tmp_path_factory.mktemp("export")
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("from nlo_lab.lab import show_robot\nshow_robot('nao')")])
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3 (ipykernel)", "language": "python"}
    nbformat.write(nb, tmp / "view.ipynb")
    # nbclient under nbconvert, its kernel's client from tools/notebook_client.py: a lost wake-up of the shell
    # socket would otherwise leave it waiting for the cell's reply with no timeout at all (nbconvert's default)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT / "tools"), os.environ.get("PYTHONPATH")]))}
    run = subprocess.run([sys.executable, "-m", "jupyter", "nbconvert", "--to", "html", "--execute", "view.ipynb",
                          "--ExecutePreprocessor.kernel_manager_class=notebook_client.PatientKernelManager"],
                         cwd=tmp, capture_output=True, text=True, timeout=300, env=env)
    assert run.returncode == 0, run.stderr[-3000:]
    return tmp / "view.html"


def test_exported_notebook_holds_the_scene(exported):
    from meshcat.servers.zmqserver import VIEWER_ROOT

    page = exported.read_text(encoding="utf-8")
    state = json.loads(re.search(r'<script type="application/vnd.jupyter.widget-state\+json">(.*?)</script>', page, re.S).group(1))["state"]
    scenes = {k: v for k, v in state.items() if v["model_module"] == "anywidget"}
    bundles = {k: v for k, v in state.items() if "code" in v["state"]}
    assert len(scenes) == 1 and len(bundles) == 1
    (scene_id, scene), = scenes.items()
    (bundle_id, bundle), = bundles.items()
    assert bundle["state"]["code"] == (Path(VIEWER_ROOT) / "main.min.js").read_text(encoding="utf-8")
    assert scene["state"]["_bundle"] == f"IPY_MODEL_{bundle_id}"
    buffer, = [b for b in scene["buffers"] if b["path"] == ["_scene"]]
    commands = unpack_commands(base64.b64decode(buffer["data"]))
    paths = {c["path"] for c in commands}
    assert commands[0]["type"] == "delete" and "/meshcat/robot/Head" in paths  # NAO, drawn from scratch
    assert scene["state"]["_scene_version"] > 0
    assert f'"model_id": "{scene_id}"' in page  # the cell's output displays that view


@pytest.mark.browser
def test_exported_notebook_shows_the_robot_in_chromium(exported, tmp_path, lab_browser):
    if export_js.missing():
        pytest.skip(export_js.missing())
    from nlo_lab.viz import GROUP_COLOURS

    seen = lab_browser.offline_view_shot(exported, tmp_path / "export.png", local=export_js.local_file)
    served, errors = seen["served"], seen["errors"]
    import matplotlib.image as mimage

    img = mimage.imread(str(tmp_path / "export.png"))[..., :3].astype(np.float64)
    colours = {key: float(lab_browser.hue_mask(img, colour).mean()) for key, colour in GROUP_COLOURS.items()}
    assert colours["arm"] > 0.002 and colours["torso"] > 0.002, colours  # NAO: arms and torso drawn
    assert any("html-manager" in u for u in served) and any("/anywidget@" in u for u in served), served
    assert errors == [], errors

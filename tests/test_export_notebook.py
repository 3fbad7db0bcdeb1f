"""An exported notebook carries its 3-D scene: ``jupyter nbconvert --to html --execute`` saves the widget state.

The page's widget state holds meshcat's bundle once (the :class:`MeshcatBundle` model), and each
view's whole scene (``_scene``, meshcat's commands) with the output that displays it. Opening
the page needs the widget manager for HTML pages (@jupyter-widgets/html-manager) and anywidget's
front end, which nbconvert's template loads from a public CDN: that part cannot be checked here,
where no CDN is reachable.
"""

from __future__ import annotations

import base64
import json
import re
import subprocess
import sys

import nbformat
import umsgpack


def _unpack(data: bytes) -> list[dict]:
    out, at = [], 0
    while at < len(data):
        n = int.from_bytes(data[at:at + 4], "little")
        out.append(umsgpack.unpackb(data[at + 4:at + 4 + n]))
        at += 4 + n
    return out


def test_exported_notebook_holds_the_scene(tmp_path):
    from meshcat.servers.zmqserver import VIEWER_ROOT
    from pathlib import Path

    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("from nlo_lab.lab import show_robot\nshow_robot('nao')")])
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3 (ipykernel)", "language": "python"}
    nbformat.write(nb, tmp_path / "view.ipynb")
    run = subprocess.run([sys.executable, "-m", "jupyter", "nbconvert", "--to", "html", "--execute", "view.ipynb"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    page = (tmp_path / "view.html").read_text(encoding="utf-8")
    state = json.loads(re.search(r'<script type="application/vnd.jupyter.widget-state\+json">(.*?)</script>', page, re.S).group(1))["state"]
    scenes = {k: v for k, v in state.items() if v["model_module"] == "anywidget"}
    bundles = {k: v for k, v in state.items() if "code" in v["state"]}
    assert len(scenes) == 1 and len(bundles) == 1
    (scene_id, scene), = scenes.items()
    (bundle_id, bundle), = bundles.items()
    assert bundle["state"]["code"] == (Path(VIEWER_ROOT) / "main.min.js").read_text(encoding="utf-8")
    assert scene["state"]["_bundle"] == f"IPY_MODEL_{bundle_id}"
    buffer, = [b for b in scene["buffers"] if b["path"] == ["_scene"]]
    commands = _unpack(base64.b64decode(buffer["data"]))
    paths = {c["path"] for c in commands}
    assert commands[0]["type"] == "delete" and "/meshcat/robot/Head" in paths  # NAO, drawn from scratch
    assert scene["state"]["_scene_version"] > 0
    assert f'"model_id": "{scene_id}"' in page  # the cell's output displays that view

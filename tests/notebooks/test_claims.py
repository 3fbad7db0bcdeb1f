"""A notebook's sentences about its results are computed from the run they describe.

Each notebook here runs (test mode, as under nbval) in a copy, and the sentence it renders
(``IPython.display.Markdown``) is read back and checked against the numbers the same run
printed: a sentence written by hand, true only for some past run, fails.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import nbformat
import pytest

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = ROOT / "notebooks"

pytestmark = pytest.mark.slow


def _run(name: str, tmp_path: Path, monkeypatch, run_notebook) -> list[nbformat.NotebookNode]:
    """Notebook ``name`` run in test mode on a copy in ``tmp_path``."""
    (path,) = NOTEBOOKS.glob(f"{name}_*.ipynb")
    shutil.copy(path, tmp_path / path.name)
    monkeypatch.setenv("NLO_LAB_TEST_MODE", "1")  # the kernel inherits this process's environment
    monkeypatch.setenv("NLO_LAB_WORK", str(tmp_path / "work"))
    return run_notebook(tmp_path / path.name, tmp_path)


def _cell(cells, text: str):
    (cell,) = [c for c in cells if text in c.source]
    return cell


def _stdout(cell) -> str:
    return "".join(o.get("text", "") for o in cell.outputs if o.output_type == "stream" and o.name == "stdout")


def _markdown(cell) -> str:
    (md,) = [o.data["text/markdown"] for o in cell.outputs if o.output_type in ("execute_result", "display_data")
             and "text/markdown" in o.data]
    return md


def test_notebook_01_fk_speed_sentence_is_the_measured_ratio(tmp_path, monkeypatch, run_notebook):
    cell = _cell(_run("01", tmp_path, monkeypatch, run_notebook), "Measured just now")
    printed = {int(b): float(r) for b, r in re.findall(r"batch\s+(\d+):.*ratio\s+([\d.]+)", _stdout(cell))}
    md = _markdown(cell)
    said = [float(x) for x in re.findall(r"\*\*([\d.]+)×\*\*", md)]
    assert set(printed) == {1, 256} and said == [printed[1], printed[256]], (printed, md)
    assert ("smaller" if printed[256] < printed[1] else "larger") in md
    assert "orders of magnitude" not in md


def test_notebook_04_comparison_sentence_is_the_printed_means(tmp_path, monkeypatch, run_notebook):
    cells = _run("04", tmp_path, monkeypatch, run_notebook)
    means = dict(re.findall(r"final loss, (latent|joints): ([\d.]+)", _stdout(_cell(cells, 'print(f"final loss, latent'))))
    md = _markdown(_cell(cells, "guided = optimize_latent"))
    said = re.findall(r"\*\*([\d.]+)\*\*", md)
    assert said[:2] == [means["latent"], means["joints"]], (means, md)
    worse = float(means["latent"]) > float(means["joints"])
    assert ("did **worse**" if worse else "did **better**") in md

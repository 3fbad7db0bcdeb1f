"""The notebooks follow notebooks/README.md."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import nbformat
import pytest

WAITS_FOR_INPUT = re.compile(r"(?<![\w.])input\(")  # the builtin, not encoder_input( or x.input(

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = ROOT / "notebooks"
MINE = ("01_", "02_", "03_", "04_", "05_", "08_")


def _tool():
    spec = importlib.util.spec_from_file_location("nlo_notebooks_tool", ROOT / "tools" / "notebooks.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


ALL = sorted(NOTEBOOKS.glob("*.ipynb"))


def test_the_series_is_there():
    names = [p.name for p in ALL]
    for prefix in MINE:
        assert any(n.startswith(prefix) for n in names), f"no notebook {prefix}*.ipynb"


@pytest.mark.parametrize("path", ALL, ids=[p.name for p in ALL])
def test_notebook_follows_the_conventions(path):
    assert _tool().problems(path) == []
    nb = nbformat.read(path, as_version=4)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code and "setup()" in code[0].source, "the first code cell must call setup() (nlo_lab.lab)"
    for i, cell in enumerate(code):
        assert "NBVAL_SKIP" not in cell.source, f"code cell {i} is skipped under nbval"
        assert not WAITS_FOR_INPUT.search(cell.source), f"code cell {i} waits for input"


def test_check_catches_a_bad_notebook(tmp_path):
    tool = _tool()
    nb = tool.from_source("# %% [markdown]\n# # x\n#\n# ## Learning goals\n#\n# - a\n\n# %%\n1 + 1\n\n# %% [markdown]\n# no exercises\n")
    nb.cells[1].outputs = [nbformat.v4.new_output("execute_result", {"text/plain": "2"}, execution_count=1)]
    nb.cells[1].execution_count = 1
    nb.metadata["kernelspec"]["name"] = "python2"
    path = tmp_path / "99_bad.ipynb"
    nbformat.write(nb, path)
    found = "\n".join(tool.problems(path))
    for expected in ("kernelspec", "outputs", "Exercises", "no source"):
        assert expected in found
    tool.strip(nb)
    assert all(not c.get("outputs") for c in nb.cells if c.cell_type == "code")


def test_build_reads_the_percent_format_with_jupytext():
    tool = _tool()
    source = "# %% [markdown]\n# # T\n#\n# text\n\n# %%\nx = 1\n\n# %%\nprint(x)\n"
    nb = tool.from_source(source)
    assert [(c.cell_type, c.source) for c in nb.cells] == [("markdown", "# T\n\ntext"), ("code", "x = 1"), ("code", "print(x)")]
    assert [c.id for c in nb.cells] == ["c00", "c01", "c02"]  # stable: a rebuild gives the same file
    assert "jupytext" not in nb.metadata and all(not c.metadata for c in nb.cells)
    assert tool.dumps(tool.from_source(source)) == tool.dumps(nb)


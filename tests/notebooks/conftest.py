"""What the notebook tests share: running a notebook as Jupyter would."""

from __future__ import annotations

import sys
from pathlib import Path

import nbformat
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))
from notebook_client import notebook_client  # noqa: E402  (nbclient without its 10-minute stalls: see there)


def _run_notebook(path: Path, cwd: Path) -> list[nbformat.NotebookNode]:
    """The code cells of the notebook at ``path`` after running all of it (a kernel in ``cwd``, this
    process's environment: set ``NLO_LAB_TEST_MODE`` first for the short budgets)."""
    nb = nbformat.read(path, as_version=4)
    notebook_client(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(cwd)}}).execute()
    return [c for c in nb.cells if c.cell_type == "code"]


@pytest.fixture(scope="session")
def run_notebook():
    """``run_notebook(path, cwd)`` -> the notebook's code cells with their outputs."""
    return _run_notebook

"""Build, strip and check the notebooks (see notebooks/README.md).

The source of every notebook is ``notebooks/src/NN_name.py`` in jupytext's
percent format: ``# %% [markdown]`` starts a markdown cell (its lines are
``# `` comments), ``# %%`` starts a code cell. ``build`` reads it with
jupytext and writes ``notebooks/NN_name.ipynb`` with nbformat 4, outputs
stripped, kernelspec python3, and a stamp of its source in the metadata
(``nlo_lab.revision``, by which ``nlo-lab lab`` tells a learner that a copy
is from another version). ``check`` is our conventions check (learning
goals, exercises, outputs stripped, in sync with the source).

Usage::

    python tools/notebooks.py build [PREFIX ...]
    python tools/notebooks.py strip FILE.ipynb [...]
    python tools/notebooks.py check
"""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import jupytext
import nbformat

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = ROOT / "notebooks"
SOURCES = NOTEBOOKS / "src"

KERNELSPEC = {"display_name": "Python 3 (ipykernel)", "language": "python", "name": "python3"}
LANGUAGE_INFO = {"name": "python", "pygments_lexer": "ipython3"}


def from_source(text: str) -> nbformat.NotebookNode:
    """A stripped nbformat-4 notebook from a percent-format source (read by jupytext).

    jupytext gives the cells; we drop its bookkeeping metadata (the sources are
    the truth, there is no pairing), fix the kernelspec, stamp the source's digest
    (``metadata.nlo_lab.revision``, kept by Jupyter when a learner saves) and give
    every cell a stable id, so that rebuilding an unchanged source gives the same file.
    """
    nb = jupytext.reads(text, fmt="py:percent")
    revision = hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]
    nb.metadata = nbformat.from_dict(
        {"kernelspec": dict(KERNELSPEC), "language_info": dict(LANGUAGE_INFO), "nlo_lab": {"revision": revision}}
    )
    for i, cell in enumerate(nb.cells):
        cell.metadata = nbformat.from_dict({})
        cell.id = f"c{i:02d}"
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
    nbformat.validate(nb)
    return nb


def make_notebook(cells: list[tuple[str, str]]) -> nbformat.NotebookNode:
    """A stripped notebook of ``[(kind, source)]`` cells, normalised like :func:`from_source` (for tests)."""
    nb = nbformat.v4.new_notebook()
    nb.metadata = nbformat.from_dict({"kernelspec": dict(KERNELSPEC), "language_info": dict(LANGUAGE_INFO)})
    for i, (kind, source) in enumerate(cells):
        cell = nbformat.v4.new_markdown_cell(source) if kind == "markdown" else nbformat.v4.new_code_cell(source)
        cell.id = f"c{i:02d}"
        nb.cells.append(cell)
    nbformat.validate(nb)
    return nb


def dumps(nb: nbformat.NotebookNode) -> str:
    return nbformat.writes(nb) + "\n"


def build_one(src: Path) -> Path:
    target = NOTEBOOKS / (src.stem + ".ipynb")
    target.write_text(dumps(from_source(src.read_text(encoding="utf-8"))), encoding="utf-8")
    return target


def strip(nb: nbformat.NotebookNode) -> nbformat.NotebookNode:
    """Remove outputs, execution counts and widget state (in place); returns ``nb``."""
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs = []
            cell.execution_count = None
        for key in ("execution", "collapsed", "scrolled"):
            cell.metadata.pop(key, None)
    nb.metadata.pop("widgets", None)
    return nb


def problems(path: Path) -> list[str]:
    """What is wrong with a committed notebook (empty list when it follows the conventions)."""
    name = path.name
    nb = nbformat.read(path, as_version=4)
    out = []
    if nb.metadata.get("kernelspec", {}).get("name") != "python3":
        out.append(f"{name}: kernelspec is not python3")
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "code" and (cell.outputs or cell.execution_count is not None):
            out.append(f"{name}: cell {i} has outputs or an execution count (run `tools/notebooks.py strip`)")
    if "widgets" in nb.metadata:
        out.append(f"{name}: widget state saved in the metadata")
    if not nb.cells or nb.cells[0].cell_type != "markdown" or "## Learning goals" not in nb.cells[0].source:
        out.append(f"{name}: the first cell must be markdown with '## Learning goals'")
    if not nb.cells or nb.cells[-1].cell_type != "markdown" or "## Exercises" not in nb.cells[-1].source:
        out.append(f"{name}: the last cell must be markdown with '## Exercises'")
    src = SOURCES / (path.stem + ".py")
    if not src.is_file():
        out.append(f"{name}: no source notebooks/src/{src.name}")
    elif dumps(from_source(src.read_text(encoding="utf-8"))) != path.read_text(encoding="utf-8"):
        out.append(f"{name}: differs from notebooks/src/{src.name} (run `tools/notebooks.py build`)")
    return out


def main(argv: list[str]) -> int:
    if not argv or argv[0] not in ("build", "strip", "check"):
        print(__doc__)
        return 2
    cmd, args = argv[0], argv[1:]
    if cmd == "build":
        sources = sorted(SOURCES.glob("*.py"))
        if args:
            sources = [s for s in sources if any(s.name.startswith(a) for a in args)]
        for src in sources:
            print(f"wrote {build_one(src).relative_to(ROOT)}")
        return 0
    if cmd == "strip":
        for name in args:
            p = Path(name)
            nb = strip(nbformat.read(p, as_version=4))
            p.write_text(dumps(nb), encoding="utf-8")
            print(f"stripped {p}")
        return 0
    found = [msg for p in sorted(NOTEBOOKS.glob("*.ipynb")) for msg in problems(p)]
    for msg in found:
        print(msg)
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

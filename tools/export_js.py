"""The JavaScript an exported notebook loads from public CDNs, installed with npm into the user cache.

``jupyter nbconvert --to html`` writes a page that loads, when opened:

* ``require.js`` (cdnjs), then the widget manager for HTML pages, ``@jupyter-widgets/html-manager``
  (``https://unpkg.com/@jupyter-widgets/html-manager@*/dist/embed-amd.js``);
* which loads each custom widget's front end by its ``model_module`` and version, here anywidget's
  (``https://cdn.jsdelivr.net/npm/anywidget@~0.11.*/dist/index.js``).

Online, a reader's browser fetches them from those CDNs. ``tests/viz/test_export_notebook.py`` opens an
exported notebook in chromium with no CDN reachable: Playwright answers those addresses from the
packages installed here (:func:`local_file`). Nothing goes into the repository or the wheel.

Run: ``make export-js`` (``make test`` runs it): installs into :func:`folder` once, with the anywidget
release that matches the Python package. Exit status 0 also when npm or the registry is unavailable
(a note says so; the test then skips with the reason).

``tools/docs.py`` (``make docs``) copies the same files into the gallery site, with MathJax
(:data:`DOCS_EXTRA`), so that the site loads nothing from a CDN.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

HTML_MANAGER = "1.0.15"  # @jupyter-widgets/html-manager for ipywidgets 8 (nbconvert asks for the latest, "@*")
REQUIREJS = "2.1.10"  # the require.js release nbconvert's template loads from cdnjs
DOCS_EXTRA = {"mathjax": "3.2.2"}  # the gallery's equations (tools/docs.py), typeset in the page


def folder() -> Path:
    """``$NLO_LAB_EXPORT_JS``, else ``export-js`` in the user cache (``$NLO_LAB_CACHE``, ``$XDG_CACHE_HOME/nlo_lab``, ``~/.cache/nlo_lab``)."""
    if os.environ.get("NLO_LAB_EXPORT_JS"):
        return Path(os.environ["NLO_LAB_EXPORT_JS"])
    cache = os.environ.get("NLO_LAB_CACHE") or str(Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "nlo_lab")
    return Path(cache) / "export-js"


def wanted(extra: dict[str, str] | None = None) -> dict[str, str]:
    """npm package -> version: anywidget's matches the Python package's (its widgets name that version); and ``extra``."""
    import anywidget

    return {"anywidget": anywidget.__version__, "@jupyter-widgets/html-manager": HTML_MANAGER, "requirejs": REQUIREJS, **(extra or {})}


def missing(extra: dict[str, str] | None = None) -> str | None:
    """Why the installed packages (with ``extra``) cannot serve an export here, or None."""
    modules = folder() / "node_modules"
    for name, version in wanted(extra).items():
        meta = modules / name / "package.json"
        if not meta.is_file():
            return f"{name}@{version} is not installed in {folder()} (run `make export-js`; it needs npm and the npm registry)"
        found = json.loads(meta.read_text(encoding="utf-8")).get("version")
        if found != version:
            return f"{name} {found} is installed in {folder()}, {version} is needed (run `make export-js`)"
    return None


def install(extra: dict[str, str] | None = None) -> str | None:
    """Install the packages (with ``extra``) with npm when they are missing; returns why that failed, or None."""
    if missing(extra) is None:
        return None
    npm = shutil.which("npm")
    if npm is None:
        return "npm is not installed"
    folder().mkdir(parents=True, exist_ok=True)
    specs = [f"{name}@{version}" for name, version in wanted(extra).items()]
    run = subprocess.run([npm, "install", "--no-save", "--no-audit", "--no-fund", "--ignore-scripts", "--prefix", str(folder()), *specs],
                         capture_output=True, text=True, timeout=600)
    if run.returncode != 0:
        return f"npm install {' '.join(specs)} failed: {run.stderr.strip()[-500:]}"
    return missing(extra)


_CDN = [
    # https://unpkg.com/NAME@VERSION/PATH and https://cdn.jsdelivr.net/npm/NAME@VERSION/PATH (NAME may be @scope/name)
    re.compile(r"^https://(?:unpkg\.com|cdn\.jsdelivr\.net/npm)/(?P<name>(?:@[^/@]+/)?[^/@]+)@[^/]*/(?P<path>[^?#]+)"),
]
_REQUIREJS = re.compile(r"^https://cdnjs\.cloudflare\.com/ajax/libs/require\.js/[^/]+/require(?:\.min)?\.js")


def local_file(url: str) -> Path | None:
    """The installed file that answers a CDN address of an exported page, or None (not one of ours)."""
    modules = folder() / "node_modules"
    if _REQUIREJS.match(url):
        return modules / "requirejs" / "require.js"
    for pattern in _CDN:
        m = pattern.match(url)
        if m and m.group("name") in wanted():
            path = (modules / m.group("name") / m.group("path")).resolve()
            if path.is_file() and (modules / m.group("name")).resolve() in path.parents:
                return path
    return None


def main() -> int:
    why = install(DOCS_EXTRA)  # the gallery's test builds a page with them too
    if why:
        print(f"note: the exported-notebook and gallery tests will be skipped: {why}")
    else:
        print(f"export JavaScript ready in {folder()}: " + ", ".join(f"{n}@{v}" for n, v in wanted(DOCS_EXTRA).items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Build the gallery: a static site of the executed notebooks, with the README, RESULTS and PAPER.

``make docs`` runs this. It stages the site's sources in ``build/docs/`` and builds ``site/``
with mkdocs and mkdocs-jupyter (``mkdocs.yml``; both in the ``docs`` extra):

1. ``README.md`` becomes the home page; ``docs/RESULTS.md`` (with its figures) and
   ``docs/PAPER.md`` (when the checkout has it) follow.
2. Every notebook runs (nbclient, as Jupyter would: the widgets' state is kept), in a scratch
   folder with ``NLO_LAB_WORK`` inside ``build/``; ``--quick`` runs them in test mode (short
   budgets, a few minutes in all; the pages then say "test mode on").
3. The JavaScript an exported notebook needs (require.js, the widget manager for HTML pages,
   anywidget's front end, MathJax for the equations) is copied from the npm packages
   ``tools/export_js.py`` installs into the user cache, so the site loads nothing from a CDN:
   it opens from ``file://`` without a network. meshcat's viewer travels inside each page's
   widget state. Every 3-D view shows its scene as it was when its cell ran; sliders and
   buttons need a kernel and do nothing in the site.

Usage::

    python tools/docs.py [--quick] [--only PREFIX ...] [--notebook FILE ...] [--stage DIR] [--site DIR]

Exit status 2 with one line on a missing tool, a failed notebook or a failed build.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
import export_js  # noqa: E402

JS = "js"  # the site's folder of JavaScript, beside the pages (every page sits at the top of the site)
# Files of each npm package the pages load: the widget manager also loads its fonts from its own folder.
JS_FILES = {
    "requirejs": ["require.js"],
    "@jupyter-widgets/html-manager": ["dist/embed-amd.js", "dist/*.woff2", "dist/*.woff", "dist/*.ttf", "dist/*.eot", "dist/*.svg"],
    "anywidget": ["dist/index.js"],
    "mathjax": ["es5/tex-chtml.js", "es5/output/chtml/fonts/woff-v2/*.woff"],
}

# Told to every page: anywidget's front end comes from the site (before the widget manager asks a CDN for it),
# and the controls' labels typeset with MathJax 2's call (MathJax.Hub.Queue), which the site's MathJax 3 answers.
WIDGETS_CONFIG = """// nlo_lab gallery: the widget manager finds anywidget's front end in the site, not on a CDN.
(function () {
  var here = document.currentScript.src.replace(/[^/]*$/, "");
  window.requirejs.config({ paths: { anywidget: here + "anywidget/dist/index" } });
  var mj = window.MathJax;
  if (mj && !mj.Hub) {  // ipywidgets' controls call MathJax.Hub.Queue(["Typeset", MathJax.Hub, element])
    mj.Hub = { Queue: function (job) {
      var element = job && job[2];
      var typeset = function () { return mj.typesetPromise ? mj.typesetPromise(element ? [element] : undefined) : null; };
      (mj.startup && mj.startup.promise ? mj.startup.promise.then(typeset) : Promise.resolve().then(typeset))
        .catch(function (err) { console.warn("MathJax:", err); });
    } };
  }
}());
"""


class BuildError(Exception):
    """The build cannot go on (the one line the command prints)."""


def stage_pages(stage: Path) -> list[str]:
    """README, RESULTS (and its figures) and PAPER into ``stage``; returns the staged page names."""
    pages = []
    for source, name in ((ROOT / "README.md", "index.md"), (ROOT / "docs" / "RESULTS.md", "RESULTS.md"),
                         (ROOT / "docs" / "PAPER.md", "PAPER.md")):
        if source.is_file():
            shutil.copy(source, stage / name)
            pages.append(name)
    if (ROOT / "docs" / "figures").is_dir():
        shutil.copytree(ROOT / "docs" / "figures", stage / "figures")
    return pages


def copy_js(stage: Path) -> list[str]:
    """The pages' JavaScript from the npm packages into ``stage/js``; returns the copied paths."""
    why = export_js.install(export_js.DOCS_EXTRA)
    if why:
        raise BuildError(f"the site's JavaScript is not available ({why}); it needs npm and the npm registry once")
    modules = export_js.folder() / "node_modules"
    copied = []
    for package, patterns in JS_FILES.items():
        for pattern in patterns:
            files = sorted((modules / package).glob(pattern))
            if not files:
                raise BuildError(f"no {pattern} in the npm package {package} ({modules / package})")
            for f in files:
                target = stage / JS / package / f.relative_to(modules / package)
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy(f, target)
                copied.append(target.relative_to(stage).as_posix())
    (stage / JS / "nlo_lab_widgets.js").write_text(WIDGETS_CONFIG, encoding="utf-8")
    return copied


def run_notebooks(sources: list[Path], stage: Path, scratch: Path, quick: bool) -> None:
    """Run each notebook as Jupyter would (widget state kept) and write it, with its outputs, into ``stage``."""
    import nbformat
    from nbclient.exceptions import CellExecutionError
    from notebook_client import notebook_client  # tools/: nbclient without its lost wake-ups

    env = {"NLO_LAB_WORK": str(scratch / "work"), "NLO_LAB_TEST_MODE": "1" if quick else "0"}
    saved = {k: os.environ.get(k) for k in env}
    os.environ.update(env)  # the kernels inherit this process's environment
    try:
        for source in sources:
            start = time.perf_counter()
            nb = nbformat.read(source, as_version=4)
            client = notebook_client(nb, timeout=1800, kernel_name="python3", store_widget_state=True,
                                    resources={"metadata": {"path": str(scratch)}})
            try:
                client.execute(stderr=subprocess.DEVNULL)  # the kernel's own start-up notes; a cell's errors are its outputs
            except CellExecutionError as exc:
                raise BuildError(f"{source.name} failed: {str(exc).strip().splitlines()[-1]}") from None
            nbformat.write(nb, stage / source.name)
            print(f"ran {source.name} in {time.perf_counter() - start:.0f} s", flush=True)
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def build_site(stage: Path, site: Path, config_dir: Path) -> None:
    """mkdocs build of ``stage`` into ``site`` (``mkdocs.yml``; nbconvert told where the widget manager is)."""
    config_dir.mkdir(parents=True, exist_ok=True)
    (config_dir / "jupyter_nbconvert_config.json").write_text(json.dumps({
        "HTMLExporter": {"widget_renderer_url": f"{JS}/@jupyter-widgets/html-manager/dist/embed-amd.js"},
    }), encoding="utf-8")
    env = {**os.environ, "JUPYTER_CONFIG_DIR": str(config_dir)}
    cmd = [sys.executable, "-m", "mkdocs", "build", "--quiet", "--config-file", str(ROOT / "mkdocs.yml"),
           "--site-dir", str(site.resolve())]
    env["NLO_LAB_DOCS_STAGE"] = str(stage.resolve())
    run = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    if run.returncode != 0:
        last = (run.stderr.strip() or run.stdout.strip() or "no message").splitlines()[-1]
        raise BuildError(f"mkdocs build failed: {last}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="tools/docs.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="run the notebooks in test mode (short budgets)")
    parser.add_argument("--only", nargs="+", default=None, metavar="PREFIX", help="only the notebooks whose name starts so")
    parser.add_argument("--notebook", nargs="+", type=Path, default=None, metavar="FILE", help="these notebooks instead")
    parser.add_argument("--stage", type=Path, default=ROOT / "build" / "docs", help="where the site's sources go (emptied)")
    parser.add_argument("--site", type=Path, default=ROOT / "site", help="the site (replaced)")
    args = parser.parse_args(argv)
    try:
        for module in ("mkdocs", "mkdocs_jupyter", "nbclient"):
            if __import__("importlib").util.find_spec(module) is None:
                raise BuildError(f"{module} is not installed: pip install -e '.[docs]' (make docs does)")
        sources = args.notebook or sorted((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
        if args.only:
            sources = [s for s in sources if s.name.startswith(tuple(args.only))]
        missing = [str(s) for s in sources if not s.is_file()]
        if not sources or missing:
            raise BuildError(f"no such notebook: {', '.join(missing)}" if missing else "no notebook selected")
        stage, scratch = args.stage, args.stage.with_name(args.stage.name + "-run")
        for folder in (stage, scratch):
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir(parents=True)
        pages = stage_pages(stage)
        copy_js(stage)
        run_notebooks([s.resolve() for s in sources], stage, scratch, args.quick)
        build_site(stage, args.site, scratch / "jupyter-config")
    except BuildError as exc:
        print(f"docs: error: {exc}", file=sys.stderr)
        return 2
    print(f"site: {args.site.resolve()}/index.html ({len(sources)} notebooks, {', '.join(pages)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())

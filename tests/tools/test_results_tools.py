"""`make results` (tools/results.py), the sections it writes (benchmarks/results_doc.py) and the quoted-figures check."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _load(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def tools():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        return (_load("results_doc", ROOT / "benchmarks" / "results_doc.py"), _load("nlo_results", ROOT / "tools" / "results.py"),
                _load("nlo_quoted_figures", ROOT / "tools" / "quoted_figures.py"))
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))


def test_sections_are_replaced_in_place_removed_and_stamped(tools, tmp_path, monkeypatch):
    results_doc = tools[0]
    out = tmp_path / "R.md"
    monkeypatch.setenv("NLO_LAB_RESULTS", str(out))
    assert results_doc.results_path() == out and results_doc.figures_dir() == tmp_path / "figures"
    results_doc.update_section("a", "first")
    results_doc.update_section("b", "second")
    results_doc.update_section("a", "first again")
    text = out.read_text()
    assert text.startswith("# nlo_lab results") and text.count("BEGIN a") == 1 and "first again" in text and "first\n" not in text
    assert results_doc.section_names() == ["a", "b"]
    assert results_doc.remove_section("a") and not results_doc.remove_section("a")
    assert results_doc.section_names() == ["b"]
    stamp = results_doc.stamp()
    assert re.search(r"- commit: `[0-9a-f]{10}", stamp), stamp
    assert re.search(r"- machine: .+, \d+ cores, ", stamp) and re.search(r"- load: \d+\.\d at the start, \d+\.\d at the end", stamp)
    assert re.search(r"- date: \d{4}-\d\d-\d\d \d\d:\d\d", stamp)


def _step_script(tmp_path: Path, name: str, fail: bool = False) -> Path:
    script = tmp_path / f"{name}.py"
    script.write_text(
        "import sys\n"
        f"sys.path.insert(0, {str(ROOT / 'benchmarks')!r})\n"
        "import results_doc\n"
        f"results_doc.update_section({name!r}, '## ' + {name!r} + '\\n\\n' + results_doc.stamp() + '\\nargs: ' + ' '.join(sys.argv[1:]))\n"
        f"sys.exit({1 if fail else 0})\n"
    )
    return script


@pytest.mark.slow
def test_the_runner_runs_each_step_resumes_and_reports_a_failure(tools, tmp_path, capsys, monkeypatch):
    _, results, _ = tools
    Step = results.Step
    steps = (
        Step("one", str(_step_script(tmp_path, "one")), "--full", "--short"),
        Step("broken", str(_step_script(tmp_path, "broken", fail=True)), "", ""),
        Step("full-only", str(_step_script(tmp_path, "full_only")), "", None),
    )
    out = tmp_path / "out" / "RESULTS.md"
    monkeypatch.chdir(tmp_path)
    assert results.run(["--quick", "--out", str(out)], steps) == 1  # one step failed; the others ran
    text = out.read_text()
    assert "args: --short" in text and "BEGIN full_only" not in text
    log = capsys.readouterr().out
    assert "[2/2] broken: FAILED (exit 1)" in log and "1 of 2 steps done" in log
    assert results.run(["--quick", "--out", str(out), "--only", "one"], steps) == 0
    assert "done with this code" in capsys.readouterr().out  # resumed: not run again
    assert results.run(["--quick", "--out", str(out), "--only", "one", "--force"], steps) == 0
    assert "done in" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="unknown step"):
        results.run(["--only", "nope"], steps)


def test_every_registered_step_exists_and_each_benchmark_writing_sections_is_registered(tools):
    _, results, _ = tools
    names = [s.name for s in results.STEPS]
    assert len(names) == len(set(names))
    for step in results.STEPS:
        assert (ROOT / step.script).is_file(), step.script
    registered = {s.script for s in results.STEPS}
    for script in sorted((ROOT / "benchmarks").glob("*.py")):
        if "update_section" in script.read_text() and script.name != "results_doc.py":
            assert f"benchmarks/{script.name}" in registered, f"{script.name} writes docs/RESULTS.md but make results does not run it"


@pytest.mark.slow
def test_a_quick_run_of_a_real_step_writes_its_stamped_section_elsewhere(tmp_path):
    """`make results QUICK=1` on the cheapest real step: the section lands in the quick file, docs/RESULTS.md is left alone."""
    out = tmp_path / "RESULTS.md"
    before = (ROOT / "docs" / "RESULTS.md").read_bytes()
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "tools/results.py", "--quick", "--only", "fk", "--out", str(out), "--force"], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    text = out.read_text()
    assert "<!-- BEGIN fk:yumi -->" in text and "- commit: `" in text and "- load: " in text
    assert (ROOT / "docs" / "RESULTS.md").read_bytes() == before


def test_quoted_figures_are_checked_against_the_named_sections(tools, tmp_path):
    quoted = tools[2]
    results = tmp_path / "R.md"
    results.write_text("<!-- BEGIN t:x -->\n| mean | 0.0582 | 24.6 % |\n<!-- END t:x -->\n")
    doc = tmp_path / "D.md"
    doc.write_text(
        "The method reaches 0.058 m, 24.6 % better (docs/RESULTS.md: t:x).\n\n"
        "- a list item quoting 0.0583 m (docs/RESULTS.md: t:x)\n"
        "- `smooth=0.5` in code is not a figure, nor is 1.25 here without a source\n\n"
        "Unknown section 0.1 (docs/RESULTS.md: t:y).\n\n"
        "A reference broken across lines still counts: 0.0591 m (docs/RESULTS.md:\nt:x).\n"
    )
    problems = quoted.check(doc, results)
    assert problems == ["D.md:3: 0.0583 is not shown in t:x", "D.md:6: no section t:y in R.md", "D.md:8: 0.0591 is not shown in t:x"], problems


def test_the_readmes_results_section_quotes_no_figure_without_its_source(tools, tmp_path):
    quoted = tools[2]
    results = tmp_path / "R.md"
    results.write_text("<!-- BEGIN t:x -->\n| mean | 0.0582 |\n<!-- END t:x -->\n")
    doc = tmp_path / "README.md"
    doc.write_text("# x\n\nA limit of 0.35 rad.\n\n## Results in one glance\n\n- 0.058 m (docs/RESULTS.md: t:x)\n"
                   "- 1.93 s, typed from memory\n\n## Layout\n\nVersion 0.5 here.\n")
    assert quoted.check(doc, results) == ["README.md:8: 1.93 has no source (docs/RESULTS.md: SECTION)"]


def test_the_readme_and_paper_quote_only_figures_that_results_shows(tools):
    quoted = tools[2]
    problems = [p for doc in quoted.DOCS for p in quoted.check(doc)]
    assert not problems, "\n".join(problems)


@pytest.mark.slow
def test_a_quick_run_of_the_paper_benchmark_trains_every_configuration_and_writes_its_sections(tmp_path):
    """benchmarks/paper.py --quick: Table II's four activations and the auto-decoder on NAO, a few steps each."""
    out = tmp_path / "RESULTS.md"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NLO_LAB_RESULTS": str(out), "NLO_LAB_CACHE": str(tmp_path / "cache"), "TQDM_DISABLE": "1"}
    r = subprocess.run([sys.executable, "benchmarks/paper.py", "--robots", "nao", "--quick", "--parts", "table2,autodecoder"], cwd=ROOT,
                       env=env, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    text = out.read_text()
    assert "| sequence | Sigmoid | Tanh | ReLU | LeakyReLU |" in text
    assert "| auto-decoder (Eq. autodecoder) | zeros |" in text and "| encoder + decoder (Eq. 10, today's) | encoder |" in text
    models = sorted(p.name.split("-")[1:3] for p in (tmp_path / "cache" / "results" / "models").glob("nao-*.pt"))
    assert models == [["autodecoder", "leaky_relu"], ["encoder", "leaky_relu"], ["encoder", "relu"], ["encoder", "sigmoid"], ["encoder", "tanh"]]
    again = subprocess.run([sys.executable, "benchmarks/paper.py", "--robots", "nao", "--quick", "--parts", "autodecoder", "--no-write"], cwd=ROOT,
                           env=env, capture_output=True, text=True, timeout=900)
    assert again.returncode == 0 and again.stderr.count(": cached (") == 2 and "training nao" not in again.stderr  # resumed from the cache


def test_the_check_names_sections_without_a_full_stamp_and_text_outside_the_sections(tools, tmp_path, capsys):
    results_doc, results, _ = tools
    out = tmp_path / "R.md"
    out.write_text(
        "# nlo_lab results\n\nThe header.\n\n"
        f"<!-- BEGIN good -->\n## Good\n\n{results_doc.stamp()}\n| a | 1.0 |\n<!-- END good -->\n\n"
        "<!-- BEGIN old -->\n## Old\n\n- command: `x`\n- machine: AMD EPYC, 2 cores\n- date: 2026-11-23 16:43 UTC\n<!-- END old -->\n\n"
        "A note typed by hand: 1.54x.\n"
    )
    problems = results.check(out)
    assert problems == ["section old: no commit in its stamp (run its step again)",
                        "1 line(s) outside the sections after old: 'A note typed by hand: 1.54x.'... (no step writes them)"], problems
    assert results.run(["--check", "--out", str(out)]) == 1
    assert "results check: section old" in capsys.readouterr().out
    out.write_text(out.read_text().split("<!-- BEGIN old")[0])
    assert results.check(out) == [] and results.run(["--check", "--out", str(out)]) == 0


def test_draft_figures_keep_a_no_write_run_out_of_the_docs(tools, monkeypatch):
    results_doc = tools[0]
    monkeypatch.delenv("NLO_LAB_RESULTS", raising=False)
    monkeypatch.setattr(results_doc, "_DRAFT_FIGURES", None)
    assert results_doc.figure_path("x.png").parent == ROOT / "docs" / "figures"
    folder = results_doc.draft_figures()
    path = results_doc.figure_path("x.png")
    assert path.parent == folder and folder.is_dir() and ROOT / "docs" not in path.parents


def test_quality_no_write_names_its_draft_figures_folder():
    """The command a developer runs to check numbers: --no-write says where its plots went (not docs/figures)."""
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "quality.py"), "--robot", "nao", "--skip", "table1,init,table3",
                          "--no-write"], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert run.returncode == 0, run.stderr[-2000:]
    folder = re.search(r"figures of this run \(not the docs'\): (\S+)", run.stderr)
    assert folder and Path(folder.group(1)).is_dir() and Path(folder.group(1)).resolve() != (ROOT / "docs" / "figures").resolve()

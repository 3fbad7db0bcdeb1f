"""``import nlo_lab``: the front door gives the names a first retargeting needs, imports nothing heavy,
and the README's three-line example runs as written."""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

import nlo_lab

ROOT = Path(__file__).resolve().parents[2]


def test_import_nlo_lab_imports_neither_torch_nor_numpy():
    code = "import sys, nlo_lab; print(sorted(m for m in ('torch', 'numpy', 'nlo_lab.robot', 'nlo_lab.inference') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("name", nlo_lab.__all__)
def test_each_name_is_its_homes_object(name):
    home = importlib.import_module(nlo_lab._HOMES[name])
    assert getattr(nlo_lab, name) is getattr(home, name)
    assert name in dir(nlo_lab)


def test_the_issue_s_names_are_there():
    from nlo_lab import errors

    wanted = {"load_robot", "load_demonstration", "retarget", "RetargetConfig", "RobotTrajectory"}
    wanted |= {n for n in errors.__all__ if isinstance(getattr(errors, n), type) and issubclass(getattr(errors, n), BaseException)}
    assert wanted <= set(nlo_lab.__all__), wanted - set(nlo_lab.__all__)


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="has no attribute 'retargett'"):
        nlo_lab.retargett  # noqa: B018


def test_load_demonstration_takes_a_file_or_demo_name(tmp_path):
    from nlo_lab.corpus import corpus_clip, corpus_names
    from nlo_lab.human import save_npz

    name = corpus_names("test")[0]
    demo = nlo_lab.load_demonstration(f"demo:{name}")
    assert demo.name == corpus_clip(name).name and len(demo) == len(corpus_clip(name))
    path = save_npz(demo, tmp_path / "clip.npz")
    again = nlo_lab.load_demonstration(path)
    assert len(again) == len(demo)
    with pytest.raises(nlo_lab.DemonstrationError, match="no_such_clip"):
        nlo_lab.load_demonstration("demo:no_such_clip")


@pytest.mark.slow
def test_the_readme_example_runs_as_written(tmp_path):
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    section = readme[readme.index("### Library"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    assert code.count("\n") == 3 and code.startswith("import nlo_lab\n"), code  # three lines
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert out.returncode == 0, out.stderr
    rows = (tmp_path / "nao.csv").read_text(encoding="utf-8").splitlines()
    assert rows[0].split(",") == ["time_s", *nlo_lab.load_robot("nao").joint_names]
    assert len(rows) == 1 + len(nlo_lab.load_demonstration("demo:introduction_06"))

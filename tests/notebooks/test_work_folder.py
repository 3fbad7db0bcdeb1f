"""The notebooks write only into a work folder (nlo_lab.lab.work_folder), which git ignores in a clone."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from nlo_lab.errors import NloLabError
from nlo_lab.lab import WORK_ENV, work_folder

ROOT = Path(__file__).resolve().parents[2]
WRITERS = ("08", "09")  # the notebooks that write files (exports, an uploaded video)


def test_the_work_folder_is_beside_the_notebook_unless_the_variable_says(tmp_path, monkeypatch):
    monkeypatch.delenv(WORK_ENV, raising=False)
    monkeypatch.chdir(tmp_path)
    assert work_folder("retargeted") == Path("nlo_lab_work/retargeted") and (tmp_path / "nlo_lab_work/retargeted").is_dir()
    monkeypatch.setenv(WORK_ENV, str(tmp_path / "elsewhere"))
    assert work_folder() == tmp_path / "elsewhere" and work_folder("x").is_dir()
    for bad in ("../up", "a/b", ".."):
        with pytest.raises(NloLabError, match="one plain folder name"):
            work_folder(bad)
    (tmp_path / "file").write_text("")
    monkeypatch.setenv(WORK_ENV, str(tmp_path / "file"))
    with pytest.raises(NloLabError, match="cannot create the work folder"):
        work_folder("x")


def test_the_notebooks_write_through_the_work_folder_only():
    for name in WRITERS:
        (src,) = (ROOT / "notebooks" / "src").glob(f"{name}_*.py")
        text = src.read_text(encoding="utf-8")
        assert "work_folder(" in text and "mkdtemp" not in text, src.name


@pytest.mark.slow
def test_running_the_notebooks_in_a_clone_leaves_git_status_clean(tmp_path, monkeypatch, run_notebook):
    """A clone of this repository with the working tree's notebooks and .gitignore (committed there), the writing
    notebooks run in it as a learner would (test mode, no NLO_LAB_WORK): they wrote their files, git sees none."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs git and a git checkout")
    clone = tmp_path / "clone"
    git = lambda *args: subprocess.run(["git", "-C", str(clone), *args], check=True, capture_output=True, text=True).stdout  # noqa: E731
    subprocess.run(["git", "clone", "--quiet", str(ROOT), str(clone)], check=True)
    shutil.copy(ROOT / ".gitignore", clone / ".gitignore")
    shutil.rmtree(clone / "notebooks")
    shutil.copytree(ROOT / "notebooks", clone / "notebooks", ignore=shutil.ignore_patterns("nlo_lab_work", ".ipynb_checkpoints"))
    git("add", "-A")
    git("-c", "user.name=test", "-c", "user.email=test@example.org", "commit", "--quiet", "--allow-empty", "-m", "working tree")
    monkeypatch.setenv("NLO_LAB_TEST_MODE", "1")
    monkeypatch.delenv(WORK_ENV, raising=False)
    for name in WRITERS:
        (path,) = (clone / "notebooks").glob(f"{name}_*.ipynb")
        run_notebook(path, path.parent)
    written = sorted(p.relative_to(clone).as_posix() for p in (clone / "notebooks" / "nlo_lab_work").rglob("*") if p.is_file())
    assert "notebooks/nlo_lab_work/retargeted/viewer.html" in written, written
    assert "notebooks/nlo_lab_work/my_video/retargeted/trajectory.csv" in written, written
    assert git("status", "--porcelain", "--untracked-files=all") == ""

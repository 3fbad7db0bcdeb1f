"""Issue 25 for ``nlo-lab batch``: the output folder is checked before any input is read, and the
library's worker count has the flag's upper bound (no cluster is ever started by these cases)."""

from __future__ import annotations

import os

import pytest

from nlo_lab.batch import retarget_many
from nlo_lab.cli import main
from nlo_lab.errors import OutputError, SettingsError


@pytest.fixture
def no_input_read(monkeypatch):
    import nlo_lab.batch.engine as engine

    monkeypatch.setattr(engine, "find_inputs", lambda *a, **k: pytest.fail("an input was read before the output folder was checked"))


@pytest.mark.parametrize(("out", "match"), [("", "must be a non-empty path"), ("a-file", "exists and is not a folder"),
                                            ("a-file/below", "lies below"), ("\x00", "non-empty path")])
def test_a_bad_output_folder_is_refused_before_any_input(out, match, tmp_path, monkeypatch, no_input_read):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a-file").write_text("x")
    with pytest.raises(OutputError, match=match):
        retarget_many(["clip.npz"], "nao", out)
    assert sorted(os.listdir(tmp_path)) == ["a-file"]


def test_an_empty_out_on_the_command_line_is_one_line(tmp_path, monkeypatch, capsys, no_input_read):
    monkeypatch.chdir(tmp_path)
    assert main(["batch", "clip.npz", "--robot", "nao", "--out", ""]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.strip() == "nlo-lab: error: the output folder must be a non-empty path, got ''"
    assert os.listdir(tmp_path) == []


def test_a_folder_we_may_not_write_in_is_refused(tmp_path, monkeypatch, no_input_read):
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if str(p) == str(tmp_path) else real(p, mode, **kw))
    with pytest.raises(OutputError, match=f"no permission to write in {tmp_path}"):
        retarget_many(["clip.npz"], "nao", tmp_path / "out")


@pytest.mark.parametrize("workers", [0, 1025, 10**9, 2.0, "2", True])
def test_the_library_bounds_the_worker_count(workers, tmp_path, no_input_read):
    with pytest.raises(SettingsError, match="workers"):
        retarget_many(["clip.npz"], "nao", tmp_path / "out", workers=workers)
    assert not (tmp_path / "out").exists()

"""The batch's inputs (files, folders, manifests), their output folders, and the settings' fingerprint: no cluster."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest

from nlo_lab.batch import BatchSettings, InputError, find_inputs, robot_files
from nlo_lab.batch.table import COLUMNS, ResultsTable, failed_row, read_rows
from nlo_lab.paths import CHECKPOINTS_DIR, RECORDINGS_DIR, ROBOTS_DIR

POSE = RECORDINGS_DIR / "holistic_both_hands_47f.pose"


def _touch(path: Path, text: str = "x") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def _names(items):
    return [(str(i.path), i.name) for i in items]


def test_folders_are_searched_recursively_for_the_known_suffixes(tmp_path):
    for rel in ("a.pose", "b/c.NPZ", "b/d/e.mp4", "f.h5", "g.txt", "h.json", ".hidden.pose", ".cache/i.pose", "j.webm"):
        _touch(tmp_path / "in" / rel)
    items = find_inputs([tmp_path / "in"])
    assert [i.name for i in items] == ["a", "f", "j", "b/c", "b/d/e"]  # each folder's files, then its sub-folders, sorted
    assert [i.is_video for i in items] == [False, False, True, False, True]


def test_the_output_folder_is_never_searched(tmp_path):
    _touch(tmp_path / "in" / "a.pose")
    _touch(tmp_path / "in" / "out" / "a" / "trajectory.npz")
    assert [i.name for i in find_inputs([tmp_path / "in"], out=tmp_path / "in" / "out")] == ["a"]


def test_a_manifest_names_paths_relative_to_its_own_folder(tmp_path, monkeypatch):
    _touch(tmp_path / "corpus" / "x" / "one.pose")
    _touch(tmp_path / "corpus" / "y" / "two.npz")
    _touch(tmp_path / "elsewhere" / "three.h5")
    manifest = _touch(tmp_path / "corpus" / "lists" / "run.txt",
                      f"# a comment\n\n../x/one.pose\n  ../y/two.npz  \n{tmp_path / 'elsewhere' / 'three.h5'}\n../missing.pose\n")
    monkeypatch.chdir(tmp_path / "elsewhere")  # the working folder does not matter
    items = find_inputs([manifest])
    assert [i.path.resolve() for i in items] == [
        (tmp_path / p).resolve() for p in ("corpus/x/one.pose", "corpus/y/two.npz", "elsewhere/three.h5", "corpus/missing.pose")
    ]
    assert [i.name for i in items] == ["corpus/x/one", "corpus/y/two", "elsewhere/three", "corpus/missing"]


def test_the_same_file_given_twice_is_one_input(tmp_path, monkeypatch):
    f = _touch(tmp_path / "a.pose")
    monkeypatch.chdir(tmp_path)
    assert len(find_inputs([f, "a.pose", tmp_path])) == 1


@pytest.mark.parametrize("layout, needle", [
    (["a.pose", "a.npz"], "would both write the output folder 'a'"),
    (["x.pose", "x/y.pose"], "would hold the folder 'x/y'"),
    (["results.csv.pose"], "would both write the output folder 'results.csv'"),
])
def test_two_inputs_for_one_output_folder_are_refused(tmp_path, layout, needle):
    for rel in layout:
        _touch(tmp_path / rel)
    with pytest.raises(InputError) as info:
        find_inputs([tmp_path / rel for rel in layout])
    assert needle in str(info.value)


def test_missing_inputs_and_empty_folders_are_errors(tmp_path):
    with pytest.raises(InputError, match="input not found: .*nope.pose"):
        find_inputs([tmp_path / "nope.pose"])
    (tmp_path / "empty").mkdir()
    _touch(tmp_path / "empty" / "notes.md")
    with pytest.raises(InputError, match="no inputs in folder"):
        find_inputs([tmp_path / "empty"])
    nested = _touch(tmp_path / "m.txt", "other.txt\n")
    with pytest.raises(InputError, match="line 1: a manifest may not name another manifest"):
        find_inputs([nested])


def test_the_fingerprint_follows_the_settings_and_the_robots_files(tmp_path):
    base = BatchSettings("yumi")
    assert base.fingerprint() == BatchSettings("yumi", weights="").fingerprint()
    assert base.fingerprint() == BatchSettings(str(ROBOTS_DIR / "yumi.json")).fingerprint()  # one robot, two names
    assert BatchSettings("yumi", weights="ori=5, ee=3").fingerprint() == BatchSettings("yumi", weights={"ee": 3, "ori": 5}).fingerprint()
    assert BatchSettings("yumi", viewer=True).fingerprint() == base.fingerprint()  # a viewer changes no result
    different = [BatchSettings("nao"), BatchSettings("yumi", iterations=99), BatchSettings("yumi", init="zeros"),
                 BatchSettings("yumi", seed=1), BatchSettings("yumi", weights="ee=3"), BatchSettings("yumi", hand_search=("ring",))]
    assert "hand_search" not in base.key() and base.hand_search is None  # without it, the fingerprints of earlier batches hold
    different.append(BatchSettings("yumi", hand_search=()))  # no search: not the default's
    assert BatchSettings("yumi", hand_search=()).key()["hand_search"] == []
    assert len({s.fingerprint() for s in different} | {base.fingerprint()}) == len(different) + 1
    # a copy of the spec whose checkpoint differs: another robot
    assert [f.name for f in robot_files("yumi")] == ["yumi.json", "yumi.urdf", "yumi.pt"]
    assert robot_files("yumi")[2] == CHECKPOINTS_DIR / "yumi.pt"
    spec = tmp_path / "robot" / "yumi.json"
    shutil.copytree(ROBOTS_DIR, spec.parent)
    assert BatchSettings(str(spec)).fingerprint() == base.fingerprint()
    (spec.parent / "yumi.urdf").write_text((spec.parent / "yumi.urdf").read_text() + "\n<!-- edited -->\n")
    assert BatchSettings(str(spec)).fingerprint() != base.fingerprint()


def test_the_fingerprint_needs_no_torch(tmp_path):
    import subprocess

    code = ("import sys; from nlo_lab.batch import BatchSettings, find_inputs; BatchSettings('yumi').fingerprint(); "
            f"find_inputs([{str(POSE)!r}]); assert 'torch' not in sys.modules and 'distributed' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_the_table_round_trips_and_only_holds_finished_rows(tmp_path):
    table = ResultsTable(tmp_path / "results.csv", ["a", "b", "c"], interval=3600)
    table.set(failed_row("/x/c.pose", "c", 'bad "quote", comma\nand newline', input_sha256="ab", settings="cd"))
    assert (tmp_path / "results.csv").is_file()  # the first row is written at once
    table.set({**dict.fromkeys(COLUMNS), "input": "/x/a.pose", "output": "a", "status": "ok", "frames": 47, "frechet_m": 0.125,
               "seconds": float("nan"), "hand_frames": 40, "wrist_tip_deg": 15.5})
    assert len(read_rows(tmp_path / "results.csv")) == 1  # throttled: not yet written
    table.flush()
    rows = read_rows(tmp_path / "results.csv")
    assert list(rows) == ["a", "c"]  # the inputs' order
    assert rows["a"]["frames"] == 47 and rows["a"]["frechet_m"] == 0.125 and rows["a"]["seconds"] is None
    assert rows["a"]["hand_frames"] == 40 and rows["a"]["wrist_tip_deg"] == 15.5 and rows["a"]["pinch_r"] is None
    assert rows["c"]["error"] == 'bad "quote", comma\nand newline' and rows["c"]["status"] == "failed"
    assert (tmp_path / "results.csv").read_text().splitlines()[0] == ",".join(COLUMNS)
    (tmp_path / "other.csv").write_text("name,value\n1,2\n")
    assert read_rows(tmp_path / "other.csv") == {}


def test_batch_handshape_runs_the_preset_and_its_search(monkeypatch, capsys):
    """``batch --handshape`` hands the preset's weights (``--weights`` on top) and fingers to the batch, and the settings
    build a retargeter whose hand stage searches them."""
    import nlo_lab.batch as batch_mod
    from nlo_lab.cli import main as cli_main
    from nlo_lab.settings import HANDSHAPE_SEARCH, HANDSHAPE_SLOWDOWN, HANDSHAPE_WEIGHTS

    seen = {}
    monkeypatch.setattr(batch_mod, "retarget_many", lambda inputs, robot, out, **kw: seen.update(kw) or [])
    assert cli_main(["batch", str(POSE), "--robot", "yumi", "--out", "out", "--handshape", "--weights", "thumb=600"]) == 0
    assert seen["weights"] == {**HANDSHAPE_WEIGHTS, "thumb": 600.0} and seen["hand_search"] == HANDSHAPE_SEARCH
    assert seen["hand_slowdown"] == HANDSHAPE_SLOWDOWN
    assert cli_main(["batch", str(POSE), "--robot", "yumi", "--out", "out", "--hand-search", "ring", "--hand-slowdown", "2"]) == 0
    assert seen["weights"] is None and seen["hand_search"] == ("ring",) and seen["hand_slowdown"] == 2.0
    settings = BatchSettings("yumi", weights=seen["weights"], hand_search=seen["hand_search"], hand_slowdown=seen["hand_slowdown"])
    assert settings.build().config.settings.hand_search == ("ring",)
    assert settings.build().config.settings.hand_slowdown == 2.0


def test_batch_hand_slowdown_is_checked_in_the_client_and_fingerprinted_only_when_not_1():
    from nlo_lab.errors import SettingsError

    with pytest.raises(SettingsError, match="hand_slowdown"):
        BatchSettings("yumi", hand_slowdown=0.5)
    plain = BatchSettings("yumi")
    assert "hand_slowdown" not in plain.key()  # a batch without it keeps the fingerprint it had
    assert BatchSettings("yumi", hand_slowdown=1.0).fingerprint() == plain.fingerprint()
    assert BatchSettings("yumi", hand_slowdown=1.7).key()["hand_slowdown"] == 1.7
    assert BatchSettings("yumi", hand_slowdown=1.7).fingerprint() != plain.fingerprint()


def test_the_tables_hand_columns_are_the_summarys_hand_keys(tmp_path):
    """``results.csv``'s hand columns (spelt out in the table: the metrics import torch) are the summary's, carried
    from an input's ``summary.json``; a table of an earlier version, without them, still resumes."""
    from nlo_lab.batch.table import HANDS, row_from_summary
    from nlo_lab.metrics import HAND_KEYS

    assert HANDS == HAND_KEYS and COLUMNS[-len(HANDS):] == HANDS
    summary = {"frames": 47, "seconds": 1.5, "frechet_m": 0.1, "hand_frames": 30, "wrist_tip_deg": 16.0, "thumb_tips_deg": 25.0,
               "base_tip_deg": 31.0, "pinch_r": 0.8, "batch": {"input": "/x/a.pose", "output": "a", "seconds": 2.0}}
    row = row_from_summary(summary)
    assert {k: row[k] for k in HANDS} == {k: summary[k] for k in HANDS}
    old = COLUMNS[:-len(HANDS)]
    (tmp_path / "results.csv").write_text(",".join(old) + "\n" + ",".join("a" if c == "output" else "ok" if c == "status" else ""
                                                                        for c in old) + "\n")
    rows = read_rows(tmp_path / "results.csv")
    assert list(rows) == ["a"] and all(rows["a"][k] is None for k in HANDS)

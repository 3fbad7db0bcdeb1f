"""Dependencies run one way along the data's path (docs/ARCHITECTURE.md, "The order"): every module of
nlo_lab belongs to a stage of ``ORDER`` and imports only from its own stage or earlier ones, not even
inside a function; no modules import each other in a circle; and the picture of docs/ARCHITECTURE.md
is the code's. ``tools/architecture.py`` holds the order and reads the imports with ast."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def arch(checkout_script):
    return checkout_script("tools/architecture.py")


def test_every_module_has_a_stage(arch):
    lost = sorted(m for m in arch.modules() if arch.stage(m) < 0)
    assert not lost, f"place these in tools/architecture.py's ORDER (and in docs/ARCHITECTURE.md): {lost}"


def test_nothing_imports_a_later_stage(arch):
    found = arch.backward_imports()
    assert not found, "imports against the data's path (move the code or the import):\n" + "\n".join(map(str, found))


def test_no_modules_import_each_other_in_a_circle(arch):
    assert arch.cycles() == []


def test_the_front_door_is_seen_importing_its_homes(arch):
    import nlo_lab

    graph = arch.import_graph()
    assert set(nlo_lab._HOMES.values()) <= graph["nlo_lab"]


def test_the_picture_in_the_docs_is_the_codes(arch):
    text = (ROOT / "docs" / "ARCHITECTURE.md").read_text(encoding="utf-8")
    assert arch.current_picture(text) == arch.diagram(), "stale: run `python tools/architecture.py`"


def test_the_checks_see_what_they_look_for(arch, tmp_path):
    """An import inside a function, a relative import, a later stage, the front door and a circle are all found."""
    fake = tmp_path / "nlo_lab"
    for folder in ("model", "lab", "training", "human", "evaluation", "cli"):
        (fake / folder).mkdir(parents=True)
        (fake / folder / "__init__.py").write_text("", encoding="utf-8")
    (fake / "__init__.py").write_text("", encoding="utf-8")
    (fake / "model" / "checkpoint.py").write_text("def f():\n    from nlo_lab.training import train_model\n", encoding="utf-8")
    (fake / "lab" / "cells.py").write_text("from ..evaluation import evaluate\nimport nlo_lab.cli\n", encoding="utf-8")
    (fake / "training" / "run.py").write_text("if __name__ == '__main__':\n    from nlo_lab.cli import main\n", encoding="utf-8")
    (fake / "human" / "a.py").write_text("from nlo_lab.human import b\n", encoding="utf-8")
    (fake / "human" / "b.py").write_text("def g():\n    from . import a\n", encoding="utf-8")
    (fake / "human" / "c.py").write_text("import nlo_lab\nv = nlo_lab.__version__\n", encoding="utf-8")  # allowed
    (fake / "human" / "d.py").write_text("import nlo_lab\nf = nlo_lab.retarget\n", encoding="utf-8")  # the front door: not
    assert arch.backward_imports(fake) == [
        ("nlo_lab.human.d", "nlo_lab"),
        ("nlo_lab.lab.cells", "nlo_lab.cli"),
        ("nlo_lab.model.checkpoint", "nlo_lab.training"),
    ]
    assert arch.cycles(fake) == [["nlo_lab.human.a", "nlo_lab.human.b"]]


@pytest.mark.parametrize("module, before, after", [
    ("nlo_lab.training.train", "nlo_lab.inference.latent", "nlo_lab.evaluation.scores"),
    ("nlo_lab.metrics", "nlo_lab.inference.retime", "nlo_lab.evaluation.scores"),
    ("nlo_lab.robot.speeds", "nlo_lab.human.demonstration", "nlo_lab.inference.retime"),
    ("nlo_lab.pipeline", "nlo_lab.metrics", "nlo_lab.evaluation.methods"),
    ("nlo_lab.corpus.body", "nlo_lab.human.demonstration", "nlo_lab.sources"),
    ("nlo_lab", "nlo_lab.batch", "nlo_lab.cli.app"),
])
def test_stages(arch, module, before, after):
    assert arch.stage(before) < arch.stage(module) < arch.stage(after)


def test_the_program_is_the_command_lines(arch):
    assert arch.stage("nlo_lab.__main__") == arch.stage("nlo_lab.cli.program") > arch.stage("nlo_lab")

"""``checkpoint=`` (library) and ``--checkpoint`` (retarget, evaluate): a trained file instead of the shipped one.

A robot drafted from its URDF has no shipped checkpoint: its user trains one (``nlo-lab train --robot SPEC
--out CKPT.pt``) and gives it. Here NAO's shipped model with its weights moved stands for such a file, so
that the file's model and the shipped one give different answers: the file must be the one used.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from nlo_lab.cli import main
from nlo_lab.errors import CheckpointError, SettingsError
from nlo_lab.evaluation import evaluate_split
from nlo_lab.inference import OptimizeSettings
from nlo_lab.model import load_pretrained, save_checkpoint
from nlo_lab.paths import RECORDINGS_DIR
from nlo_lab.pipeline import RetargetConfig, retarget
from nlo_lab.robot import load_robot

SETTINGS = OptimizeSettings(iterations=3)


@pytest.fixture(scope="module")
def nao():
    return load_robot("nao")


@pytest.fixture(scope="module")
def moved(nao, tmp_path_factory):
    """(model, file): NAO's shipped model with every weight moved a little, saved as a checkpoint."""
    model = load_pretrained(nao)
    generator = torch.Generator().manual_seed(0)
    with torch.no_grad():
        for p in model.parameters():
            p.add_(0.05 * torch.randn(p.shape, generator=generator, dtype=p.dtype))
    path = tmp_path_factory.mktemp("ckpt") / "nao_moved.pt"
    save_checkpoint(model, path, nao)
    return model, path


def test_retarget_uses_the_checkpoint_file(nao, moved, make_demo):
    model, path = moved
    demo = make_demo(T=6)
    from_file = retarget(demo, nao, checkpoint=path, settings=SETTINGS).trajectory.angles
    from_model = retarget(demo, nao, model=model, settings=SETTINGS).trajectory.angles
    shipped = retarget(demo, nao, settings=SETTINGS).trajectory.angles
    np.testing.assert_allclose(from_file, from_model, atol=1e-6)
    assert np.abs(from_file - shipped).max() > 1e-3


def test_a_model_and_a_checkpoint_together_or_another_robots_checkpoint_are_refused(nao, moved):
    model, path = moved
    with pytest.raises(SettingsError, match="not both"):
        RetargetConfig(nao, model=model, checkpoint=path).build()
    with pytest.raises(CheckpointError, match="nao"):
        load_pretrained(load_robot("pepper"), path)


def test_the_command_line_retarget_and_evaluate_take_the_file(nao, moved, tmp_path, capsys, assert_one_line_error):
    _, path = moved
    code = main(["retarget", str(RECORDINGS_DIR / "holistic_both_hands_47f.pose"), "--robot", "nao", "--checkpoint", str(tmp_path / "gone.pt"), "--out", str(tmp_path / "out")])
    assert_one_line_error(code, capsys.readouterr().err, "gone.pt")
    assert not (tmp_path / "out").exists()

    def encoder_only(*extra):
        code = main(["evaluate", "--robot", "nao", "--methods", "encoder_only", "--limit", "2", "--json", "--quiet", *extra])
        assert code == 0
        return json.loads(capsys.readouterr().out.strip().splitlines()[-1])["methods"]["encoder_only"]["per_sequence"]

    from_file = encoder_only("--checkpoint", str(path))
    library = evaluate_split(nao, limit=2, methods=("encoder_only",), progress=False, model=moved[0]).scores["encoder_only"]
    assert from_file == pytest.approx({s: v.frechet_m for s, v in library.items()}, abs=1e-4)
    assert from_file != pytest.approx(encoder_only(), abs=1e-4)

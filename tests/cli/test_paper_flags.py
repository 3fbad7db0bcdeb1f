"""The paper's options on the command line: `train --activation/--mode/--max-steps`, `evaluate --mode`, `retarget --sigma`."""

from __future__ import annotations

import json

import pytest

import nlo_lab.evaluation.scores as scores
import nlo_lab.training.train as training_mod
from nlo_lab.cli import main as cli_main
from nlo_lab.model import load_checkpoint
from nlo_lab.settings import HANDSHAPE_SLOWDOWN


@pytest.mark.slow
def test_train_takes_the_activation_the_mode_and_a_budget_of_steps(tmp_path, monkeypatch, nao, capsys, demonstration_from_robot,
                                                                   random_feasible_pose):
    fit = [demonstration_from_robot(nao, random_feasible_pose(nao, 24, seed=41))]
    val = [demonstration_from_robot(nao, random_feasible_pose(nao, 8, seed=42))]
    monkeypatch.setattr(training_mod, "train_validation_split", lambda seed=0: (fit, val))
    out = tmp_path / "ad.pt"
    argv = ["train", "--robot", "nao", "--activation", "tanh", "--mode", "autodecoder", "--max-steps", "3", "--batch-size", "8",
            "--out", str(out), "--quiet"]
    assert cli_main(argv) == 0
    printed = capsys.readouterr().out
    assert "trained nao: 3 steps" in printed and "no encoder" in printed
    model = load_checkpoint(out, nao)
    assert model.config["activation"] == "tanh" and not model.has_encoder
    s = model.train_info["train_settings"]
    assert (s["activation"], s["mode"], s["max_steps"]) == ("tanh", "autodecoder", 3)


@pytest.mark.parametrize("flag, value", [("--activation", "swish"), ("--mode", "vae"), ("--max-steps", "0")])
def test_bad_paper_flags_of_train_are_one_line_exit_2(flag, value, capsys):
    assert cli_main(["train", "--robot", "nao", flag, value]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and flag in err and "Traceback" not in err


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["paper", "robot-ready"])
def test_evaluate_runs_in_the_mode_asked(mode, monkeypatch, capsys):
    seen = []
    real = scores.run_method

    def spy(name, robot, demo, settings, **k):
        seen.append(settings.mode)
        return real(name, robot, demo, settings, **k)

    monkeypatch.setattr(scores, "run_method", spy)
    assert cli_main(["evaluate", "--robot", "nao", "--json", "--limit", "1", "--methods", "ik", "--mode", mode, "--quiet"]) == 0
    assert seen == [mode] and "ik" in json.loads(capsys.readouterr().out.strip().splitlines()[-1])["methods"]


def test_retarget_sigma_is_the_standard_deviation_of_the_random_start(capsys):
    def frechet(*extra):
        assert cli_main(["retarget", "demo:introduction_06", "--robot", "nao", "--iters", "0", "--json", "--quiet", *extra]) == 0
        return json.loads(capsys.readouterr().out.strip().splitlines()[-1])["frechet_m"]

    zeros = frechet("--init", "zeros")
    assert frechet("--init", "random", "--sigma", "1e-9") == pytest.approx(zeros, abs=1e-6)  # σ → 0: the zero start
    assert abs(frechet("--init", "random", "--sigma", "3") - zeros) > 0.01
    assert cli_main(["retarget", "demo:introduction_06", "--robot", "nao", "--sigma", "-1"]) == 2
    assert "--sigma" in capsys.readouterr().err


@pytest.mark.parametrize("extra, given, search, tip_dir, thumb", [
    ([], None, ("middle", "ring", "pinky"), 7000.0, 500.0),  # the defaults: the robot's fingers of HAND_SEARCH
    (["--hand-search", "none"], (), (), 7000.0, 500.0),
    (["--handshape"], ("middle", "ring", "pinky"), ("middle", "ring", "pinky"), 8000.0, 800.0),
    (["--handshape", "--weights", "thumb=600", "--hand-search", "ring"], ("ring",), ("ring",), 8000.0, 600.0),
    (["--hand-search", "ring,pinky"], ("ring", "pinky"), ("ring", "pinky"), 7000.0, 500.0),
])
def test_retarget_handshape_and_hand_search_reach_the_pipeline(extra, given, search, tip_dir, thumb, capsys, monkeypatch):
    """``--handshape`` is the preset (LossWeights.handshape, HANDSHAPE_SEARCH); ``--weights`` and ``--hand-search`` refine it;
    without them the pipeline searches the robot's default fingers, ``--hand-search none`` none."""
    import nlo_lab.pipeline as pipeline

    seen, built = [], []
    build = pipeline.RetargetConfig.build
    monkeypatch.setattr(pipeline.RetargetConfig, "build", lambda self: seen.append(self) or built.append(build(self)) or built[-1])
    assert cli_main(["retarget", "demo:introduction_06", "--robot", "yumi", "--iters", "0", "--json", "--quiet", *extra]) == 0
    (config,) = seen
    assert config.settings.hand_search == given
    assert built[0].hand_search == search
    assert (config.weights.tip_dir, config.weights.thumb) == (tip_dir, thumb)
    assert config.settings.hand_slowdown == (HANDSHAPE_SLOWDOWN if "--handshape" in extra else 1.0)


@pytest.mark.parametrize("extra, slowdown", [(["--hand-slowdown", "2.5"], 2.5), (["--handshape", "--hand-slowdown", "1"], 1.0)])
def test_retarget_hand_slowdown_reaches_the_pipeline(extra, slowdown, capsys, monkeypatch):
    """``--hand-slowdown`` sets the hand stage's slowdown, over the preset's too."""
    import nlo_lab.pipeline as pipeline

    seen = []
    build = pipeline.RetargetConfig.build
    monkeypatch.setattr(pipeline.RetargetConfig, "build", lambda self: seen.append(self) or build(self))
    assert cli_main(["retarget", "demo:introduction_06", "--robot", "yumi", "--iters", "0", "--json", "--quiet", *extra]) == 0
    assert seen[0].settings.hand_slowdown == slowdown


@pytest.mark.parametrize("value", ["0.5", "11", "nan", "x"])
def test_a_bad_hand_slowdown_is_one_line_and_exit_2(value, capsys, tmp_path):
    rc = cli_main(["retarget", "demo:introduction_06", "--robot", "yumi", "--hand-slowdown", value, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "--hand-slowdown" in err[0], err
    assert not (tmp_path / "o").exists()

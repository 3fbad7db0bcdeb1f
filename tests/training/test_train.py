"""Training loop and checkpoints."""

from __future__ import annotations

import pytest
import torch

import nlo_lab.model.checkpoint as checkpoint
import nlo_lab.training.train as training_mod
from nlo_lab.errors import CheckpointError, SettingsError
from nlo_lab.inference import RetargetInputs
from nlo_lab.model import CHECKPOINT_FORMAT_VERSION, load_checkpoint, load_pretrained, save_checkpoint
from nlo_lab.robot import load_robot
from nlo_lab.training import TrainSettings, new_model, train_model


@pytest.fixture(scope="module")
def pose_data(nao, demonstration_from_robot, random_feasible_pose):
    """Small train / validation sets the robot can meet exactly."""
    train = RetargetInputs.from_demonstration(demonstration_from_robot(nao, random_feasible_pose(nao, 96, seed=21)))
    val = RetargetInputs.from_demonstration(demonstration_from_robot(nao, random_feasible_pose(nao, 32, seed=22)))
    return train, val


@pytest.mark.parametrize(
    "kwargs, word",
    [({"epochs": 0}, "epochs"), ({"batch_size": -2}, "batch_size"), ({"lr": 0.0}, "lr"), ({"clip": float("nan")}, "clip"),
     ({"kind": "cnn"}, "kind"), ({"seed": -1}, "seed"), ({"max_seconds": 0}, "max_seconds")],
)
def test_train_settings_are_validated(kwargs, word):
    with pytest.raises(SettingsError, match=word):
        TrainSettings(**kwargs)


def test_training_lowers_the_validation_loss_and_keeps_the_best(nao, pose_data):
    train, val = pose_data
    settings = TrainSettings(epochs=5, batch_size=16, lr=3e-3, val_every=6, progress=False, seed=1)
    result = train_model(nao, settings, train_data=train, val_data=val)
    vals = [h["val"] for h in result.history]
    assert result.val_loss == pytest.approx(min(vals))
    assert result.val_loss < 0.8 * vals[0]
    assert result.steps == 5 * (96 // 16)
    # The returned model is the best state: its validation loss is the reported one.
    assert training_mod._evaluate(result.model, nao, val, training_mod.LossWeights(), "hinge") == pytest.approx(result.val_loss, rel=1e-4)
    # Latent statistics of the training latents are filled in.
    z = result.model.encode(train.encoder.node_features, train.encoder.edge_features)
    torch.testing.assert_close(result.model.latent_mean, z.mean(0), atol=1e-5, rtol=1e-4)


def test_training_is_reproducible_with_a_seed(nao, pose_data):
    train, val = pose_data
    settings = TrainSettings(epochs=1, batch_size=32, progress=False, seed=5)
    a = train_model(nao, settings, train_data=train, val_data=val)
    b = train_model(nao, settings, train_data=train, val_data=val)
    assert a.val_loss == b.val_loss
    # by default the decoder trains on the pipeline's latent objective: without the hand stage's terms
    from nlo_lab.objective import HAND_STAGE_TERMS, LossWeights

    assert a.model.train_info["weights"] == LossWeights().latent_stage().as_dict()
    assert all(a.model.train_info["weights"][name] == 0.0 for name in HAND_STAGE_TERMS)


def test_checkpoint_round_trip(tmp_path, nao, pose_data):
    model = new_model(nao)
    with torch.no_grad():
        model.latent_mean.fill_(0.25)
    path = save_checkpoint(model, tmp_path / "nao.pt", nao)
    loaded = load_checkpoint(path, nao)
    for k, v in model.state_dict().items():
        torch.testing.assert_close(loaded.state_dict()[k], v)
    x = pose_data[1].encoder
    torch.testing.assert_close(loaded(x.node_features, x.edge_features)[0], model(x.node_features, x.edge_features)[0])
    assert path.stat().st_size < 2_000_000


def test_checkpoint_for_another_robot_is_refused(tmp_path, nao):
    path = save_checkpoint(new_model(nao), tmp_path / "nao.pt", nao)
    with pytest.raises(CheckpointError, match="'nao'.*'pepper'"):
        load_checkpoint(path, load_robot("pepper"))


def test_checkpoint_of_another_format_version_is_refused(tmp_path, nao):
    path = save_checkpoint(new_model(nao), tmp_path / "nao.pt", nao)
    ckpt = torch.load(path, weights_only=True)
    ckpt["format_version"] = CHECKPOINT_FORMAT_VERSION + 1
    torch.save(ckpt, path)
    with pytest.raises(CheckpointError, match=f"version {CHECKPOINT_FORMAT_VERSION + 1}.*version {CHECKPOINT_FORMAT_VERSION}"):
        load_checkpoint(path, nao)


def test_missing_corrupt_and_foreign_files_are_refused(tmp_path, nao):
    with pytest.raises(CheckpointError, match="no such file"):
        load_checkpoint(tmp_path / "none.pt", nao)
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"\x00not a checkpoint" * 10)
    with pytest.raises(CheckpointError, match="corrupt"):
        load_checkpoint(bad, nao)
    foreign = tmp_path / "foreign.pt"
    torch.save({"weights": torch.zeros(3)}, foreign)
    with pytest.raises(CheckpointError, match="not an nlo_lab checkpoint"):
        load_checkpoint(foreign, nao)
    half = tmp_path / "half.pt"
    ckpt = torch.load(save_checkpoint(new_model(nao), tmp_path / "ok.pt", nao), weights_only=True)
    del ckpt["state_dict"]["decoder.layers.0.weight"]
    torch.save(ckpt, half)
    with pytest.raises(CheckpointError, match="does not fit"):
        load_checkpoint(half, nao)


def test_load_pretrained_without_a_checkpoint_says_how_to_make_one(tmp_path, monkeypatch, nao):
    monkeypatch.setattr(checkpoint, "CHECKPOINTS_DIR", tmp_path)
    with pytest.raises(CheckpointError, match="nlo-lab train --robot nao"):
        load_pretrained(nao)
    save_checkpoint(new_model(nao), tmp_path / "nao.pt", nao)
    assert load_pretrained("nao").robot_name == "nao"


def test_validation_is_held_out_of_the_training_split_never_the_test_split():
    from nlo_lab.corpus import corpus_names
    from nlo_lab.training import train_validation_split

    fit, val = train_validation_split()
    fit_names, val_names = {d.name for d in fit}, {d.name for d in val}
    assert val_names and fit_names
    assert not fit_names & val_names
    assert fit_names | val_names == set(corpus_names("train"))
    assert not val_names & set(corpus_names("test"))


def test_new_models_start_at_the_robot_neutral_pose_and_checkpoints_keep_it(tmp_path, nao):
    model = new_model(nao)
    rest = model.decoder.rest_pre
    assert float(rest.abs().max()) > 0.1, "the neutral pose is not the limits' midpoint"
    torch.testing.assert_close(model.decoder.remap(rest[None]), nao.neutral_q[None].clamp(
        (nao.lower_limits + nao.upper_limits) / 2 - 0.9 * (nao.upper_limits - nao.lower_limits) / 2,
        (nao.lower_limits + nao.upper_limits) / 2 + 0.9 * (nao.upper_limits - nao.lower_limits) / 2), atol=1e-5, rtol=1e-5)
    loaded = load_checkpoint(save_checkpoint(model, tmp_path / "nao.pt", nao), nao)
    torch.testing.assert_close(loaded.decoder.rest_pre, rest)


def test_the_command_line_trains_with_its_flags_and_writes_a_loadable_checkpoint(tmp_path, monkeypatch, nao, capsys, demonstration_from_robot, random_feasible_pose):

    from nlo_lab.cli import main as cli_main

    fit = [demonstration_from_robot(nao, random_feasible_pose(nao, 24, seed=31))]
    val = [demonstration_from_robot(nao, random_feasible_pose(nao, 8, seed=32))]
    monkeypatch.setattr(training_mod, "train_validation_split", lambda seed=0: (fit, val))
    out = tmp_path / "nao.pt"
    argv = ["train", "--robot", "nao", "--epochs", "2", "--batch-size", "8", "--lr", "0.002", "--max-seconds", "60",
            "--latent-per-node", "3", "--kind", "mlp", "--seed", "5", "--out", str(out), "--quiet"]
    assert cli_main(argv) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    model = load_checkpoint(out, nao)
    settings = model.train_info["train_settings"]
    assert (settings["epochs"], settings["batch_size"], settings["lr"], settings["max_seconds"]) == (2, 8, 0.002, 60.0)
    assert (settings["latent_per_node"], settings["kind"], settings["seed"]) == (3, "mlp", 5)
    assert model.train_info["steps"] == 2 * (24 // 8)


@pytest.mark.parametrize("flag, value", [("--max-seconds", "0"), ("--max-seconds", "nan"), ("--lr", "-1"), ("--batch-size", "0"), ("--kind", "cnn")])
def test_bad_training_flags_are_one_line_exit_2(flag, value, capsys):
    from nlo_lab.cli import main as cli_main

    assert cli_main(["train", "--robot", "nao", flag, value]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and flag in err and "Traceback" not in err


def test_python_m_nlo_lab_cli_train_is_the_command_line(tmp_path):
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "nlo_lab.cli", "train", "--robot", "nao", "--epochs", "0"], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2 and "nlo-lab train: argument --epochs" in r.stderr and "Traceback" not in r.stderr

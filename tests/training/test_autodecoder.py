"""The auto-decoder training (the paper's Eq. ``autodecoder``): decoder and one latent code per motion, jointly."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from nlo_lab.corpus import sign_corpus
from nlo_lab.errors import SettingsError
from nlo_lab.inference import OptimizeSettings, optimize_latent
from nlo_lab.model import load_checkpoint, save_checkpoint
from nlo_lab.objective import LossWeights, objective
from nlo_lab.pipeline import RetargetConfig
from nlo_lab.training import LatentCodes, TrainSettings, autodecoder_loss, demos_inputs, new_model, train_model

pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def frames():
    """Real frames of the synthetic training split: 128 to fit, 32 held out."""
    data = demos_inputs(sign_corpus("train")[:2])
    return data.index(slice(0, 128)), data.index(slice(128, 160))


@pytest.fixture(scope="module")
def trained(nao, frames):
    train, val = frames
    settings = TrainSettings(mode="autodecoder", max_steps=40, batch_size=16, val_every=20, val_frames=32, val_iterations=5,
                             code_lr=0.05, progress=False, seed=3)
    return train_model(nao, settings, train_data=train, val_data=val)


@pytest.mark.slow
def test_the_prior_term_is_the_squared_norm_over_sigma_squared(robot64, frames):
    nao = robot64("nao")
    train, _ = frames
    targets = train.targets.to(dtype=torch.float64)
    model = new_model(nao).double()
    codes = LatentCodes(len(train), model.latent_shape, init_std=0.5, seed=1).double()
    idx = torch.tensor([3, 0, 77])
    weights = LossWeights(latent=0.25)  # 1/σ² with σ = 2
    got = autodecoder_loss(model, nao, codes, idx, targets.index(idx), weights, "hinge")
    z = codes.table.weight.detach()[idx].view(3, *model.latent_shape)
    expected_objective, _ = objective(nao, model.decode(z), targets.index(idx), weights, collision_form="hinge")
    torch.testing.assert_close(got, expected_objective + z.flatten(1).square().sum(1) / 2.0**2)
    # the prior's gradient on a code is 2 z / σ² (the objective's part subtracted)
    zero_prior = dataclasses.replace(weights, latent=0.0)
    (g_all,) = torch.autograd.grad(autodecoder_loss(model, nao, codes, idx, targets.index(idx), weights, "hinge").sum(), codes.table.weight)
    (g_obj,) = torch.autograd.grad(autodecoder_loss(model, nao, codes, idx, targets.index(idx), zero_prior, "hinge").sum(), codes.table.weight)
    torch.testing.assert_close((g_all - g_obj).to_dense()[idx].view(3, *model.latent_shape), 2 * z / 4.0)


def test_there_is_one_code_per_training_motion_and_the_decoder_alone_learns(nao, frames, trained):
    train, _ = frames
    model = trained.model
    assert trained.codes is not None and trained.codes.shape == (len(train), *model.latent_shape)
    assert len(torch.unique(trained.codes.flatten(1), dim=0)) == len(train), "codes are not per motion"
    torch.manual_seed(3)  # as train_model seeds the new model
    fresh = new_model(nao, TrainSettings(seed=3))
    enc_same = all(torch.equal(a, b) for a, b in zip(model.encoder.state_dict().values(), fresh.encoder.state_dict().values(), strict=True))
    dec_same = all(torch.equal(a, b) for a, b in zip(model.decoder.state_dict().values(), fresh.decoder.state_dict().values(), strict=True))
    assert enc_same, "the auto-decoder has no encoder: its weights must stay untrained"
    assert not dec_same, "the decoder did not learn"
    torch.testing.assert_close(model.latent_mean, trained.codes.mean(0))  # train-stats starts from the learned codes


def test_a_short_run_lowers_the_training_and_validation_loss(trained):
    train = [h["train"] for h in trained.history[1:]]
    val = [h["val"] for h in trained.history]
    assert trained.steps == 40
    assert train[-1] < 0.7 * train[0], train
    assert trained.val_loss == pytest.approx(min(val)) and trained.val_loss < 0.8 * val[0], val


def test_the_learned_codes_fit_their_frames_better_than_the_mean_code(nao, frames, trained):
    """Each code holds its own frame: it fits that frame better than the codes' mean and than another frame's code.

    Measured on this 40-step run (one thread, deterministic): own / mean 0.82 (0.77-0.87 over seeds 1-5),
    own / shuffled 0.61, 87 % of the frames better. It was own / mean 0.70 before NAO's capsules were fitted
    to its URDF's geometry (430e5cc, 99 pairs instead of 17): the collision term now holds the hands away
    from targets near the body in this short run (end-effector term 0.54 instead of 0.38), so the codes
    separate the frames less there; the auto-decoder's numbers are otherwise bit-identical.
    """
    train, _ = frames
    model = trained.model
    weights = LossWeights(smooth=0.0)
    other = torch.randperm(len(train), generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        own, _ = objective(nao, model.decode(trained.codes), train.targets, weights)
        mean, _ = objective(nao, model.decode(trained.codes.mean(0).expand_as(trained.codes)), train.targets, weights)
        shuffled, _ = objective(nao, model.decode(trained.codes[other]), train.targets, weights)
    assert float(own.mean()) < 0.9 * float(mean.mean())  # better than the common start
    assert float((own < mean).float().mean()) > 0.75
    assert float(own.mean()) < 0.8 * float(shuffled.mean())  # a code is its frame's, not any frame's


def test_a_step_moves_only_the_codes_of_its_batch(nao, frames):
    train, val = frames
    settings = TrainSettings(mode="autodecoder", max_steps=1, batch_size=16, val_frames=8, val_iterations=1, progress=False, seed=4)
    before = LatentCodes(len(train), new_model(nao).latent_shape, settings.code_init_std, settings.seed).all()
    after = train_model(nao, settings, train_data=train, val_data=val.index(slice(0, 8))).codes
    moved = (after != before).flatten(1).any(1)
    assert int(moved.sum()) == 16  # sparse updates: the 16 codes of the one batch


def test_an_autodecoder_model_refuses_the_encoder_start_and_retargets_from_train_stats(tmp_path, nao, frames, trained):
    _, val = frames
    model = load_checkpoint(save_checkpoint(trained.model, tmp_path / "ad.pt", nao), nao)
    assert not model.has_encoder and model.config["training"] == "autodecoder"
    torch.testing.assert_close(model.latent_mean, trained.model.latent_mean)
    with pytest.raises(SettingsError, match="auto-decoder"):
        optimize_latent(model, nao, val.targets, OptimizeSettings(init="encoder", iterations=2), encoder_input=val.encoder)
    demo = sign_corpus("test")[0].slice(0, 10)
    result = RetargetConfig(nao, OptimizeSettings(init="train-stats", iterations=5), model=model).build()(demo)
    assert result.trajectory.angles.shape == (10, nao.n_joints)
    assert new_model(nao).has_encoder


def test_training_modes_are_validated():
    with pytest.raises(SettingsError, match="mode"):
        TrainSettings(mode="vae")
    for name in ("code_lr", "code_init_std"):
        with pytest.raises(SettingsError, match=name):
            TrainSettings(**{name: 0.0})
    with pytest.raises(SettingsError, match="max_steps"):
        TrainSettings(max_steps=0)

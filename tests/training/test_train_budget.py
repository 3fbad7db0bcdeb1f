"""Training settings added for the paper's experiments: a budget of steps, the decoder's start, the defaults kept."""

from __future__ import annotations

import pytest
import torch

from nlo_lab.corpus import sign_corpus
from nlo_lab.errors import SettingsError
from nlo_lab.threads import single_thread
from nlo_lab.training import TrainSettings, demos_inputs, new_model, train_model


@pytest.fixture(scope="module")
def frames():
    data = demos_inputs(sign_corpus("train")[:1])
    return data.index(slice(0, 96)), data.index(slice(96, 112))


def test_the_defaults_that_made_the_shipped_checkpoints_are_unchanged():
    s = TrainSettings()
    assert (s.epochs, s.batch_size, s.lr, s.clip, s.seed, s.kind, s.latent_per_node) == (30, 64, 1e-3, 10.0, 0, "graph", 4)
    assert (s.mode, s.activation, s.max_steps, s.decoder_rest, s.collision_form) == ("encoder", "leaky_relu", None, "neutral", "hinge")


def test_max_steps_ends_training_after_that_many_steps_whatever_the_epochs(nao, frames):
    train, val = frames
    with single_thread(1):
        r = train_model(nao, TrainSettings(epochs=50, batch_size=16, max_steps=7, val_every=3, val_frames=16, progress=False), train_data=train, val_data=val)
    assert r.steps == 7 and [h["step"] for h in r.history] == [0, 3, 6, 7]
    with single_thread(1):
        short = train_model(nao, TrainSettings(epochs=1, batch_size=16, max_steps=100, val_frames=16, progress=False), train_data=train, val_data=val)
    assert short.steps == 96 // 16  # the epochs end it first


def test_the_decoder_starts_at_the_neutral_pose_or_at_the_limits_midpoint(nao):
    neutral = new_model(nao, TrainSettings())
    midpoint = new_model(nao, TrainSettings(decoder_rest="midpoint"))
    assert float(neutral.decoder.rest_pre.abs().max()) > 0.1
    assert torch.equal(midpoint.decoder.rest_pre, torch.zeros_like(midpoint.decoder.rest_pre))
    with pytest.raises(SettingsError, match="decoder_rest"):
        TrainSettings(decoder_rest="zeros")

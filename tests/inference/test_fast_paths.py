"""Readable by default, fast by choice: FastPaths says which evaluation of the decoder, the
objective and FK runs; the pipeline chooses by batch size (RetargetConfig(fast=True), the
default) or takes an explicit choice, and the optimisation's result does not depend on it."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from nlo_lab.corpus import corpus_clip
from nlo_lab.errors import SettingsError
from nlo_lab.inference import FastPaths, OptimizeSettings, RetargetInputs, fast_paths, optimize_joints, optimize_latent
from nlo_lab.inference.fast_paths import DECODER_NUMPY_MAX_BATCH
from nlo_lab.inference.numpy_descent import WrittenGradientLoss
from nlo_lab.model import load_pretrained
from nlo_lab.pipeline import RetargetConfig


@pytest.fixture(scope="module")
def nao64(robot64):
    return robot64("nao")


@pytest.fixture(scope="module")
def model64(nao64):
    return load_pretrained(nao64).double()


@pytest.fixture(scope="module")
def inputs(nao64):
    return RetargetInputs.from_demonstration(corpus_clip("introduction_12").slice(0, 12), dtype=torch.float64)


def _raise(*args, **kwargs):
    raise AssertionError("a fast path ran")


def test_the_choice_by_batch_size():
    assert FastPaths.readable() == FastPaths() == FastPaths("paper", False, False, False, False, False, False)
    one, many = FastPaths.for_frames(1), FastPaths.for_frames(1000)
    assert one == FastPaths("numpy", True, True, True, True, True, True)
    edge, above = FastPaths.for_frames(DECODER_NUMPY_MAX_BATCH), FastPaths.for_frames(DECODER_NUMPY_MAX_BATCH + 1)
    assert edge.decoder == "numpy" and edge.numpy_iteration and above.decoder == "node-major" and not above.numpy_iteration
    assert many == FastPaths("node-major", True, True, True, False, True, True)  # the numpy terms at any batch on the CPU
    assert FastPaths.for_frames(1, "meta") == FastPaths("node-major", False, True, True, False, True, False)  # numpy forms: the CPU only
    assert fast_paths(True, 1) == one and fast_paths(False, 1) == FastPaths() and fast_paths(many, 1) is many
    assert one.objective_options() == {"fused": True, "cull": True, "analytic_fk": True}


@pytest.mark.parametrize("bad", [{"decoder": "fast"}, {"fused_objective": 1}, {"analytic_fk": "yes"}])
def test_bad_choices_are_refused_in_one_line(bad):
    with pytest.raises(SettingsError) as info:
        FastPaths(**bad)
    assert "\n" not in str(info.value)
    with pytest.raises(SettingsError, match="fast"):
        fast_paths("yes", 1)


@pytest.mark.parametrize("frames", [1, 12])
def test_latent_optimisation_gives_the_same_result_fast_or_readable(nao64, model64, inputs, frames):
    """float64 end to end: every form agrees to rounding, so 15 Adam steps end at the same point."""
    x = inputs.index(slice(0, frames))
    settings = OptimizeSettings(iterations=15, patience=15)
    written = []
    real = WrittenGradientLoss.__call__
    def spy(self, z):
        written.append(len(z))
        return real(self, z)

    with pytest.MonkeyPatch.context() as m:
        m.setattr(WrittenGradientLoss, "__call__", spy)
        runs = {fast: optimize_latent(model64, nao64, x.targets, settings, encoder_input=x.encoder, fast=fast) for fast in (True, False)}
    # one frame alone: the numpy iteration; 12 frames, coupled by the smoothness term: the gradient written out
    assert written == ([] if frames == 1 else [frames] * 16)
    torch.testing.assert_close(runs[True].q, runs[False].q, atol=1e-8, rtol=1e-8)
    np.testing.assert_allclose(runs[True].history, runs[False].history, rtol=1e-9)
    assert runs[True].iterations == runs[False].iterations == 15
    assert min(runs[False].history) < runs[False].history[0]  # it did descend


def test_joint_space_gives_the_same_result_fast_or_readable(nao64, inputs):
    from nlo_lab.inference import JointOptimizeSettings

    settings = JointOptimizeSettings(iterations=10, patience=10)
    fast, readable = (optimize_joints(nao64, inputs.targets, settings, fast=f) for f in (True, False))
    torch.testing.assert_close(fast.q, readable.q, atol=1e-9, rtol=1e-9)


def test_optimisers_run_the_readable_forms_unless_asked(nao64, model64, inputs, monkeypatch):
    from nlo_lab.inference.numpy_descent import NumpyLatentLoss
    from nlo_lab.model import decoder
    from nlo_lab.objective import total

    monkeypatch.setattr(decoder, "decode_numpy", _raise)
    monkeypatch.setattr(total, "point_terms", _raise)
    monkeypatch.setattr(NumpyLatentLoss, "__call__", _raise)
    monkeypatch.setattr(WrittenGradientLoss, "__call__", _raise)
    settings = OptimizeSettings(iterations=2, patience=2)
    for frames in (1, 12):
        x = inputs.index(slice(0, frames))
        optimize_latent(model64, nao64, x.targets, settings, encoder_input=x.encoder)
        for fast in (True, FastPaths(decoder="numpy"), FastPaths(fused_objective=True), FastPaths(numpy_iteration=True, decoder="numpy", fused_objective=True),
                     FastPaths(written_gradient=True, fused_objective=True)):
            with pytest.raises(AssertionError, match="fast path"):
                optimize_latent(model64, nao64, x.targets, settings, encoder_input=x.encoder, fast=fast)


def test_the_pipeline_chooses_by_batch_size_or_takes_the_choice(nao64, model64, monkeypatch):
    demo = corpus_clip("introduction_12").slice(0, 3)
    built = RetargetConfig(nao64, OptimizeSettings(iterations=2), model=model64).build()
    assert built.fast_paths(1) == FastPaths.for_frames(1) and built.fast_paths(500) == FastPaths.for_frames(500)
    readable = RetargetConfig(nao64, OptimizeSettings(iterations=2), model=model64, fast=False).build()
    assert readable.fast_paths(1) == FastPaths.readable()
    chosen = FastPaths(decoder="node-major")
    assert RetargetConfig(nao64, model=model64, fast=chosen).build().fast_paths(1) is chosen
    with pytest.raises(SettingsError, match="fast"):
        RetargetConfig(nao64, model=model64, fast="always").build()
    from nlo_lab.model import decoder

    monkeypatch.setattr(decoder, "decode_numpy", _raise)
    readable(demo)  # no fast path at all
    with pytest.raises(AssertionError, match="fast path"):
        built(demo)


@pytest.mark.parametrize("name", ["yumi", "nao"])
def test_sequence_start_costs_its_candidates_the_same_fast_or_readable(robot64, name):
    """sequence_start with the numpy terms decodes and maps each start latent once and measures its collision term
    once: each candidate's cost and angles are those of the readable loop (each candidate decoded, the term
    functions), and the chosen starts the same."""
    from nlo_lab.inference import initial_latent, sequence_start
    from nlo_lab.inference.descent import frozen
    from nlo_lab.inference.latent import _candidate_costs
    from nlo_lab.objective import TERMS, LossWeights, Objective

    robot = robot64(name)
    model = load_pretrained(robot).double()
    x = RetargetInputs.from_demonstration(corpus_clip("introduction_12").slice(0, 20), dtype=torch.float64)
    gen = torch.Generator().manual_seed(4)
    z0 = initial_latent(model, x.encoder, OptimizeSettings())
    z0 = z0 + 1.5 * torch.randn(z0.shape, generator=gen, dtype=z0.dtype)  # starts far apart: candidates differ, some collide
    weights, T = LossWeights(), len(x.targets)
    idx = (torch.arange(T)[:, None] + torch.arange(-2, 3)[None]).clamp(0, T - 1)
    fused = Objective(robot, x.targets, weights, fused=True, cull=True, analytic_fk=True)
    readable = Objective(robot, x.targets, weights)
    with frozen(model), torch.no_grad():
        unary, angles = _candidate_costs(model, fused, z0, idx, weights.latent, "node-major", True)
        collided = 0.0
        for k in range(idx.shape[1]):
            z = z0[idx[:, k]]
            q = model.decode(z)
            total, terms = readable(q)
            torch.testing.assert_close(unary[k], total + weights.latent * z.pow(2).flatten(1).sum(1), atol=1e-9, rtol=1e-9)
            torch.testing.assert_close(angles[k], q, atol=1e-12, rtol=1e-12)
            collided = max(collided, float(terms[:, TERMS.index("collision")].max()))
    assert collided > 0  # the collision term, measured once per start latent, is in the costs
    fast, slow = (sequence_start(model, robot, x.targets, z0, weights, fast=f) for f in (True, False))
    assert torch.equal(fast, slow)

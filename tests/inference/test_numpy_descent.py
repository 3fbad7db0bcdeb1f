"""The numpy iteration (NumpyLatentLoss: decoder, FK and terms chained by hand, no autograd)
gives the readable torch path's loss, angles, terms and gradient; it declines where a piece
has no numpy form; and the descent on arrays is the descent on tensors."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from nlo_lab.corpus import corpus_clip
from nlo_lab.inference import OptimizeSettings, RetargetInputs, descend, optimize_latent
from nlo_lab.inference.numpy_descent import NumpyLatentLoss
from nlo_lab.model import GraphDecoder, MLPDecoder, build_model
from nlo_lab.objective import LossWeights, Objective


@pytest.fixture(scope="module")
def robot(each_robot64):
    return each_robot64


def _model(robot, kind="graph"):
    from nlo_lab.human import skeleton_graph

    torch.manual_seed(1)
    human = skeleton_graph()
    model = build_model(robot.name, robot.graph, robot.lower_limits, robot.upper_limits, human, 8, kind=kind, rest=robot.neutral_q)
    return model.double().requires_grad_(False)


def _inputs(frames: int):
    x = RetargetInputs.from_demonstration(corpus_clip("introduction_12").slice(0, frames), dtype=torch.float64)
    return x


@pytest.mark.parametrize("frames", [1, 3])
def test_numpy_loss_equals_the_readable_torch_loss(robot, frames):
    model, x = _model(robot), _inputs(frames)
    weights = LossWeights(latent=0.3)
    z = 2 * torch.randn(frames, *model.latent_shape, dtype=torch.float64, generator=torch.Generator().manual_seed(2))
    numpy_loss = NumpyLatentLoss.build(model, robot, Objective(robot, x.targets, weights, fused=True), weights.latent)
    loss, q, terms, grad = numpy_loss(z.numpy().copy())
    zr = z.clone().requires_grad_(True)
    ref_q = model.decode(zr)  # the paper's decoder, the term functions, autograd through FK
    ref_total, ref_terms = Objective(robot, x.targets, weights)(ref_q)
    ref_loss = ref_total + weights.latent * zr.pow(2).flatten(1).sum(1)
    (ref_grad,) = torch.autograd.grad(ref_loss.sum(), zr)
    for got, want in ((loss, ref_loss), (q, ref_q), (terms, ref_terms), (grad, ref_grad)):
        torch.testing.assert_close(torch.from_numpy(np.asarray(got)), want.detach(), atol=1e-9, rtol=1e-9)
    assert float(ref_grad.abs().max()) > 0


def test_it_declines_where_a_piece_has_no_numpy_form(robot):
    x = _inputs(1)
    fused = Objective(robot, x.targets, fused=True)
    assert NumpyLatentLoss.build(_model(robot), robot, fused, 1.0) is not None
    assert NumpyLatentLoss.build(_model(robot), robot, Objective(robot, x.targets), 1.0) is None  # no numpy terms
    assert NumpyLatentLoss.build(_model(robot, "mlp"), robot, fused, 1.0) is None  # the MLP decoder has no numpy form
    trainable = _model(robot).requires_grad_(True)
    assert NumpyLatentLoss.build(trainable, robot, fused, 1.0) is None  # weights not frozen
    assert isinstance(_model(robot).decoder, GraphDecoder) and isinstance(_model(robot, "mlp").decoder, MLPDecoder)


@pytest.mark.parametrize("stepper,lr,patience", [("adam", 0.1, 40), ("adam", 0.05, 41), ("rprop", 0.05, 41)])
def test_the_descent_on_arrays_is_the_descent_on_tensors(stepper, lr, patience):
    """descend() on a numpy array (gradient from evaluate) takes the steps it takes on a tensor (autograd), with each
    step rule."""
    target = torch.tensor([[1.0, -2.0, 0.5], [0.0, 3.0, -1.0]], dtype=torch.float64)

    def on_tensor(x):
        loss = ((x - target) ** 2).sum(1) + (x**4).sum(1) * 0.01
        return loss, x, loss[:, None]

    def on_array(x):
        t = target.numpy()
        loss = ((x - t) ** 2).sum(1) + (x**4).sum(1) * 0.01
        return loss, x, loss[:, None], 2 * (x - t) + 0.04 * x**3

    start = torch.zeros(2, 3, dtype=torch.float64)
    a = descend(start, on_tensor, None, 40, patience, lr, None, stepper=stepper)
    b = descend(start.numpy(), on_array, None, 40, patience, lr, None, stepper=stepper)
    assert isinstance(b[0], np.ndarray) and a[5] == b[5] == 40
    for x, y in zip(a[:4], b[:4], strict=True):
        torch.testing.assert_close(torch.from_numpy(np.asarray(y)), x, atol=1e-12, rtol=1e-12)
    np.testing.assert_allclose(a[4], b[4], rtol=1e-12)


def test_one_frame_optimisation_runs_the_numpy_iteration(robot, monkeypatch):
    model, x = _model(robot), _inputs(1)
    calls = []
    original = NumpyLatentLoss.__call__
    monkeypatch.setattr(NumpyLatentLoss, "__call__", lambda self, z: calls.append(1) or original(self, z))
    settings = OptimizeSettings(iterations=5, patience=5, init="zeros")
    fast = optimize_latent(model, robot, x.targets, settings, fast=True)
    assert len(calls) == 6  # the start and after each of the 5 steps
    readable = optimize_latent(model, robot, x.targets, settings)
    assert len(calls) == 6
    torch.testing.assert_close(fast.q, readable.q, atol=1e-9, rtol=1e-9)
    assert isinstance(fast.z, torch.Tensor) and fast.z.shape == readable.z.shape


def test_it_declines_when_the_objective_has_a_term_without_a_numpy_form(robot):
    """A term the numpy terms do not compute (the weights say the objective has it) means torch runs."""
    x = _inputs(1)
    fused = Objective(robot, x.targets, fused=True)
    fused.weights = torch.cat([fused.weights, torch.zeros(1, dtype=fused.weights.dtype)])  # one more term, even at weight 0
    assert NumpyLatentLoss.build(_model(robot), robot, fused, 1.0) is None


@pytest.mark.parametrize("kind, form", [("graph", "node-major"), ("graph", "numpy"), ("mlp", "paper")])
@pytest.mark.parametrize("anchored", [False, True])
def test_written_gradient_loss_equals_the_readable_torch_loss(robot, kind, form, anchored):
    """A recording's batch, smoothness term on (frame 0 anchored to the frame before or not): the loss, angles,
    terms and gradient of WrittenGradientLoss are the readable path's (the paper's decoder, the term functions,
    autograd through FK and the smoothness term)."""
    from nlo_lab.inference import smoothness_term
    from nlo_lab.inference.numpy_descent import WrittenGradientLoss
    from nlo_lab.objective.numpy_backend import NEAR_SLACK

    frames = 6
    model, x = _model(robot, kind), _inputs(frames)
    weights = LossWeights(latent=0.3, smooth=25.0)  # a larger weight than the default: the smoothness gradient counts
    gen = torch.Generator().manual_seed(3)
    z = 2 * torch.randn(frames, *model.latent_shape, dtype=torch.float64, generator=gen)
    anchor = robot.neutral_q.double() + 0.3 if anchored else None
    objective = Objective(robot, x.targets, weights, fused=True, cull=True, analytic_fk=True)
    written = WrittenGradientLoss.build(model, robot, objective, weights.latent, x.targets, weights.smooth, anchor, form)
    assert (written.decoder is not None) == (form == "node-major" and kind == "graph")  # its gradient written out too
    # every frame's pairs searched every call, on its own copy of the terms: the caller's objective keeps its slack
    assert written.terms.near_pairs.slack == 0.0 and objective.numpy_terms.near_pairs.slack == NEAR_SLACK
    loss, q, terms, grad = written(z)
    zr = z.clone().requires_grad_(True)
    ref_q = model.decode(zr)
    ref_total, ref_terms = Objective(robot, x.targets, weights)(ref_q)
    ref_loss = ref_total + smoothness_term(robot, x.targets, weights, anchor)(ref_q) + weights.latent * zr.pow(2).flatten(1).sum(1)
    (ref_grad,) = torch.autograd.grad(ref_loss.sum(), zr)
    for got, want in ((loss, ref_loss), (q, ref_q), (terms, ref_terms), (grad, ref_grad)):
        torch.testing.assert_close(got, want.detach(), atol=1e-9, rtol=1e-9)
    assert float(ref_grad.abs().max()) > 0
    # the smoothness term is in: without it the loss differs
    assert not torch.allclose(ref_loss, ref_total + weights.latent * zr.pow(2).flatten(1).sum(1))


def test_written_gradient_loss_declines_without_numpy_terms(robot):
    from nlo_lab.inference.numpy_descent import WrittenGradientLoss

    x = _inputs(3)
    assert WrittenGradientLoss.build(_model(robot), robot, Objective(robot, x.targets), 1.0, x.targets, 10.0, None, "node-major") is None
    without = WrittenGradientLoss.build(_model(robot), robot, Objective(robot, x.targets, fused=True), 1.0, x.targets, 0.0, None, "node-major")
    assert without is not None and without.smooth is None  # smooth = 0: frames independent

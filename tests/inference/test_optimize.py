"""Latent optimisation, initialisations, streaming, and the joint-space baseline."""

from __future__ import annotations

import pytest
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.inference import (
    JointOptimizeSettings,
    OptimizeSettings,
    descend,
    initial_latent,
    optimize_joints,
    optimize_latent,
    optimize_stream,
)
from nlo_lab.model import encoder_input
from nlo_lab.objective import LossWeights, latent_loss, objective, targets_from_demonstration
from nlo_lab.robot import load_robot
from nlo_lab.training import new_model


@pytest.fixture(scope="module")
def nao():
    return load_robot("nao")


@pytest.fixture(scope="module")
def setup(nao, demonstration_from_robot, random_feasible_pose):
    torch.manual_seed(0)
    model = new_model(nao)
    q = random_feasible_pose(nao, 6, seed=11)
    targets = targets_from_demonstration(demonstration_from_robot(nao, q))
    return model, targets


@pytest.fixture(scope="module")
def features(nao, demonstration_from_robot, random_feasible_pose):
    """The encoder's input of the same frames as ``setup``'s targets."""
    return encoder_input(demonstration_from_robot(nao, random_feasible_pose(nao, 6, seed=11)))


@pytest.mark.parametrize(
    "kwargs, word",
    [({"init": "best"}, "init"), ({"iterations": -1}, "iterations"), ({"patience": 0}, "patience"), ({"lr": 0}, "lr"),
     ({"latent_sigma": -1.0}, "latent_sigma"), ({"collision_form": "x"}, "collision_form"), ({"iterations": 2.5}, "iterations")],
)
def test_optimize_settings_are_validated(kwargs, word):
    with pytest.raises(SettingsError, match=word):
        OptimizeSettings(**kwargs)


@pytest.mark.parametrize("kwargs, word", [({"init": "random"}, "init"), ({"limits": "soft"}, "limits"), ({"penalty": 0}, "penalty")])
def test_joint_settings_are_validated(kwargs, word):
    with pytest.raises(SettingsError, match=word):
        JointOptimizeSettings(**kwargs)


def test_gradients_reach_z_through_the_frozen_decoder(nao, setup):
    model, targets = setup
    z = torch.zeros(len(targets), *model.latent_shape, requires_grad=True)
    total, _ = objective(nao, model.decode(z), targets)
    total.sum().backward()
    assert z.grad is not None and torch.isfinite(z.grad).all() and float(z.grad.abs().sum()) > 0


@pytest.mark.parametrize("init", ["encoder", "zeros", "random", "train-stats"])
def test_latent_optimisation_lowers_the_objective(nao, setup, features, init):
    model, targets = setup
    weights = LossWeights(smooth=0.0)  # the paper's objective: frames independent (smoothing: test_smoothness.py)
    z0 = initial_latent(model, features, OptimizeSettings(init=init))
    with torch.no_grad():
        start, _ = objective(nao, model.decode(z0), targets, weights)
        start = start + latent_loss(z0)
    result = optimize_latent(model, nao, targets, OptimizeSettings(init=init, iterations=100), weights=weights, encoder_input=features)
    assert result.history[0] == pytest.approx(float(start.mean()), rel=1e-5)
    assert min(result.history) < 0.7 * result.history[0]
    assert (result.loss <= start + 1e-6).all()  # the best point is kept per frame
    # The returned q and z are the best point: re-evaluating gives the reported loss and terms.
    with torch.no_grad():
        total, terms = objective(nao, model.decode(result.z), targets, weights)
    torch.testing.assert_close(result.q, model.decode(result.z))
    torch.testing.assert_close(total + latent_loss(result.z), result.loss)
    for k, v in terms.items():
        torch.testing.assert_close(v, result.terms[k])
    assert result.q.shape == (len(targets), nao.n_joints)
    assert (result.q >= nao.lower_limits).all() and (result.q <= nao.upper_limits).all()
    assert len(result.history) == result.iterations + 1 and result.seconds > 0


def test_decoder_stays_frozen_and_untouched(nao, setup):
    model, targets = setup
    model.zero_grad(set_to_none=True)  # earlier tests may have left gradients
    before = {k: v.clone() for k, v in model.state_dict().items()}
    optimize_latent(model, nao, targets, OptimizeSettings(init="zeros", iterations=5))
    for k, v in model.state_dict().items():
        torch.testing.assert_close(v, before[k])
    assert all(p.grad is None for p in model.parameters())
    assert all(p.requires_grad for p in model.parameters())  # restored afterwards


def test_patience_stops_after_evaluations_without_improvement():
    x0 = torch.zeros(3, 2)
    def evaluate(x):  # flat loss: never improves
        return x.sum(-1) * 0 + 1.0, x, {}

    *_, history, steps = descend(x0, evaluate, None, iterations=100, patience=4, lr=0.1, callback=None)
    assert steps == 4 and len(history) == 5
    def evaluate(x):  # a bowl: keeps improving
        return (x - 3).pow(2).sum(-1), x, {}

    *_, history, steps = descend(x0, evaluate, None, iterations=20, patience=4, lr=0.1, callback=None)
    assert steps == 20 and history[-1] < history[0]


def test_initialisations(nao, setup, features):
    model, targets = setup
    T = len(targets)
    zeros = initial_latent(model, targets, OptimizeSettings(init="zeros"))
    assert zeros.shape == (T, *model.latent_shape) and float(zeros.abs().max()) == 0
    r1 = initial_latent(model, targets, OptimizeSettings(init="random", seed=3, latent_sigma=2.0))
    r2 = initial_latent(model, targets, OptimizeSettings(init="random", seed=3, latent_sigma=2.0))
    r3 = initial_latent(model, targets, OptimizeSettings(init="random", seed=4, latent_sigma=2.0))
    torch.testing.assert_close(r1, r2)
    assert not torch.allclose(r1, r3)
    assert 1.5 < float(r1.std()) < 2.5
    with torch.no_grad():
        model.latent_mean.fill_(5.0)
        model.latent_std.fill_(1e-3)
    try:
        ts = initial_latent(model, targets, OptimizeSettings(init="train-stats"))
        assert float((ts - 5.0).abs().max()) < 0.01
    finally:
        with torch.no_grad():
            model.latent_mean.zero_()
            model.latent_std.fill_(1.0)
    enc = initial_latent(model, features, OptimizeSettings(init="encoder"))
    torch.testing.assert_close(enc, model.encode(features.node_features, features.edge_features))
    # the loss targets do not carry the encoder's input: the encoder start asks for it
    assert not hasattr(targets, "node_features")
    with pytest.raises(SettingsError, match="encoder_input"):
        initial_latent(model, targets, OptimizeSettings(init="encoder"))
    with pytest.raises(SettingsError, match="encoder_input"):
        optimize_latent(model, nao, targets, OptimizeSettings(iterations=0))


def test_z0_overrides_init_and_is_checked(nao, setup):
    model, targets = setup
    z0 = torch.full((len(targets), *model.latent_shape), 0.5)
    r = optimize_latent(model, nao, targets, OptimizeSettings(iterations=0), z0=z0)
    torch.testing.assert_close(r.z, z0)
    assert r.iterations == 0 and r.init == "given"
    with pytest.raises(SettingsError, match="z0"):
        optimize_latent(model, nao, targets, OptimizeSettings(iterations=0), z0=z0[:2])


def test_stream_warm_start_chains_frames(nao, setup):
    model, targets = setup
    settings = OptimizeSettings(init="random", iterations=0, seed=1)
    cold = optimize_stream(model, nao, targets, OptimizeSettings(init="random", iterations=0, seed=1, warm_start=False))
    warm = optimize_stream(model, nao, targets, settings)
    # No steps: cold frames keep their own draws, warm frames all inherit frame 0's latent.
    torch.testing.assert_close(cold.z, initial_latent(model, targets, settings))
    for t in range(1, len(targets)):
        torch.testing.assert_close(warm.z[t], warm.z[0])
    stepped = optimize_stream(model, nao, targets, OptimizeSettings(init="zeros", iterations=3))
    assert stepped.q.shape == (len(targets), nao.n_joints) and stepped.iterations > 0


@pytest.mark.parametrize("limits", ["clamp", "penalty"])
def test_joint_space_baseline(nao, setup, limits):
    _, targets = setup
    r = optimize_joints(nao, targets, JointOptimizeSettings(iterations=40, limits=limits, lr=0.05))
    assert r.z is None and r.q.shape == (len(targets), nao.n_joints)
    assert min(r.history) < 0.7 * r.history[0]
    if limits == "clamp":
        assert (r.q >= nao.lower_limits).all() and (r.q <= nao.upper_limits).all()
    starts = {
        "neutral": nao.neutral_q,  # the default
        "midpoint": (nao.lower_limits + nao.upper_limits) / 2,
        "zeros": torch.zeros_like(nao.lower_limits).clamp(nao.lower_limits, nao.upper_limits),
    }
    assert JointOptimizeSettings().init == "neutral"
    for init, q0 in starts.items():
        start = optimize_joints(nao, targets, JointOptimizeSettings(iterations=0, init=init))
        torch.testing.assert_close(start.q, q0.expand(len(targets), -1))


def test_float64_end_to_end(setup):
    robot = load_robot("nao").to(dtype=torch.float64)
    model, targets = setup
    model64 = new_model(robot).double()
    r = optimize_latent(model64, robot, targets.to(dtype=torch.float64), OptimizeSettings(init="zeros", iterations=3))
    assert r.q.dtype == torch.float64 and r.z.dtype == torch.float64


def test_hand_written_adam_equals_torch_adam():
    from nlo_lab.inference import Adam as _Adam

    g = torch.Generator().manual_seed(10)
    x0 = torch.randn(4, 3, 2, generator=g, dtype=torch.float64)
    a, b = x0.clone(), x0.clone().requires_grad_(True)
    ours, ref = _Adam(a, lr=0.01), torch.optim.Adam([b], lr=0.01)
    for _ in range(25):
        grad = torch.randn(4, 3, 2, generator=g, dtype=torch.float64) * 10
        ours.update(a, grad)
        b.grad = grad.clone()
        ref.step()
    torch.testing.assert_close(a, b.detach(), atol=0, rtol=0)

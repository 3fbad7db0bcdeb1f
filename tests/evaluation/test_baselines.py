"""The method and its baselines (nlo_lab.evaluation.methods, nlo_lab.training.supervised): shapes, limits, IK round trip, NN determinism."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.evaluation import METHODS, BaselineSettings, ik_wrists, run_method, wrist_positions
from nlo_lab.inference import RetargetInputs
from nlo_lab.metrics import limit_violations
from nlo_lab.model import encoder_input
from nlo_lab.objective import LossWeights
from nlo_lab.robot import load_robot
from nlo_lab.training import SupervisedSettings, new_model, train_supervised_model, train_supervised_net

FAST = BaselineSettings(iterations=3, ik_iterations=5, supervised=SupervisedSettings(epochs=2, hidden=(16,)))


@pytest.fixture(scope="module", params=["nao", "yumi"])
def case(request, demonstration_from_robot, random_feasible_pose):
    robot = load_robot(request.param)
    q = random_feasible_pose(robot, 6, seed=3)
    demo = demonstration_from_robot(robot, q)
    torch.manual_seed(0)
    model = new_model(robot)  # untrained: the interface, not the quality, is under test
    net = train_supervised_net(robot, encoder_input(demo).node_features, q, FAST.supervised)
    return robot, demo, model, net


@pytest.mark.parametrize("method", METHODS)
def test_every_method_returns_angles_inside_the_limits(case, method):
    robot, demo, model, net = case
    r = run_method(method, robot, demo, FAST, model=model, network=net)
    assert r.method == method
    assert r.angles.shape == (len(demo), robot.n_joints)
    assert r.angles.dtype == np.float64 and np.isfinite(r.angles).all()
    assert limit_violations(robot, r.angles) == 0
    assert r.seconds > 0


def test_ik_clamps_an_unreachable_target_into_the_limits():
    robot = load_robot("nao")
    far = torch.tensor([[[2.0, 1.0, 1.5], [2.0, -1.0, -1.5]]])  # metres away from a 0.2 m arm
    q, steps = ik_wrists(robot, far, iterations=20)
    assert steps == 20
    assert limit_violations(robot, q.numpy()) == 0
    assert (q <= robot.upper_limits).all() and (q >= robot.lower_limits).all()
    # and it moved towards the target: closer than from the neutral pose
    d0 = (wrist_positions(robot, robot.neutral_q[None]) - far).norm(dim=-1).sum()
    d1 = (wrist_positions(robot, q) - far).norm(dim=-1).sum()
    assert d1 < d0


@pytest.mark.parametrize("name", ["nao", "pepper", "yumi"])
def test_ik_recovers_the_wrists_of_a_random_pose(name, random_feasible_pose):
    robot = load_robot(name)
    q = random_feasible_pose(robot, 16, seed=7)
    with torch.no_grad():
        target = wrist_positions(robot, q)  # (16, 2, 3) reachable by construction
    start = (wrist_positions(robot, robot.neutral_q[None].expand(16, -1)) - target).norm(dim=-1)
    q_ik, _ = ik_wrists(robot, target, iterations=100)
    err = (wrist_positions(robot, q_ik) - target).norm(dim=-1)  # (16, 2) [m]
    assert float(start.median()) > 0.05  # the start really is far away
    assert float(err.median()) < 1e-3
    assert float((err < 5e-3).float().mean()) >= 0.8  # a few YuMi frames may end on a limit
    assert limit_violations(robot, q_ik.numpy()) == 0


def test_ik_ignores_masked_wrists(random_feasible_pose):
    robot = load_robot("nao")
    q = random_feasible_pose(robot, 4, seed=1)
    with torch.no_grad():
        target = wrist_positions(robot, q)
    target[:, 1] = float("nan")  # right wrist unobserved
    q_ik, _ = ik_wrists(robot, target, iterations=60)
    err = (wrist_positions(robot, q_ik)[:, 0] - target[:, 0]).norm(dim=-1)
    assert torch.isfinite(q_ik).all()
    assert float(err.max()) < 1e-3


def test_supervised_network_is_deterministic_from_its_seed(demonstration_from_robot, random_feasible_pose):
    robot = load_robot("nao")
    q = random_feasible_pose(robot, 32, seed=5)
    x = encoder_input(demonstration_from_robot(robot, q)).node_features
    s = SupervisedSettings(epochs=3, hidden=(32,), batch_size=8, seed=11)
    a = train_supervised_net(robot, x, q, s)
    b = train_supervised_net(robot, x, q, s)
    c = train_supervised_net(robot, x, q, dataclasses.replace(s, seed=12))
    for (ka, va), (kb, vb) in zip(a.state_dict().items(), b.state_dict().items(), strict=True):
        assert ka == kb and torch.equal(va, vb)
    assert not torch.equal(a(x), c(x))
    assert a.info["history"][-1] < a.info["history"][0]  # it learns


def test_supervised_model_training_fits_the_labels(demonstration_from_robot, random_feasible_pose):
    robot = load_robot("nao")
    q = random_feasible_pose(robot, 16, seed=2)
    x = encoder_input(demonstration_from_robot(robot, q))
    torch.manual_seed(0)
    model = new_model(robot)
    history = train_supervised_model(model, x, q, epochs=8, batch_size=8, seed=0)
    assert history[-1] < 0.5 * history[0]
    assert not model.training


@pytest.mark.parametrize(
    "kwargs, word",
    [({"iterations": -1}, "iterations"), ({"random_sigma": 0}, "random_sigma"), ({"ik_damping": float("nan")}, "ik_damping"), ({"supervised": 3}, "supervised")],
)
def test_settings_are_validated(kwargs, word):
    with pytest.raises(SettingsError, match=word):
        BaselineSettings(**kwargs)


def test_unknown_method_is_refused():
    robot = load_robot("nao")
    with pytest.raises(SettingsError, match="unknown method 'magic'"):
        run_method("magic", robot, None)


def test_table3_variants_train_and_stay_inside_the_limits(demonstration_from_robot, random_feasible_pose):
    from nlo_lab.training import VARIANTS, train_variant

    robot = load_robot("nao")
    q = random_feasible_pose(robot, 16, seed=4)
    data = RetargetInputs.from_demonstration(demonstration_from_robot(robot, q))
    for name in VARIANTS:
        model, seconds, steps = train_variant(robot, name, data, q, 0.2)
        assert steps >= 1 and seconds > 0
        out = model.decode(model.encode(data.encoder.node_features, data.encoder.edge_features))
        assert limit_violations(robot, out.detach().numpy()) == 0
    paper = LossWeights.paper()  # Table III trains the FK variants on the paper's objective
    model, _, _ = train_variant(robot, "GAE+FK", data, q, steps=2, weights=paper)
    assert model.train_info["weights"] == paper.as_dict() != LossWeights().as_dict()
    with pytest.raises(SettingsError, match="unknown variant"):
        train_variant(robot, "VAE", data, q, 0.1)
    with pytest.raises(SettingsError, match="needs labels"):
        train_variant(robot, "GAE", data, None, 0.1)

"""The descent's step rules (Adam, Rprop), which one runs where, and the budgets that follow from it."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import nlo_lab.inference.latent as latent_module
from nlo_lab.errors import SettingsError
from nlo_lab.evaluation import BaselineSettings
from nlo_lab.inference import (
    PAPER_ITERATIONS,
    PAPER_LR,
    PAPER_PATIENCE,
    RPROP_LR,
    SMOOTH_LR,
    Adam,
    OptimizeSettings,
    Rprop,
    descend,
)
from nlo_lab.pipeline import RetargetConfig
from nlo_lab.settings import ITERATIONS_RANGE, LATENT_ITERATIONS
from nlo_lab.training import new_model


@pytest.mark.parametrize("kind", ["tensor", "array"])
def test_rprop_steps_grow_while_the_sign_holds_and_halve_where_it_flips(kind):
    as_kind = (lambda v: torch.tensor(v, dtype=torch.float64)) if kind == "tensor" else (lambda v: np.array(v, dtype=np.float64))
    x = as_kind([0.0, 0.004])
    rprop = Rprop(x, 0.005)
    moves = []
    for _ in range(4):
        before = [float(v) for v in x]
        # coordinate 0: a far minimum at 10 (the sign holds); coordinate 1: a minimum at 0 it steps over
        rprop.update(x, as_kind([2 * (float(x[0]) - 10.0), 2 * float(x[1])]))
        moves.append([float(a) - b for a, b in zip(x, before, strict=True)])
    moves = np.array(moves)
    np.testing.assert_allclose(moves[:, 0], [0.005, 0.006, 0.0072, 0.00864], rtol=1e-12)  # x 1.2 per step
    # 0.004 -> -0.001 (over the minimum); the sign flipped: the step halves to 0.0025 and waits; -> 0.0015 (over
    # it again): halves to 0.00125 and waits
    np.testing.assert_allclose(moves[:, 1], [-0.005, 0.0, 0.0025, 0.0], rtol=1e-12)
    np.testing.assert_allclose(float(rprop.step_size[1]), 0.00125, rtol=1e-12)


def test_rprop_steps_stay_within_their_bounds():
    x = torch.zeros(1, dtype=torch.float64)
    rprop = Rprop(x, 0.005, max_step=0.1)
    for _ in range(40):  # a minimum 100 away: the step grows to its cap and stays there
        rprop.update(x, 2 * (x - 100.0))
    assert float(rprop.step_size[0]) == pytest.approx(0.1)
    before = float(x[0])
    rprop.update(x, 2 * (x - 100.0))
    assert float(x[0]) - before == pytest.approx(0.1)


def test_rprop_travels_where_adam_crawls():
    """Why a recording runs Rprop: a latent that must move far (an arm leaving a self-collision) gets there in a
    few dozen steps; Adam's steps stay at about ``lr``."""

    def bowl(x):
        loss = (x - 1.0).pow(2).sum(1)
        return loss, x, loss[:, None]

    start = torch.zeros(2, 3, dtype=torch.float64)
    rprop = descend(start, bowl, None, 30, 31, RPROP_LR, None, stepper="rprop")
    adam = descend(start, bowl, None, 30, 31, RPROP_LR, None, stepper="adam")
    assert float((rprop[0] - 1).abs().max()) < 0.05
    assert float(adam[0].max()) < 0.2  # 30 steps of about 0.005


def test_unknown_step_rule_is_refused():
    with pytest.raises(SettingsError, match="stepper"):
        OptimizeSettings(stepper="sgd")
    with pytest.raises(SettingsError, match="stepper"):
        descend(torch.zeros(1, 1), lambda x: (x.sum(1), x, {}), None, 1, 1, 0.1, None, stepper="sgd")


def test_the_step_rule_follows_the_coupling():
    default = OptimizeSettings()
    assert default.iterations == LATENT_ITERATIONS == 40 and default.patience == PAPER_PATIENCE
    # a recording (frames coupled by the smoothness term): Rprop over the whole budget
    assert default.step_rule(coupled=True) == ("rprop", RPROP_LR, ITERATIONS_RANGE[1] + 1)
    # a frame alone, or the paper's objective: Adam with its patience stop
    assert default.step_rule(coupled=False) == ("adam", PAPER_LR, PAPER_PATIENCE)
    assert OptimizeSettings(stepper="adam").step_rule(coupled=True) == ("adam", SMOOTH_LR, PAPER_PATIENCE)
    assert OptimizeSettings(stepper="rprop", lr=0.02).step_rule(coupled=False)[:2] == ("rprop", 0.02)
    paper = OptimizeSettings.paper()
    assert (paper.iterations, paper.patience, paper.step_rule(coupled=False)) == (PAPER_ITERATIONS, PAPER_PATIENCE, ("adam", PAPER_LR, 5))
    assert OptimizeSettings.paper(init="zeros").init == "zeros"


@pytest.mark.parametrize("stepper, stops", [("adam", True), ("rprop", False)])
def test_patience_stops_adam_and_not_rprop(stepper, stops):
    """Rprop's loss rises for a while once its steps have grown, then falls below its earlier best: the patience
    stop would end it on the rise. A loss that rises for more than ``patience`` evaluations and then falls: Adam
    (the paper's rule) must stop there, Rprop must run its whole budget."""
    _, lr, patience = OptimizeSettings(stepper=stepper).step_rule(coupled=True)
    calls = []

    def rises_then_falls(x):
        calls.append(None)
        level = [10.0, 11, 12, 13, 14, 15, 16, 17, 5, 4, 3, 2, 1][min(len(calls) - 1, 12)]
        return x.sum(1) * 0 + level, x, {}

    *_, history, steps = descend(torch.zeros(2, 2), rises_then_falls, None, 12, patience, lr, None, per_sample=False, stepper=stepper)
    assert (steps, min(history)) == ((PAPER_PATIENCE, 10.0) if stops else (12, 1.0))


@pytest.fixture(scope="module")
def nao_model(nao):
    torch.manual_seed(0)
    return new_model(nao)


def test_a_recording_runs_rprop_and_a_frame_alone_adam(nao, nao_model, make_demo, monkeypatch):
    seen = []
    real = latent_module.descend

    def spy(*args, **kwargs):
        seen.append((kwargs["stepper"], args[3]))  # the step rule, the budget
        return real(*args, **kwargs)

    monkeypatch.setattr(latent_module, "descend", spy)
    retargeter = RetargetConfig(nao, OptimizeSettings(iterations=6), model=nao_model).build()
    demo = make_demo(T=5)
    result = retargeter(demo)
    assert seen == [("rprop", 6)] and result.optimization.iterations == 6  # smoothing couples the frames: the whole budget
    retargeter.optimize_frame(retargeter.inputs(demo), 2)
    assert seen[-1] == ("adam", 6)


def test_evaluation_budgets_follow_the_mode():
    robot_ready, paper = BaselineSettings(), BaselineSettings(mode="paper")
    assert (robot_ready.latent_iterations, robot_ready.joint_iterations) == (LATENT_ITERATIONS, 100)
    assert (paper.latent_iterations, paper.joint_iterations) == (PAPER_ITERATIONS, 100)
    given = BaselineSettings(iterations=7)
    assert (given.latent_iterations, given.joint_iterations) == (7, 7)
    with pytest.raises(SettingsError, match="iterations"):
        BaselineSettings(iterations=-1)


def test_adam_is_the_paper_arithmetic():
    """The Adam step unchanged by the step-rule choice: torch.optim.Adam's numbers."""
    x = torch.tensor([0.3, -1.0], dtype=torch.float64)
    ref = x.clone().requires_grad_(True)
    opt = torch.optim.Adam([ref], lr=0.01)
    adam = Adam(x, 0.01)
    for _ in range(5):
        g = 2 * (x - 2.0)
        adam.update(x, g)
        ref.grad = 2 * (ref.detach() - 2.0)
        opt.step()
    torch.testing.assert_close(x, ref.detach())

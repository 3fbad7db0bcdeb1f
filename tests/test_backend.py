"""nlo_lab.backend: the one switch. Each fast path equals its reference (values and
gradients, float64), and reference() really routes every computation to the readable code."""

from __future__ import annotations

import pytest
import torch

from nlo_lab import backend
from nlo_lab.errors import SettingsError
from nlo_lab.robot import load_robot

ROBOTS = ("yumi", "nao", "pepper")


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request):
    return load_robot(request.param).to(dtype=torch.float64)


def random_q(robot, batch: int, seed: int) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    u = torch.rand(batch, robot.n_joints, generator=g, dtype=torch.float64)
    return robot.lower_limits + u * (robot.upper_limits - robot.lower_limits)


def _raise(*args, **kwargs):
    raise AssertionError("a fast path ran under backend.reference()")


def value_and_grad(f, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    x = x.detach().clone().requires_grad_(True)
    y = f(x)
    w = torch.linspace(0.5, 1.5, y.numel(), dtype=y.dtype).view_as(y)  # every output counts, differently
    (g,) = torch.autograd.grad((y * w).sum(), x)
    return y.detach(), g


def fast_and_reference(f, x):
    fast = value_and_grad(f, x)
    with backend.reference():
        ref = value_and_grad(f, x)
    return fast, ref


def assert_same(fast, ref, atol=1e-10):
    for a, b in zip(fast, ref, strict=True):
        torch.testing.assert_close(a, b, atol=atol, rtol=1e-10)


# ----------------------------------------------------------------- the switch
def test_use_changes_the_setting_inside_the_block_only():
    before = backend.current()
    with backend.use(objective_max_frames=0) as b:
        assert backend.current() is b and b.objective_max_frames == 0
        assert not backend.numpy_objective(1)
        assert backend.numpy_decoder(1)  # the others as before
    assert backend.current() == before
    with pytest.raises(RuntimeError):
        with backend.reference():
            assert not backend.current().enabled
            raise RuntimeError("inside")
    assert backend.current() == before  # restored on an error too


def test_reference_turns_every_fast_path_off_at_any_size():
    with backend.reference():
        assert not any(
            (backend.numpy_objective(1), backend.numpy_decoder(1), backend.numpy_collision(1), backend.fk_pointer_jumping(1),
             backend.analytic_fk_gradient(), backend.cull_far_pairs())
        )
    assert all((backend.numpy_objective(1), backend.numpy_decoder(1), backend.numpy_collision(1), backend.fk_pointer_jumping(1),
                backend.analytic_fk_gradient(), backend.cull_far_pairs()))


def test_thresholds_are_inclusive_sizes():
    with backend.use(objective_max_frames=4, decoder_max_batch=2, collision_numpy_max_pairs=10, fk_jump_max_work=6):
        assert backend.numpy_objective(4) and not backend.numpy_objective(5)
        assert backend.numpy_decoder(2) and not backend.numpy_decoder(3)
        assert backend.numpy_collision(10) and not backend.numpy_collision(11)
        assert backend.fk_pointer_jumping(6) and not backend.fk_pointer_jumping(7)


@pytest.mark.parametrize("changes", [{"objective_max_frames": -1}, {"decoder_max_batch": 2.5}, {"fk_jump_max_work": True}, {"enabled": 1}, {"speed": 3}])
def test_bad_settings_are_refused_in_one_line(changes):
    before = backend.current()
    with pytest.raises(SettingsError) as info:
        with backend.use(**changes):
            pass
    assert "\n" not in str(info.value) and next(iter(changes)) in str(info.value)
    assert backend.current() == before


# ----------------------------------------------------------------- FK
def test_fk_pointer_jumping_equals_level_by_level(robot):
    q = random_q(robot, 3, seed=1)
    with backend.use(fk_jump_max_work=10**9):  # pointer jumping whatever the size
        fast = value_and_grad(robot.forward_kinematics_tensor, q)
    with backend.reference():
        ref = value_and_grad(robot.forward_kinematics_tensor, q)
    assert_same(fast, ref)


def test_reference_fk_composes_level_by_level(robot, monkeypatch):
    from nlo_lab.robot.kinematics import KinematicTree

    monkeypatch.setattr(KinematicTree, "_compose_by_jumps", _raise)
    q = random_q(robot, 1, seed=2)
    with backend.reference():
        robot.forward_kinematics_tensor(q)
    with pytest.raises(AssertionError, match="fast path"):  # the fast path is the default at batch 1
        robot.forward_kinematics_tensor(q)


def test_mapped_points_analytic_gradient_equals_autograd(robot):
    links = [robot.arm(s).wrist for s in ("left", "right")] + [robot.root_link]
    body, vec = robot.point_map(links, torch.tensor([[0.1, 0.0, 0.02, 1.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.1, 0.0, 1.0]]).numpy())
    body, vec = torch.as_tensor(body), torch.as_tensor(vec)
    fast, ref = fast_and_reference(lambda q: robot.map_points(q, body, vec), random_q(robot, 4, seed=3))
    assert_same(fast, ref)


def test_reference_mapped_points_use_autograd(robot, monkeypatch):
    from nlo_lab.robot import point_gradient

    monkeypatch.setattr(point_gradient.MapPoints, "apply", _raise)
    body, vec = robot.point_map([robot.arm("left").wrist], [[0.0, 0.0, 0.0, 1.0]])
    q = random_q(robot, 2, seed=4).requires_grad_(True)
    with backend.reference():
        robot.map_points(q, torch.as_tensor(body), torch.as_tensor(vec)).sum().backward()
    with pytest.raises(AssertionError, match="fast path"):
        robot.map_points(q, torch.as_tensor(body), torch.as_tensor(vec))


# ----------------------------------------------------------------- collision
def test_collision_numpy_equals_torch(robot):
    q = random_q(robot, 5, seed=5)
    fast, ref = fast_and_reference(lambda x: robot.capsule_distances(robot.forward_kinematics_tensor(x)), q)
    assert_same(fast, ref)
    assert float(ref[1].abs().max()) > 0


def test_reference_collision_runs_in_torch(robot, monkeypatch):
    from nlo_lab.robot import collision

    monkeypatch.setattr(collision, "_distance_parts_numpy", _raise)
    T = robot.forward_kinematics_tensor(random_q(robot, 2, seed=6))
    with backend.reference():
        robot.capsule_distances(T)
    with pytest.raises(AssertionError, match="fast path"):
        robot.capsule_distances(T)


# ----------------------------------------------------------------- objective
def _objective_case(robot, frames=4):
    """Targets the robot meets at one pose, and other (random, some colliding) poses to score."""
    from robot_targets import demonstration_from_robot

    from nlo_lab.objective import targets_from_demonstration

    t = targets_from_demonstration(demonstration_from_robot(robot, random_q(robot, frames, seed=9)), dtype=torch.float64)
    return t, random_q(robot, frames, seed=7)


def test_objective_numpy_terms_equal_torch_ops(robot):
    from nlo_lab.objective import Objective

    t, q = _objective_case(robot)
    for form in ("hinge", "paper"):
        fast = value_and_grad(lambda x, form=form: Objective(robot, t, collision_form=form)(x)[1], q)
        with backend.reference():
            ref = value_and_grad(lambda x, form=form: Objective(robot, t, collision_form=form)(x)[1], q)
        assert_same(fast, ref, atol=1e-9)


def test_reference_objective_runs_the_term_functions(robot, monkeypatch):
    """Under reference() every term function of nlo_lab.objective.terms runs, and the numpy terms do not."""
    from nlo_lab.objective import terms
    from nlo_lab.objective import total as module

    names = ("end_effector_loss", "orientation_loss", "elbow_loss", "finger_loss", "collision_loss", "capsule_distances")
    calls = []
    for name in names:
        fn = getattr(terms, name)
        monkeypatch.setattr(module, name, lambda *a, _fn=fn, **k: calls.append(_fn.__name__) or _fn(*a, **k))
    monkeypatch.setattr(module, "point_terms", _raise)
    t, q = _objective_case(robot)
    with backend.reference():
        module.Objective(robot, t)(q)
    assert sorted(calls) == sorted(names)
    with pytest.raises(AssertionError, match="fast path"):
        module.Objective(robot, t)(q)


def test_objective_culling_far_pairs_equals_every_pair(robot):
    """The torch path (many frames) measures only the pairs that may be near; the reference measures all."""
    from nlo_lab.objective import Objective

    t, q = _objective_case(robot, frames=48)
    for form in ("hinge", "paper"):
        fast = value_and_grad(lambda x, form=form: Objective(robot, t, collision_form=form, fused=False)(x)[1], q)
        with backend.reference():
            ref = value_and_grad(lambda x, form=form: Objective(robot, t, collision_form=form)(x)[1], q)
        assert_same(fast, ref, atol=1e-9)
        assert float(ref[0][:, 4].max()) > 0, "some random poses should bring capsules within their margin"


def test_reference_objective_measures_every_pair(robot, monkeypatch):
    from nlo_lab.objective import total as module

    monkeypatch.setattr(module, "near_pair_distances", _raise)
    t, q = _objective_case(robot)
    with backend.reference():
        module.Objective(robot, t)(q)
    with pytest.raises(AssertionError, match="fast path"):
        module.Objective(robot, t, fused=False)(q)


# ----------------------------------------------------------------- decoder
def _frozen_decoder(robot):
    from nlo_lab.model import GraphDecoder

    torch.manual_seed(0)
    dec = GraphDecoder(robot.graph, robot.lower_limits, robot.upper_limits, latent_per_node=3, widths=(16, 8, 1)).to(torch.float64)
    for p in dec.parameters():
        p.requires_grad_(False)
    return dec


def test_decoder_numpy_layers_equal_torch(robot):
    dec = _frozen_decoder(robot)
    z = 2 * torch.randn(3, robot.n_joints, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(8))
    fast, ref = fast_and_reference(dec, z)
    assert_same(fast, ref)


def test_decoder_node_major_layers_equal_the_paper_form(robot):
    """Above the numpy batch (and while training) the decoder runs folded node-major weights: same map."""
    dec = _frozen_decoder(robot)
    z = 2 * torch.randn(12, robot.n_joints, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(9))
    with backend.use(decoder_max_batch=0):
        fast = value_and_grad(dec, z)
    with backend.reference():
        ref = value_and_grad(dec, z)
    assert_same(fast, ref)


def test_reference_decoder_runs_the_paper_layers(robot, monkeypatch):
    from nlo_lab.model import decoder
    from nlo_lab.model.layers import GraphLayer

    dec = _frozen_decoder(robot)
    z = torch.zeros(1, robot.n_joints, 3, dtype=torch.float64)
    calls = []
    paper_forward = GraphLayer.forward
    monkeypatch.setattr(GraphLayer, "forward", lambda self, *a: calls.append(self) or paper_forward(self, *a))
    monkeypatch.setattr(decoder, "decode_numpy", _raise)
    monkeypatch.setattr(GraphLayer, "forward_node_major", _raise)
    with backend.reference():
        dec(z)
        dec.preactivation(z)
    assert calls == list(dec.layers) * 2  # every layer in its paper form, in order
    with pytest.raises(AssertionError, match="fast path"):
        dec(z)

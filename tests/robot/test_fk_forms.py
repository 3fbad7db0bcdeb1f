"""FK's faster forms equal its readable one (values and gradients, float64), and FK called
without asking composes level by level with autograd through it."""

from __future__ import annotations

import pytest
import torch


@pytest.fixture(scope="module")
def robot(each_robot64):
    return each_robot64


def value_and_grad(f, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    x = x.detach().clone().requires_grad_(True)
    y = f(x)
    w = torch.linspace(0.5, 1.5, y.numel(), dtype=y.dtype).view_as(y)  # every output counts, differently
    (g,) = torch.autograd.grad((y * w).sum(), x)
    return y.detach(), g


def _raise(*args, **kwargs):
    raise AssertionError("a fast path ran")


def _wrist_points(robot):
    links = [robot.arm(s).wrist for s in ("left", "right")] + [robot.root_link]
    body, vec = robot.point_map(links, torch.tensor([[0.1, 0.0, 0.02, 1.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.1, 0.0, 1.0]]).numpy())
    return torch.as_tensor(body), torch.as_tensor(vec)


def test_pointer_jumping_equals_level_by_level_with_gradients(robot, random_angles):
    q = random_angles(robot, 3, seed=1)
    fast = value_and_grad(lambda x: robot.tree.body_poses(x, compose="jumps"), q)
    ref = value_and_grad(lambda x: robot.tree.body_poses(x, compose="levels"), q)
    for a, b in zip(fast, ref, strict=True):
        torch.testing.assert_close(a, b, atol=1e-10, rtol=1e-10)


def test_mapped_points_analytic_gradient_equals_autograd(robot, random_angles):
    body, vec = _wrist_points(robot)
    q = random_angles(robot, 4, seed=3)
    fast = value_and_grad(lambda x: robot.map_points(x, body, vec, analytic_gradient=True), q)
    ref = value_and_grad(lambda x: robot.map_points(x, body, vec), q)
    for a, b in zip(fast, ref, strict=True):
        torch.testing.assert_close(a, b, atol=1e-10, rtol=1e-10)
    assert float(ref[1].abs().max()) > 0


def test_fk_called_directly_is_the_readable_form(robot, random_angles, monkeypatch):
    """Without an argument: level by level, and autograd differentiates through it."""
    from nlo_lab.robot import point_gradient
    from nlo_lab.robot.kinematics import KinematicTree

    monkeypatch.setattr(KinematicTree, "_compose_by_jumps", _raise)
    monkeypatch.setattr(point_gradient.MapPoints, "apply", _raise)
    body, vec = _wrist_points(robot)
    q = random_angles(robot, 1, seed=2).requires_grad_(True)
    robot.forward_kinematics_tensor(q)
    p = robot.map_points(q, body, vec)
    assert "MapPoints" not in type(p.grad_fn).__name__
    p.sum().backward()
    with pytest.raises(AssertionError, match="fast path"):  # asked for, the fast form runs
        robot.map_points(q, body, vec, analytic_gradient=True)


def test_unknown_composition_is_refused(robot, random_angles):
    with pytest.raises(ValueError, match="compose"):
        robot.tree.body_poses(random_angles(robot, 1, seed=4), compose="fast")


def test_numpy_point_map_equals_the_torch_forms(robot, random_angles):
    """NumpyPointMap (the numpy descent's FK): points and their gradient as map_points gives them."""
    import numpy as np

    from nlo_lab.robot.point_gradient import NumpyPointMap

    body, vec = _wrist_points(robot)
    q = random_angles(robot, 3, seed=6)
    ref = value_and_grad(lambda x: robot.map_points(x, body, vec), q)  # autograd through level-by-level FK
    w = torch.linspace(0.5, 1.5, ref[0].numel(), dtype=torch.float64).view_as(ref[0])
    numpy_map = NumpyPointMap(robot.tree, body.numpy(), vec.numpy(), np.float64)
    pts, state = numpy_map.forward(q.numpy())
    torch.testing.assert_close(torch.from_numpy(pts), ref[0], atol=1e-12, rtol=1e-12)
    torch.testing.assert_close(torch.from_numpy(numpy_map.backward(w.numpy(), state)), ref[1], atol=1e-10, rtol=1e-10)


def test_the_closed_form_gradient_over_some_columns_is_the_gradient_over_all(robot, random_angles):
    """MapPoints.gradient(columns=...): where g is 0 outside those points, the same gradient."""
    from nlo_lab.objective import point_plan
    from nlo_lab.robot.point_gradient import MapPoints

    plan = point_plan(robot, torch.float64, torch.device("cpu"))
    q = random_angles(robot, 5, seed=6)
    poses, pts = MapPoints.points(q, robot.tree, plan.body, plan.vectors)
    columns = torch.arange(0, pts.shape[1], 3)
    g = torch.zeros_like(pts)
    g[:, columns] = torch.randn(len(q), len(columns), 3, dtype=g.dtype, generator=torch.Generator().manual_seed(7))
    every = MapPoints.gradient(g, poses, pts, robot.tree, plan.body, plan.vectors)
    some = MapPoints.gradient(g, poses, pts, robot.tree, plan.body, plan.vectors, columns)
    torch.testing.assert_close(some, every, atol=1e-12, rtol=1e-12)
    assert float(every.abs().max()) > 0

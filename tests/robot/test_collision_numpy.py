"""The capsule distances' closest points, computed in numpy for few pairs, equal the same
function run in torch (values and gradients, float64)."""

from __future__ import annotations

import pytest
import torch

from nlo_lab.robot import collision


@pytest.mark.parametrize("name", ("yumi", "nao", "pepper"))
def test_collision_numpy_equals_torch(name, robot64, monkeypatch):
    robot = robot64(name)
    g = torch.Generator().manual_seed(5)
    frames = min(5, collision.NUMPY_MAX_PAIRS // len(robot.pair_capsules))  # few enough pairs for numpy (YuMi: 873 per frame)
    q = robot.lower_limits + torch.rand(frames, robot.n_joints, generator=g, dtype=torch.float64) * (robot.upper_limits - robot.lower_limits)

    def value_and_grad():
        x = q.clone().requires_grad_(True)
        d = robot.capsule_distances(robot.forward_kinematics_tensor(x))
        (grad,) = torch.autograd.grad((d * torch.linspace(0.5, 1.5, d.numel(), dtype=d.dtype).view_as(d)).sum(), x)
        return d.detach(), grad

    calls = []
    numpy_parts = collision._distance_parts_numpy
    monkeypatch.setattr(collision, "_distance_parts_numpy", lambda flat: calls.append(1) or numpy_parts(flat))
    fast = value_and_grad()
    assert calls, "few pairs on the CPU: numpy"
    monkeypatch.setattr(collision, "NUMPY_MAX_PAIRS", 0)
    calls.clear()
    ref = value_and_grad()
    assert not calls
    for a, b in zip(fast, ref, strict=True):
        torch.testing.assert_close(a, b, atol=1e-10, rtol=1e-10)
    assert float(ref[1].abs().max()) > 0

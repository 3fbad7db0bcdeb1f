"""Synthetic human targets made from a robot's own pose (for round-trip tests)."""

from __future__ import annotations

import numpy as np
import torch

from nlo_lab.human.demonstration import FINGERS, SIDES, Demonstration
from nlo_lab.objective import robot_points


def random_feasible_pose(robot, n: int, seed: int, margin: float = 0.15, tries: int = 50) -> torch.Tensor:
    """``(n, n_joints)`` random angles inside the limits, shrunk by ``margin`` of each
    range, without self-collision (pairs at least their d_min apart)."""
    gen = torch.Generator().manual_seed(seed)
    lo, hi = robot.lower_limits, robot.upper_limits
    out = []
    for _ in range(tries):
        u = torch.rand(4 * n, robot.n_joints, generator=gen, dtype=torch.float64).to(lo.dtype)
        q = lo + (hi - lo) * (margin + (1 - 2 * margin) * u)
        d = robot.capsule_distances(robot.forward_kinematics(q))
        ok = (d >= robot.collision_margins).all(-1)
        out.extend(q[ok])
        if len(out) >= n:
            return torch.stack(out[:n])
    raise RuntimeError(f"no collision-free pose of {robot.name} found")


def demonstration_from_robot(robot, q: torch.Tensor, fps: float = 15.0) -> Demonstration:
    """A demonstration whose every target the robot meets exactly at ``q`` (T, n)."""
    with torch.no_grad():
        pts = robot_points(robot, robot.forward_kinematics(q))
    T = q.shape[0]
    arm = torch.stack([pts["shoulder"], pts["elbow"], pts["wrist"]], dim=2).double().numpy()  # (T, 2, 3, 3)
    fingers = np.full((T, 2, 5, 2, 3), np.nan)
    fmask = np.zeros((T, 2, 5), dtype=bool)
    if robot.has_fingers:
        k = 0
        for s, side in enumerate(SIDES):
            arm_spec = robot.arm(side)
            for f, name in enumerate(FINGERS):
                if arm_spec.fingers and name in arm_spec.fingers:
                    fingers[:, s, f, 0] = pts["finger_base"][:, k].double().numpy()
                    fingers[:, s, f, 1] = pts["finger_tip"][:, k].double().numpy()
                    fmask[:, s, f] = True
                    k += 1
    return Demonstration(
        fps=fps,
        arm_positions=arm,
        arm_mask=np.ones((T, 2, 3), dtype=bool),
        wrist_rotations=pts["wrist_rotation"].double().numpy(),
        wrist_mask=np.ones((T, 2), dtype=bool),
        finger_positions=fingers,
        finger_mask=fmask,
        name=f"{robot.name}-pose",
    )

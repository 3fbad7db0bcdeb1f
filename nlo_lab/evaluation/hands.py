"""Handshape measures and the tools around them: the robot hand's chains, points and best angles.

The measures themselves (:class:`HandScores`, :func:`hand_scores`, :func:`hand_frames_mask`, :func:`angle_deg`,
their definitions) live in :mod:`nlo_lab.metrics`, below the pipeline, whose summary reports their means; they are
named here too, beside :func:`finger_chains`, :func:`hand_joint_indices`, :func:`robot_hand_points` and
:func:`best_hand_angles` (``benchmarks/hands.py``, notebook 12).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.human.demonstration import Demonstration
from nlo_lab.metrics import MEASURES, HandScores, angle_deg, hand_frames_mask, hand_scores
from nlo_lab.objective import TERMS, LossWeights, Objective, targets_from_demonstration

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = [
    "HandScores", "hand_scores", "hand_frames_mask", "angle_deg", "MEASURES",
    "finger_chains", "hand_joint_indices", "robot_hand_points", "best_hand_angles",
]

def finger_chains(robot: Robot, side: str) -> dict[str, list[str]]:
    """Per finger of ``side``, the links from the wrist link to the fingertip link (the URDF chain)."""
    arm = robot.arm(side)
    out = {}
    for name, (_, tip) in (arm.fingers or {}).items():
        chain, link = [tip], tip
        while link != arm.wrist:
            joint = robot.model.parent_joint(link)
            if joint is None:
                raise SettingsError(f"{robot.name}: fingertip {tip!r} does not hang below the wrist link {arm.wrist!r}")
            link = joint.parent
            chain.append(link)
        out[name] = chain[::-1]
    return out


def hand_joint_indices(robot: Robot, side: str) -> list[int]:
    """Indices (into ``robot.joint_names``) of the actuated joints that move the fingers of ``side``."""
    names = set()
    for chain in finger_chains(robot, side).values():
        for link in chain[1:]:
            joint = robot.model.parent_joint(link)
            if joint.moving:
                names.add(joint.mimic[0] if joint.mimic else joint.name)
    return sorted(robot.joint_names.index(n) for n in names if n in robot.joint_names)


def robot_hand_points(robot: Robot, q, side: str) -> dict[str, np.ndarray]:
    """Per finger the chain's link origins ``(T, k, 3)`` [m] in the aligned wrist frame, for ``q (T, n)``."""
    q = torch.as_tensor(np.array(q, dtype=np.float64))
    rb = robot.to(dtype=torch.float64)
    with torch.no_grad():
        poses = rb.forward_kinematics(q)
    arm = robot.arm(side)
    wrist = poses[arm.wrist].numpy()  # (T, 4, 4)
    rot = wrist[:, :3, :3] @ arm.wrist_alignment.double().numpy()
    out = {}
    for name, chain in finger_chains(robot, side).items():
        p = np.stack([poses[link].numpy()[:, :3, 3] for link in chain], axis=1)  # (T, k, 3)
        out[name] = np.einsum("tji,tkj->tki", rot, p - wrist[:, None, :3, 3])
    return out


def best_hand_angles(robot: Robot, q, demo: Demonstration, weights=None, steps: int = 200, lr: float = 0.05) -> np.ndarray:
    """The hands' joints alone optimised on the hand terms (``tip``, ``thumb``, ``pinch`` of ``weights``),
    the arms kept at ``q (T, n)``: the closest this hand comes to each handshape (Adam in joint space,
    clamped to the limits). Returns ``(T, n)`` [rad]."""
    w = weights or LossWeights()
    only = LossWeights(**({n: 0.0 for n in TERMS} | {"latent": 0.0, "smooth": 0.0, "tip": w.tip, "thumb": w.thumb, "pinch": w.pinch}))
    rb = robot.to(dtype=torch.float64)
    loss = Objective(rb, targets_from_demonstration(demo, dtype=torch.float64), only, fused=False)
    hand = torch.zeros(robot.n_joints, dtype=torch.bool)
    hand[[i for side in ("left", "right") for i in hand_joint_indices(robot, side)]] = True
    x = torch.as_tensor(np.array(q, dtype=np.float64)).requires_grad_(True)
    opt = torch.optim.Adam([x], lr=lr)
    for _ in range(steps):
        opt.zero_grad()
        loss(x)[0].sum().backward()
        x.grad[:, ~hand] = 0.0
        opt.step()
        with torch.no_grad():
            x.copy_(torch.maximum(torch.minimum(x, rb.upper_limits), rb.lower_limits))
    return x.detach().numpy()

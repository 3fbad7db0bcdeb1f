"""How closely a robot's arms point where the human's do: the angle between their directions.

For every frame and arm, the angle between the human's shoulder -> elbow direction and the
robot's, and between the shoulder -> wrist directions (both in the body / robot frame, which
share X forward, Y left, Z up). Unlike the Fréchet distance it needs no scaling between a
human and a robot of other proportions, so it compares robots of any size. The reference is
the robot standing still at its rest pose (all joints at zero, clamped into their limits):
a retargeting worth the name halves that error or better (issue 28 asks for at most 0.6 of it).
"""

from __future__ import annotations

import numpy as np
import torch

from nlo_lab.human.demonstration import SIDES

__all__ = ["direction_angles", "direction_error"]


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(n > 1e-9, v / np.maximum(n, 1e-9), np.nan)


def direction_angles(robot, demo, angles) -> np.ndarray:
    """``(T, 2, 2)`` angles [rad] per frame, side (left, right) and direction (shoulder -> elbow,
    shoulder -> wrist); NaN where the demonstration does not see the arm.

    Args:
        robot: a loaded robot; its shoulder is the objective's (``robot.shoulder_position``).
        demo: the demonstration (positions in the body frame).
        angles: ``(T, n)`` robot joint angles [rad] (or ``(n,)``: one pose for every frame).
    """
    q = robot.check_angles(angles)
    if len(q) == 1:
        q = np.repeat(q, len(demo), 0)
    links = [name for side in SIDES for name in (robot.arm(side).elbow, robot.arm(side).wrist)]
    with torch.no_grad():
        P = robot.forward_kinematics_links(torch.as_tensor(np.array(q, dtype=np.float64)), links).numpy()[..., :3, 3]  # (T, 4, 3)
    out = np.full((len(demo), 2, 2), np.nan)
    for s, side in enumerate(SIDES):
        shoulder = robot.shoulder_position(side).double().numpy()
        human = demo.arm_positions[:, s]  # (T, 3 joints, 3)
        seen = demo.arm_mask[:, s]
        for d, joint in enumerate((1, 2)):  # elbow, wrist
            h = _unit(human[:, joint] - human[:, 0])
            r = _unit(P[:, 2 * s + d] - shoulder)
            cos = np.clip((h * r).sum(-1), -1.0, 1.0)
            out[:, s, d] = np.where(seen[:, 0] & seen[:, joint], np.arccos(cos), np.nan)
    return out


def direction_error(robot, demo, angles) -> dict[str, float]:
    """The mean angle [deg] over frames, arms and both directions: of ``angles`` (``mean_deg``), of the
    rest pose (``rest_deg``), and their ratio (``ratio``; issue 28's target: at most 0.6)."""
    moved = float(np.nanmean(direction_angles(robot, demo, angles)))
    rest = float(np.nanmean(direction_angles(robot, demo, robot.reference_q.double().numpy())))
    return {"mean_deg": float(np.degrees(moved)), "rest_deg": float(np.degrees(rest)), "ratio": moved / rest if rest > 0 else float("nan")}

"""A wrist alignment derived from the robot, not asked for: ``R_wristlink_handframe`` of a drafted spec.

The human wrist frame (:mod:`nlo_lab.human.demonstration`): x from the wrist along the hand
(to the middle finger's base), y from the little finger's side to the index finger's, z = x × y
(the palm of the left hand, the back of the right). On the robot, at the rest pose:

* **with fingers**: x from the wrist link's origin to the middle finger's base (else the mean of
  the finger bases), y from the little finger's base (else ring, else middle) to the index
  finger's (else the thumb's), made square to x;
* **without**: x along the hand, i.e. along the last arm joint's axis when that joint rolls the
  hand (its axis within 45 deg of the forearm, elbow -> wrist), else along the forearm; y the
  body's midline side (the robot frame's -Y for the left hand, +Y for the right) made square to x,
  or forward (+X) when the hand points sideways: the thumb towards the body, as NAO's and
  Pepper's hands are drawn (``assets/robots/README.md``, "Wrist alignment").
"""

from __future__ import annotations

import numpy as np
import torch

from nlo_lab.errors import RobotDescriptionError

__all__ = ["wrist_alignment"]


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if n < 1e-9:
        raise RobotDescriptionError("a wrist alignment needs a direction, got a zero vector")
    return v / n


def wrist_alignment(robot, side: str, fingers: dict[str, tuple[str, str]]) -> np.ndarray:
    """``(3, 3)`` ``R_wristlink_handframe`` of ``side`` (see the module docstring).

    Args:
        robot: a ``Robot`` whose root is the robot frame.
        side: ``"left"`` or ``"right"``.
        fingers: finger -> (base, tip) links of that hand (may be empty).
    """
    with torch.no_grad():
        T = robot.forward_kinematics_tensor(robot.reference_q.double()).numpy()
    pose = {n: T[i] for i, n in enumerate(robot.link_names)}
    arm = robot.arm(side)
    W = pose[arm.wrist]
    wrist = W[:3, 3]
    bases = {f: pose[b][:3, 3] for f, (b, _) in fingers.items()}
    if len(bases) >= 2 and any(f != "thumb" for f in bases):
        ahead = bases.get("middle", np.mean([p for f, p in bases.items() if f != "thumb"], axis=0))
        x = _unit(ahead - wrist)
        index = bases.get("index", bases.get("thumb"))
        little = next((bases[f] for f in ("pinky", "ring", "middle") if f in bases and bases[f] is not index), None)
        y = (index - little) if index is not None and little is not None else None
    else:
        forearm = _unit(wrist - pose[arm.elbow][:3, 3])
        last = robot.model.parent_joint(arm.wrist)
        axis = W[:3, :3] @ last.axis if last is not None and last.type != "fixed" else None
        x = np.sign(axis @ forearm) * axis if axis is not None and abs(axis @ forearm) > np.cos(np.pi / 4) else forearm
        y = None
    if y is None or np.linalg.norm(y - (y @ x) * x) < 1e-6:
        y = np.array([0.0, -1.0 if side == "left" else 1.0, 0.0])  # the thumb towards the body's midline
        if abs(y @ x) > 0.9:
            y = np.array([1.0, 0.0, 0.0])
    y = _unit(y - (y @ x) * x)
    R_world_hand = np.stack([x, y, np.cross(x, y)], axis=1)
    return W[:3, :3].T @ R_world_hand

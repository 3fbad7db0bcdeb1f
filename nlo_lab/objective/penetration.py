"""Which frames put two capsules of the robot into each other: the exact check, and a culled one with the same verdicts.

The metrics count such frames (:func:`nlo_lab.metrics.self_collision_frames`, the retargeting summary's
``self_collision_frames``) and the hand stage keeps the start's hands where its own would add one
(:func:`nlo_lab.inference.hand_stage.refine_hands`). Both ask the same question of the same capsules; the culled form
answers it from the objective's point plan and measures a pair exactly only where a separating-axis bound does not
clear it (tests hold the two equal on random poses over the joint ranges of YuMi, NAO and Pepper, and through the
pipeline).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch

from nlo_lab.objective.near_pairs import CULL_SLACK
from nlo_lab.objective.numpy_backend import maybe_near
from nlo_lab.objective.points import point_plan
from nlo_lab.robot.collision import segment_closest_points

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["penetrating"]


def penetrating(robot: Robot, q: torch.Tensor, cull: bool = False, points: torch.Tensor | None = None) -> torch.Tensor:
    """``(T,)`` bool: some checked capsule pair of ``q (T, n)`` penetrates (surface distance < 0), as the metrics count it.

    ``cull``: the faster form, the same verdicts: the capsules' end points from the objective's point plan (one FK of
    the points it maps, not of every link), and a pair's exact distance only where the separating-axis bound
    (:func:`~nlo_lab.objective.numpy_backend.maybe_near`) does not clear it of contact (most of YuMi's pairs are
    centimetres apart in every frame). ``points``: with ``cull``, the plan's points of ``q`` (``(T, K, 3)``,
    ``point_plan(robot).map(q)``) where the caller has them already; else they are mapped here."""
    if q.shape[0] == 0 or not robot.spec.collision_pairs:
        return torch.zeros(q.shape[0], dtype=torch.bool, device=q.device)
    with torch.no_grad():
        if not cull:
            return (robot.capsule_distances(robot.forward_kinematics(q)) < 0).any(-1)
        plan = point_plan(robot, q.dtype, q.device)
        mapped = plan.map(q, analytic_gradient=True) if points is None else points.detach()
        positions = mapped.cpu().numpy()  # (T, K, 3)
    T, pairs = positions.shape[0], robot.pair_capsules
    radii = plan.pair_radii.cpu().numpy().astype(np.float64)
    near = maybe_near(positions[:, plan.capsule_end_rows.cpu().numpy()].reshape(T, -1, 2, 3), pairs, radii + CULL_SLACK)
    frame, pair = np.divmod(near, len(pairs))
    ends = positions[frame[:, None], plan.pair_points.cpu().numpy().reshape(-1, 4)[pair]]  # (n, 4, 3): a0, a1, b0, b1
    dist = segment_closest_points(ends.transpose(1, 2, 0).astype(np.float64))[3]
    out = np.zeros(T, dtype=bool)
    out[frame[dist - radii[pair] < 0]] = True
    return torch.as_tensor(out, device=q.device)

"""The retargeting objective ``L(D, K(q))``: what the optimiser minimises, term by term.

- :mod:`~nlo_lab.objective.weights`: :class:`LossWeights`, ``TERMS``, the smoothness constants.
- :mod:`~nlo_lab.objective.targets`: :class:`Targets`, the demonstration as the terms compare it.
- :mod:`~nlo_lab.objective.points`: :class:`PointPlan`, the robot points and frames the terms need, one FK.
- :mod:`~nlo_lab.objective.terms`: one function per term, each with the paper's equation.
- :mod:`~nlo_lab.objective.total`: :class:`Objective` weights and sums the terms; :func:`objective`.
- :mod:`~nlo_lab.objective.numpy_backend`, :mod:`~nlo_lab.objective.near_pairs`: faster
  evaluations of the same terms, taken only when asked for (``Objective(fused=True, cull=True)``).
"""

from nlo_lab.objective.near_pairs import CULL_SLACK, near_pair_distances
from nlo_lab.objective.points import PointPlan, RobotPoints, point_plan, robot_points
from nlo_lab.objective.targets import Targets, targets_from_demonstration
from nlo_lab.objective.terms import (
    CHORD_EPS,
    UNIT_EPS,
    capsule_distances,
    chord,
    collision_loss,
    collision_scale,
    elbow_loss,
    end_effector_loss,
    finger_direction_loss,
    finger_loss,
    fingertip_direction_loss,
    fingertip_loss,
    in_wrist_frame,
    latent_loss,
    orientation_loss,
    pinch_activation,
    pinch_loss,
    smoothness_loss,
    smoothness_scale,
    step_cost,
    thumb_gap_loss,
    thumb_loss,
)
from nlo_lab.objective.total import Objective, objective
from nlo_lab.objective.weights import (
    COLLISION_FORMS,
    CONTACT_SCALE,
    HAND_STAGE_TERMS,
    HAND_TERMS,
    PINCH_OFF,
    PINCH_ON,
    SMOOTH_MAX_STEP,
    SMOOTH_SPEED_CAP,
    SMOOTH_STEP_WIDTH,
    TERMS,
    LossWeights,
)

__all__ = [
    # weights
    "LossWeights", "TERMS", "HAND_TERMS", "HAND_STAGE_TERMS", "COLLISION_FORMS", "SMOOTH_SPEED_CAP", "SMOOTH_MAX_STEP", "SMOOTH_STEP_WIDTH",
    "PINCH_ON", "PINCH_OFF", "CONTACT_SCALE",
    # targets, points
    "Targets", "targets_from_demonstration", "PointPlan", "point_plan", "RobotPoints", "robot_points",
    # terms
    "end_effector_loss", "orientation_loss", "elbow_loss", "finger_loss", "collision_loss", "collision_scale", "capsule_distances",
    "fingertip_loss", "thumb_loss", "pinch_loss", "fingertip_direction_loss", "finger_direction_loss", "thumb_gap_loss", "pinch_activation", "in_wrist_frame",
    "latent_loss", "smoothness_loss", "smoothness_scale", "step_cost", "chord", "UNIT_EPS", "CHORD_EPS",
    # the total, and the fast path kept beside it
    "Objective", "objective", "near_pair_distances", "CULL_SLACK",
]  # fmt: skip

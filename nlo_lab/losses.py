"""The old import path of the objective: everything lives in :mod:`nlo_lab.objective`.

Kept because notebooks of earlier versions, which ``nlo-lab lab`` never overwrites
in a learner's folder, import ``nlo_lab.losses``.
"""

from nlo_lab.objective import (
    COLLISION_FORMS,
    SMOOTH_MAX_STEP,
    SMOOTH_SPEED_CAP,
    SMOOTH_STEP_WIDTH,
    TERMS,
    LossWeights,
    Objective,
    Targets,
    collision_loss,
    elbow_loss,
    end_effector_loss,
    finger_loss,
    latent_loss,
    near_pair_distances,
    objective,
    orientation_loss,
    robot_points,
    smoothness_loss,
    smoothness_scale,
    step_cost,
    targets_from_demonstration,
)

__all__ = [
    "LossWeights",
    "Targets",
    "TERMS",
    "COLLISION_FORMS",
    "SMOOTH_SPEED_CAP",
    "SMOOTH_MAX_STEP",
    "SMOOTH_STEP_WIDTH",
    "targets_from_demonstration",
    "objective",
    "Objective",
    "end_effector_loss",
    "orientation_loss",
    "elbow_loss",
    "finger_loss",
    "collision_loss",
    "latent_loss",
    "smoothness_loss",
    "smoothness_scale",
    "step_cost",
    "robot_points",
    "near_pair_distances",
]

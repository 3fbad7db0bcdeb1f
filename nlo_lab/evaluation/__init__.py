"""Evaluation: the method against its baselines on a corpus split (paper, "Comparative Study").

* :mod:`~nlo_lab.evaluation.methods`: every method behind one interface, :func:`run_method`.
* :mod:`~nlo_lab.evaluation.scores`: :func:`evaluate` scores methods on demonstrations
  with the metric of :mod:`nlo_lab.metrics` (``nlo-lab evaluate``).
* :mod:`~nlo_lab.evaluation.tables`: the JSON contract object and Table I.
* :mod:`~nlo_lab.evaluation.hands`: the handshape measures (:func:`hand_scores`; ``benchmarks/hands.py``).
* :mod:`~nlo_lab.evaluation.directions`: the angle between the human's and the robot's arm
  directions, against the robot at rest (:func:`direction_error`; ``benchmarks/robots.py``).

The supervised baseline's network is trained by :mod:`nlo_lab.training.supervised`.
"""

from nlo_lab.evaluation.directions import direction_angles, direction_error
from nlo_lab.evaluation.hands import (
    MEASURES,
    HandScores,
    angle_deg,
    best_hand_angles,
    finger_chains,
    hand_frames_mask,
    hand_joint_indices,
    hand_scores,
    robot_hand_points,
)
from nlo_lab.evaluation.methods import (
    EVALUATION_MODES,
    LATENT_METHODS,
    METHODS,
    BaselineSettings,
    MethodResult,
    encoder_only,
    ik,
    ik_wrists,
    joint_space,
    latent_encoder,
    latent_random,
    mean_objective,
    nn_supervised,
    run_method,
    wrist_positions,
)
from nlo_lab.evaluation.scores import Evaluation, SequenceScore, check_methods, evaluate, evaluate_split
from nlo_lab.evaluation.tables import COLLISION_MARK, JSON_KEYS, format_table, to_json

__all__ = [
    "direction_angles",
    "direction_error",
    # methods
    "METHODS", "LATENT_METHODS", "EVALUATION_MODES", "BaselineSettings", "MethodResult", "latent_encoder", "encoder_only",
    "latent_random", "joint_space", "nn_supervised", "ik", "ik_wrists", "wrist_positions", "run_method", "mean_objective",
    # scores
    "SequenceScore", "Evaluation", "check_methods", "evaluate", "evaluate_split",
    # tables
    "JSON_KEYS", "COLLISION_MARK", "to_json", "format_table",
    # hands
    "HandScores", "hand_scores", "hand_frames_mask", "angle_deg", "MEASURES", "finger_chains", "hand_joint_indices",
    "robot_hand_points", "best_hand_angles",
]

"""Inference: from a demonstration to a robot trajectory with a trained, frozen model.

- :mod:`~nlo_lab.inference.settings`: :class:`OptimizeSettings`, :class:`JointOptimizeSettings`, :data:`INITS`.
- :mod:`~nlo_lab.inference.fast_paths`: :class:`FastPaths`, which evaluation of the decoder, objective and FK runs.
- :mod:`~nlo_lab.inference.numpy_descent`: the loss and gradient of one iteration in numpy (a few frames).
- :mod:`~nlo_lab.inference.descent`: the one descent (Adam or Rprop, best point, patience), :class:`OptimizeResult`.
- :mod:`~nlo_lab.inference.latent`: latent optimisation (:func:`initial_latent`, :func:`sequence_start`,
  :func:`optimize_latent`, :func:`optimize_stream`).
- :mod:`~nlo_lab.inference.joint_space`: the joint-space baseline (:func:`optimize_joints`).
- :mod:`~nlo_lab.inference.retime`: slowing a trajectory to the joints' velocity limits.
- :mod:`~nlo_lab.inference.trajectory`: :class:`RobotTrajectory` and its files.
- :mod:`~nlo_lab.inference.inputs`: :class:`RetargetInputs`, a demonstration's frames as the
  optimisation and the training read them.

The pipeline that assembles inference with the metrics (:class:`~nlo_lab.pipeline.RetargetConfig`,
:func:`~nlo_lab.pipeline.retarget`) comes after the metrics: :mod:`nlo_lab.pipeline`.
"""

from nlo_lab.inference.descent import STEPPERS, Adam, OptimizeResult, Rprop, descend, frozen, join_results, smoothness_term
from nlo_lab.inference.fast_paths import FastPaths, fast_paths
from nlo_lab.inference.inputs import RetargetInputs
from nlo_lab.inference.joint_space import optimize_joints
from nlo_lab.inference.latent import initial_latent, optimize_latent, optimize_stream, sequence_start
from nlo_lab.inference.retime import retime_times, segment_durations
from nlo_lab.inference.settings import (
    HAND_SEARCH,
    HANDSHAPE_SEARCH,
    HANDSHAPE_SLOWDOWN,
    INITS,
    JOINT_INITS,
    JOINT_LIMITS,
    PAPER_ITERATIONS,
    PAPER_LR,
    PAPER_PATIENCE,
    RPROP_LR,
    SMOOTH_LR,
    JointOptimizeSettings,
    OptimizeSettings,
)
from nlo_lab.inference.trajectory import FORMAT_VERSION, RobotTrajectory, TrajectoryError

__all__ = [
    # settings
    "INITS", "JOINT_INITS", "JOINT_LIMITS", "PAPER_LR", "SMOOTH_LR", "RPROP_LR", "PAPER_ITERATIONS", "PAPER_PATIENCE",
    "OptimizeSettings", "JointOptimizeSettings", "HAND_SEARCH", "HANDSHAPE_SEARCH", "HANDSHAPE_SLOWDOWN",
    # fast paths
    "FastPaths", "fast_paths",
    # descent
    "OptimizeResult", "Adam", "Rprop", "STEPPERS", "descend", "frozen", "smoothness_term", "join_results",
    # latent, joint_space
    "initial_latent", "sequence_start", "optimize_latent", "optimize_stream", "optimize_joints",
    # retime, trajectory
    "retime_times", "segment_durations",
    "RobotTrajectory", "TrajectoryError", "FORMAT_VERSION",
    # inputs
    "RetargetInputs",
]

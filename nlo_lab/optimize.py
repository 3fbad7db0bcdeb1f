"""The old import path of the optimisers: everything lives in :mod:`nlo_lab.inference`.

Kept because the notebooks of earlier versions, which ``nlo-lab lab`` never overwrites
in a learner's folder, import ``nlo_lab.optimize``.
"""

from nlo_lab.inference.descent import OptimizeResult
from nlo_lab.inference.joint_space import optimize_joints
from nlo_lab.inference.latent import initial_latent, optimize_latent, optimize_stream, sequence_start
from nlo_lab.inference.settings import INITS, JOINT_INITS, JOINT_LIMITS, PAPER_LR, SMOOTH_LR, JointOptimizeSettings, OptimizeSettings

__all__ = [
    "INITS",
    "JOINT_INITS",
    "JOINT_LIMITS",
    "PAPER_LR",
    "SMOOTH_LR",
    "OptimizeSettings",
    "JointOptimizeSettings",
    "OptimizeResult",
    "initial_latent",
    "sequence_start",
    "optimize_latent",
    "optimize_stream",
    "optimize_joints",
]

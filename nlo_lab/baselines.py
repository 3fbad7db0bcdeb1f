"""Old import path of the methods (:mod:`nlo_lab.evaluation.methods`), the supervised network
(:mod:`nlo_lab.training.supervised`) and the Table III ablation (:mod:`nlo_lab.training.ablation`),
kept for notebooks copied by earlier versions."""

from nlo_lab.evaluation import methods
from nlo_lab.evaluation.methods import *  # noqa: F403
from nlo_lab.training import ablation, supervised
from nlo_lab.training.ablation import *  # noqa: F403
from nlo_lab.training.supervised import *  # noqa: F403

__all__ = methods.__all__ + supervised.__all__ + ablation.__all__

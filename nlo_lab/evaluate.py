"""Old import path of the evaluation (:mod:`nlo_lab.evaluation`), kept for notebooks copied by earlier versions."""

from nlo_lab.evaluation import *  # noqa: F403
from nlo_lab.evaluation import __all__  # noqa: F401

"""Old import path of the cell helpers (:mod:`nlo_lab.lab.cells`), kept because the notebooks a
learner copied with an earlier ``nlo-lab lab`` (never overwritten) start with
``from nlo_lab.notebook import TEST_MODE, budget, setup``."""

from nlo_lab.lab.cells import *  # noqa: F403
from nlo_lab.lab.cells import __all__  # noqa: F401

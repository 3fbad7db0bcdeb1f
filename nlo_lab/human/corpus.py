"""The old import path of the synthetic corpus: everything lives in :mod:`nlo_lab.corpus`.

Kept because notebooks of earlier versions, which ``nlo-lab lab`` never overwrites
in a learner's folder, import ``nlo_lab.human.corpus``.
"""

from nlo_lab.corpus import (
    CLEARANCE,
    ELBOW_CLEARANCE,
    FINGERTIP_ACCEL_LIMIT,
    HAND_CLEARANCE,
    N_SIGNERS,
    SCENARIOS,
    SPLITS,
    WRIST_ACCEL_LIMIT,
    WRIST_SPEED_LIMIT,
    Scenario,
    corpus_angles,
    corpus_clip,
    corpus_lexicon,
    corpus_names,
    sign_corpus,
)

__all__ = [
    "Scenario",
    "SCENARIOS",
    "SPLITS",
    "N_SIGNERS",
    "CLEARANCE",
    "HAND_CLEARANCE",
    "ELBOW_CLEARANCE",
    "WRIST_ACCEL_LIMIT",
    "FINGERTIP_ACCEL_LIMIT",
    "WRIST_SPEED_LIMIT",
    "sign_corpus",
    "corpus_clip",
    "corpus_names",
    "corpus_angles",
    "corpus_lexicon",
]

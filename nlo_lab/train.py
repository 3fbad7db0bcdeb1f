"""The old import path of training and checkpoints (``nlo_lab.train``).

Training lives in :mod:`nlo_lab.training`, checkpoints in :mod:`nlo_lab.model`
(:mod:`nlo_lab.model.checkpoint`); the names are re-exported here because the
notebooks of earlier versions (which ``nlo-lab lab`` never overwrites in a
learner's folder) import them from ``nlo_lab.train``.

``python -m nlo_lab.train ARGS`` runs ``nlo-lab train ARGS``.
"""

from __future__ import annotations

import sys

from nlo_lab.model import CHECKPOINT_FORMAT_VERSION, checkpoint_path, load_checkpoint, load_pretrained, save_checkpoint
from nlo_lab.training import TrainResult, TrainSettings, corpus_targets, new_model, train_model

__all__ = [
    "CHECKPOINT_FORMAT_VERSION",
    "TrainSettings",
    "TrainResult",
    "train_model",
    "corpus_targets",
    "new_model",
    "save_checkpoint",
    "load_checkpoint",
    "load_pretrained",
    "checkpoint_path",
]

if __name__ == "__main__":
    from nlo_lab.cli import main

    sys.exit(main(["train", *sys.argv[1:]]))

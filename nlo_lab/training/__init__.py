"""Training: the encoder-decoder on the objective (paper Eq. 10), the supervised baseline's
network, and the Table III ablation.

* :mod:`~nlo_lab.training.data`: the training split as targets and encoder input; validation held out of it.
* :mod:`~nlo_lab.training.train`: :func:`train_model` (``nlo-lab train``), in either mode (:data:`TRAIN_MODES`).
* :mod:`~nlo_lab.training.autodecoder`: the paper's auto-decoder (:class:`LatentCodes`: one code per training frame).
* :mod:`~nlo_lab.training.supervised`: labels by joint-space optimisation, :class:`SupervisedNet`, the cache.
* :mod:`~nlo_lab.training.ablation`: :data:`VARIANTS` and :func:`train_variant` (Table III).

Checkpoints (save, load, the shipped ones) belong to the model: :mod:`nlo_lab.model`.
"""

from nlo_lab.training.ablation import VARIANTS, train_variant
from nlo_lab.training.autodecoder import LatentCodes, autodecoder_loss, validate_autodecoder
from nlo_lab.training.data import VALIDATION_EVERY, corpus_inputs, corpus_targets, demos_inputs, demos_targets, train_validation_split
from nlo_lab.training.supervised import (
    SupervisedNet,
    SupervisedSettings,
    cache_dir,
    supervised_dataset,
    supervised_labels,
    supervised_network,
    train_supervised_model,
    train_supervised_net,
)
from nlo_lab.training.train import TRAIN_MODES, TrainResult, TrainSettings, latent_statistics, new_model, train_model

__all__ = [
    # train, data
    "TRAIN_MODES", "TrainSettings", "TrainResult", "train_model", "new_model", "latent_statistics",
    # the auto-decoder
    "LatentCodes", "autodecoder_loss", "validate_autodecoder",
    "VALIDATION_EVERY", "train_validation_split", "demos_targets", "corpus_targets", "demos_inputs", "corpus_inputs",
    # supervised
    "SupervisedSettings", "SupervisedNet", "supervised_labels", "train_supervised_net", "train_supervised_model",
    "supervised_dataset", "supervised_network", "cache_dir",
    # ablation
    "VARIANTS", "train_variant",
]

"""The training data: the synthetic corpus's training split, as objective targets and encoder input.

Validation uses sequences held out of the training split (:func:`train_validation_split`):
the test split stays unseen until evaluation, so no checkpoint is chosen on test data.
"""

from __future__ import annotations

import torch

from nlo_lab.corpus import sign_corpus
from nlo_lab.inference import RetargetInputs
from nlo_lab.objective import Targets, targets_from_demonstration

__all__ = ["VALIDATION_EVERY", "train_validation_split", "demos_targets", "corpus_targets", "demos_inputs", "corpus_inputs"]

VALIDATION_EVERY = 6  # every 6th training sequence validates (10 of the 61)


def train_validation_split(seed: int = 0) -> tuple[list, list]:
    """The training split's sequences for fitting and for validation.

    Every :data:`VALIDATION_EVERY`-th sequence of ``sign_corpus("train")`` is
    held out for validation; ``sign_corpus("test")`` is never looked at.
    """
    demos = sign_corpus("train", seed=seed)
    fit = [d for i, d in enumerate(demos) if i % VALIDATION_EVERY != VALIDATION_EVERY - 1]
    val = [d for i, d in enumerate(demos) if i % VALIDATION_EVERY == VALIDATION_EVERY - 1]
    return fit, val


def demos_targets(demos, dtype: torch.dtype = torch.float32) -> Targets:
    """All frames of ``demos`` as one :class:`Targets` (what the objective compares)."""
    return Targets.cat([targets_from_demonstration(d, dtype=dtype) for d in demos])


def corpus_targets(split: str, dtype: torch.dtype = torch.float32, seed: int = 0) -> Targets:
    """All frames of ``sign_corpus(split)`` as one :class:`Targets`."""
    return demos_targets(sign_corpus(split, seed=seed), dtype)


def demos_inputs(demos, dtype: torch.dtype = torch.float32) -> RetargetInputs:
    """All frames of ``demos``: targets and encoder input (what training reads)."""
    return RetargetInputs.cat([RetargetInputs.from_demonstration(d, dtype=dtype) for d in demos])


def corpus_inputs(split: str, dtype: torch.dtype = torch.float32, seed: int = 0) -> RetargetInputs:
    """All frames of ``sign_corpus(split)``: targets and encoder input."""
    return demos_inputs(sign_corpus(split, seed=seed), dtype)

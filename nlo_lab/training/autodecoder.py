"""Auto-decoder training (the paper's Eq. ``autodecoder``): the decoder and one latent code per motion, jointly.

``min_{z, psi} sum_i L(D_i, K(f_psi(z_i))) + ||z_i||²/σ²`` (σ = 1: ``LossWeights.latent = 1/σ²``).

There is no encoder: every training motion ``i`` owns a latent code ``z_i``, a free
parameter optimised together with the decoder's weights, as in DeepSDF's auto-decoder
(Park et al. 2019, which the paper cites). A "motion" is what the decoder maps one code
to: the robot's joint angles of one frame, so here there is one code per training frame.
The prior term keeps the codes near ``N(0, σ²)``, the distribution inference starts from.

At inference a new demonstration has no code: latent optimisation starts from the codes'
statistics (``init="train-stats"``: :attr:`RetargetModel.latent_mean` /
:attr:`~RetargetModel.latent_std` hold the learned codes' mean and spread), from
``N(0, σ²)`` (``"random"``) or from zeros, never from the encoder (the model's is untrained,
and ``init="encoder"`` says so). The paper then adds the encoder (Eq. 10,
:func:`nlo_lab.training.train_model`'s default mode) to start from a better guess; the two
trainings are compared in docs/RESULTS.md ("Auto-decoder against encoder training").

:func:`nlo_lab.training.train_model` runs this with ``TrainSettings(mode="autodecoder")``
(``nlo-lab train --mode autodecoder``); this module holds its pieces.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import torch
from torch import nn

from nlo_lab.inference import FastPaths, OptimizeSettings, fast_paths, optimize_latent
from nlo_lab.objective import LossWeights, latent_loss, objective

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.model import RetargetModel
    from nlo_lab.robot import Robot

__all__ = ["LatentCodes", "autodecoder_loss", "validate_autodecoder"]


class LatentCodes(nn.Module):
    """One latent code ``(N_r, k)`` per training motion, as a sparse embedding table.

    Sparse: a step touches only the codes of its batch, and
    ``torch.optim.SparseAdam`` updates only those (a dense Adam would keep moving every
    code with its momentum long after its last batch).

    Args:
        count: number of training motions (frames).
        latent_shape: ``(N_r, k)``, the model's :attr:`~nlo_lab.model.RetargetModel.latent_shape`.
        init_std: the codes start at ``N(0, init_std²)`` (DeepSDF's 0.01: near the prior's
            centre, all nearly alike, so the decoder shapes the space from the start).
        seed: seeds the initial codes.
    """

    def __init__(self, count: int, latent_shape: tuple[int, int], init_std: float = 0.01, seed: int = 0):
        super().__init__()
        self.latent_shape = tuple(latent_shape)
        self.table = nn.Embedding(count, math.prod(self.latent_shape), sparse=True)
        gen = torch.Generator().manual_seed(seed)
        with torch.no_grad():
            self.table.weight.copy_(torch.randn(self.table.weight.shape, generator=gen) * init_std)

    def __len__(self) -> int:
        return self.table.num_embeddings

    def forward(self, idx: torch.Tensor) -> torch.Tensor:
        """Codes of the motions ``idx (B,)`` -> ``(B, N_r, k)``."""
        return self.table(idx).view(-1, *self.latent_shape)

    def all(self) -> torch.Tensor:
        """Every code, ``(count, N_r, k)`` (a detached copy)."""
        return self.table.weight.detach().clone().view(-1, *self.latent_shape)


def autodecoder_loss(model: RetargetModel, robot: Robot, codes: LatentCodes, idx: torch.Tensor, targets, weights: LossWeights, form: str,
                     fast: bool | FastPaths = True) -> torch.Tensor:
    """Per-motion Eq. ``autodecoder``: ``L(D_i, K(f_psi(z_i))) + weights.latent * ||z_i||²`` -> ``(B,)``.

    Args:
        model: the :class:`~nlo_lab.model.RetargetModel` whose decoder is trained.
        robot: the robot (FK, capsules), in the model's dtype.
        codes: the table of latent codes.
        idx: ``(B,)`` the motions of the batch (rows of ``codes`` and of ``targets``' source).
        targets: the objective's :class:`~nlo_lab.objective.Targets` of those B motions.
        weights: loss weights; ``weights.latent`` is ``1/σ²``.
        form: the collision term's form.
        fast: the evaluations that run (same numbers; :func:`nlo_lab.inference.fast_paths`).
    """
    paths = fast_paths(fast, len(idx), targets.shoulder.device)
    z = codes(idx)
    q = model.decode(z, form=paths.decoder).to(robot.lower_limits.dtype)
    total, _ = objective(robot, q, targets, weights, collision_form=form, **paths.objective_options())
    return total + weights.latent * latent_loss(z)


def validate_autodecoder(model: RetargetModel, robot: Robot, data, start: torch.Tensor, weights: LossWeights, form: str, iterations: int,
                         fast: bool | FastPaths = True) -> float:
    """Mean objective (with the prior term) on ``data`` after latent optimisation with the decoder frozen.

    What the auto-decoder is for: an unseen frame is fitted by ``iterations`` Adam steps on
    its latent from ``start`` (``(N_r, k)``, the codes' mean), frames independent.
    """
    was_training = model.training
    model.eval()
    z0 = start.to(next(model.parameters()).dtype).expand(len(data), *start.shape).clone()
    settings = OptimizeSettings(iterations=iterations, patience=max(1, iterations), collision_form=form)
    r = optimize_latent(model, robot, data.targets, settings, weights=dataclasses.replace(weights, smooth=0.0), z0=z0, fast=fast)
    model.train(was_training)
    return float(r.loss.mean())

"""Table III of the paper: encoder-decoder variants trained for the same budget.

``AE``/``GAE`` (MLP / graph) learn joint-space labels supervised
(:func:`nlo_lab.training.train_supervised_model`); ``AE+FK``/``GAE+FK`` learn the
objective through forward kinematics (:func:`nlo_lab.training.train_model`). The budget is
a number of optimiser steps (the same batches for every variant, whatever the machine's
load) or a wall-clock time.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import torch

from nlo_lab.errors import SettingsError
from nlo_lab.inference import RetargetInputs
from nlo_lab.model import DEFAULT_ACTIVATION
from nlo_lab.settings import EPOCHS_RANGE, SECONDS_RANGE
from nlo_lab.training.supervised import train_supervised_model
from nlo_lab.training.train import TrainSettings, new_model, train_model

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.objective import LossWeights
    from nlo_lab.robot import Robot

__all__ = ["VARIANTS", "train_variant"]

VARIANTS = {  # Table III of the paper: name -> (model kind, training objective)
    "AE": ("mlp", "supervised"),
    "GAE": ("graph", "supervised"),
    "AE+FK": ("mlp", "fk"),
    "GAE+FK": ("graph", "fk"),
}


def train_variant(robot: Robot, name: str, data: RetargetInputs, labels: torch.Tensor | None, seconds: float | None = None, *,
                  val_data: RetargetInputs | None = None, seed: int = 0, steps: int | None = None, activation: str = DEFAULT_ACTIVATION,
                  weights: LossWeights | None = None):
    """Train one Table III variant for a budget of optimiser steps or of wall-clock time.

    Args:
        robot: a loaded robot.
        name: ``"AE"``, ``"GAE"`` (supervised on ``labels``) or ``"AE+FK"``, ``"GAE+FK"``
            (the objective through forward kinematics, :func:`nlo_lab.training.train_model`).
        data: training frames (targets and encoder input).
        labels: ``(N, n)`` joint-space labels of ``data`` (supervised variants only).
        seconds: wall-clock budget [s]; None: no time limit.
        val_data: validation frames of the FK variants (default: ``data``).
        seed: initial weights and batch order.
        steps: optimiser steps (batch 64); None: no step limit. Give ``steps`` or ``seconds``
            (the same for every variant makes them comparable; steps also on a busy machine).
        activation: the networks' message activation (:data:`~nlo_lab.model.ACTIVATIONS`).
        weights: the training objective of the FK variants (None: :class:`LossWeights` defaults;
            the paper's Table III: ``LossWeights.paper()``). The supervised variants learn their labels.

    Returns:
        ``(model, seconds, steps)``: the model in eval mode, in the robot's dtype.
    """
    if name not in VARIANTS:
        raise SettingsError(f"unknown variant {name!r}; expected one of {', '.join(VARIANTS)}")
    if seconds is None and steps is None:
        raise SettingsError("train_variant needs a budget: steps or seconds")
    kind, objective_kind = VARIANTS[name]
    start = time.perf_counter()
    max_seconds = float(seconds) if seconds is not None else SECONDS_RANGE[1]
    if objective_kind == "fk":
        val = val_data if val_data is not None else data
        settings = TrainSettings(kind=kind, epochs=EPOCHS_RANGE[1], max_seconds=max_seconds, max_steps=steps, val_every=100,
                                 val_frames=min(600, len(val)), seed=seed, progress=False, activation=activation)
        r = train_model(robot, settings, train_data=data, val_data=val, weights=weights)
        model, taken = r.model, r.steps
    else:
        if labels is None:
            raise SettingsError(f"variant {name!r} is supervised: it needs labels")
        torch.manual_seed(seed)
        model = new_model(robot, TrainSettings(kind=kind, activation=activation))
        hist = train_supervised_model(model, data, labels, epochs=EPOCHS_RANGE[1], batch_size=64, lr=1e-3, seed=seed, max_seconds=max_seconds, max_steps=steps)
        per_epoch = (len(data) + 63) // 64
        taken = min(steps, len(hist) * per_epoch) if steps is not None else len(hist) * per_epoch
    return model.to(dtype=robot.lower_limits.dtype).eval(), time.perf_counter() - start, taken

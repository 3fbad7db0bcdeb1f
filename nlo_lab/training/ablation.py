"""Table III of the paper: encoder-decoder variants trained for the same wall-clock budget.

``AE``/``GAE`` (MLP / graph) learn joint-space labels supervised
(:func:`nlo_lab.training.train_supervised_model`); ``AE+FK``/``GAE+FK`` learn the
objective through forward kinematics (:func:`nlo_lab.training.train_model`).
"""

from __future__ import annotations

import time

import torch

from nlo_lab.errors import SettingsError
from nlo_lab.inference import RetargetInputs
from nlo_lab.training.supervised import train_supervised_model
from nlo_lab.training.train import TrainSettings, new_model, train_model

__all__ = ["VARIANTS", "train_variant"]

VARIANTS = {  # Table III of the paper: name -> (model kind, training objective)
    "AE": ("mlp", "supervised"),
    "GAE": ("graph", "supervised"),
    "AE+FK": ("mlp", "fk"),
    "GAE+FK": ("graph", "fk"),
}


def train_variant(robot, name: str, data: RetargetInputs, labels: torch.Tensor | None, seconds: float, *, val_data: RetargetInputs | None = None, seed: int = 0):
    """Train one Table III variant for a wall-clock budget.

    Args:
        robot: a loaded robot.
        name: ``"AE"``, ``"GAE"`` (supervised on ``labels``) or ``"AE+FK"``, ``"GAE+FK"``
            (the objective through forward kinematics, :func:`nlo_lab.training.train_model`).
        data: training frames (targets and encoder input).
        labels: ``(N, n)`` joint-space labels of ``data`` (supervised variants only).
        seconds: training budget [s] (the same for every variant makes them comparable).
        val_data: validation frames of the FK variants (default: ``data``).
        seed: initial weights and batch order.

    Returns:
        ``(model, seconds, steps)``: the model in eval mode, in the robot's dtype.
    """
    if name not in VARIANTS:
        raise SettingsError(f"unknown variant {name!r}; expected one of {', '.join(VARIANTS)}")
    kind, objective_kind = VARIANTS[name]
    start = time.perf_counter()
    if objective_kind == "fk":
        val = val_data if val_data is not None else data
        settings = TrainSettings(kind=kind, epochs=100_000, max_seconds=seconds, val_every=100, val_frames=min(600, len(val)), seed=seed, progress=False)
        r = train_model(robot, settings, train_data=data, val_data=val)
        model, steps = r.model, r.steps
    else:
        if labels is None:
            raise SettingsError(f"variant {name!r} is supervised: it needs labels")
        torch.manual_seed(seed)
        model = new_model(robot, TrainSettings(kind=kind))
        hist = train_supervised_model(model, data, labels, epochs=100_000, batch_size=64, lr=1e-3, seed=seed, max_seconds=seconds)
        steps = len(hist) * ((len(data) + 63) // 64)
    return model.to(dtype=robot.lower_limits.dtype).eval(), time.perf_counter() - start, steps

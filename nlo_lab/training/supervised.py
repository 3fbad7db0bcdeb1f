"""The supervised baseline's network (the paper's 'NN') and its data.

Labels are joint-space optimisation results (:func:`nlo_lab.inference.optimize_joints`)
over every ``frame_stride``-th frame of the training split (:func:`supervised_dataset`);
a feed-forward network (:class:`SupervisedNet`) learns the angles from the human
node features (:func:`train_supervised_net`). Both are cached in memory and under
the user cache folder (:func:`cache_dir`), keyed by the robot, the settings and the
training frames, because labelling takes minutes (:func:`supervised_network`).
:func:`train_supervised_model` trains the graph or MLP encoder-decoder the same
way (Table III, :mod:`nlo_lab.training.ablation`).
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch
from torch import nn
from tqdm.auto import tqdm

from nlo_lab.errors import SettingsError
from nlo_lab.inference import JointOptimizeSettings, RetargetInputs, optimize_joints
from nlo_lab.model import EncoderInput
from nlo_lab.model.checkpoint import load_torch_file
from nlo_lab.objective import LossWeights, Targets
from nlo_lab.settings import (
    BATCH_RANGE,
    COUNT_RANGE,
    EPOCHS_RANGE,
    ITERATIONS_RANGE,
    RATE_RANGE,
    SEED_RANGE,
    check_int,
    check_range,
    check_type,
)
from nlo_lab.training.data import corpus_inputs

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.model import RetargetModel
    from nlo_lab.robot import Robot

__all__ = [
    "SupervisedSettings",
    "SupervisedNet",
    "supervised_labels",
    "train_supervised_net",
    "train_supervised_model",
    "cache_dir",
    "supervised_dataset",
    "supervised_network",
]


@dataclass(frozen=True)
class SupervisedSettings:
    """How the supervised network (``nn_supervised``) is made.

    Attributes:
        frame_stride: every ``frame_stride``-th frame of the training split is a sample.
        label_iterations: joint-space Adam steps that make each label (the 'ground truth').
        hidden: widths of the hidden layers.
        epochs: passes over the samples.
        batch_size: samples per step.
        lr: Adam step size.
        seed: seeds the weights and the batch order (same seed, same network).
        corpus_seed: seed of the synthetic corpus (:func:`nlo_lab.corpus.sign_corpus`).
    """

    frame_stride: int = 4
    label_iterations: int = 150
    hidden: tuple[int, ...] = (256, 256)
    epochs: int = 60
    batch_size: int = 128
    lr: float = 1e-3
    seed: int = 0
    corpus_seed: int = 0

    def __post_init__(self) -> None:
        for name, bounds in (("frame_stride", COUNT_RANGE), ("label_iterations", ITERATIONS_RANGE), ("epochs", EPOCHS_RANGE),
                             ("batch_size", BATCH_RANGE), ("seed", SEED_RANGE), ("corpus_seed", SEED_RANGE)):
            object.__setattr__(self, name, check_int(name, getattr(self, name), *bounds))
        check_type("hidden", self.hidden, (tuple, list), "a tuple of layer widths")
        hidden = tuple(self.hidden)
        if not 1 <= len(hidden) <= 16 or any(isinstance(h, bool) or not isinstance(h, (int, np.integer)) or not 1 <= h <= 65536 for h in hidden):
            raise SettingsError(f"hidden must be 1 to 16 layer widths in [1, 65536], got {self.hidden!r}")
        object.__setattr__(self, "hidden", tuple(int(h) for h in hidden))
        object.__setattr__(self, "lr", check_range("lr", self.lr, *RATE_RANGE))


class SupervisedNet(nn.Module):
    """Feed-forward network: flattened human node features -> angles inside the limits.

    It regresses ``u = (q - mid) / half_range``; the output is clamped to
    ``[-1, 1]`` and mapped back, so the angles never leave the limits.
    """

    q_mid: torch.Tensor  # a buffer (typed here: nn.Module's __getattr__ says Tensor | Module)
    q_half: torch.Tensor

    def __init__(self, in_features: int, lower: torch.Tensor, upper: torch.Tensor, hidden: tuple[int, ...] = (256, 256)):
        super().__init__()
        dims = (in_features, *hidden, lower.shape[0])
        layers: list[nn.Module] = []
        for i, (a, b) in enumerate(zip(dims[:-1], dims[1:], strict=True)):
            layers.append(nn.Linear(a, b))
            if i < len(dims) - 2:
                layers.append(nn.LeakyReLU(0.01))
        self.net = nn.Sequential(*layers)
        self.register_buffer("q_mid", ((upper + lower) / 2).detach().float().clone())
        self.register_buffer("q_half", ((upper - lower) / 2).detach().float().clamp_min(1e-9).clone())
        self.info: dict = {}

    def normalized(self, x: torch.Tensor) -> torch.Tensor:
        """``x (B, N_h, F)`` -> ``u (B, n)`` before clamping."""
        return self.net(x.flatten(1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``x (B, N_h, F)`` -> ``q (B, n)`` [rad] inside the limits."""
        return self.q_mid + self.q_half * self.normalized(x).clamp(-1.0, 1.0)


def supervised_labels(robot: Robot, targets: Targets, iterations: int, *, progress: bool = False) -> torch.Tensor:
    """The supervised 'ground truth': joint-space optimisation results ``(N, n)`` for every frame of ``targets``.

    Each frame on its own, with the paper's objective (no smoothness term): the frames are
    samples (every ``frame_stride``-th frame, several sequences end to end), not a motion.
    ``progress``: a tqdm bar of the optimisation steps (every chunk of frames takes ``iterations + 1``).
    """
    chunk = 2048  # bounded memory; frames are independent
    starts = range(0, len(targets), chunk)
    out = []
    per_frame = LossWeights.paper()  # frames independent, no hand terms of ours
    with tqdm(total=len(starts) * (iterations + 1), desc=f"labels {robot.name}", unit="step", disable=not progress) as bar:
        for i in starts:
            settings = JointOptimizeSettings(iterations=iterations, patience=iterations + 1)
            r = optimize_joints(robot, targets.index(slice(i, i + chunk)), settings, fast=True, weights=per_frame,
                                callback=lambda it, loss: bar.update(1))
            out.append(r.q.detach())
    return torch.cat(out)


def _fit(module: nn.Module, predict: Callable, x: tuple, u: torch.Tensor, epochs: int, batch: int, lr: float, seed: int,
         max_seconds: float | None, max_steps: int | None = None) -> list[float]:
    """Adam on the mean squared error of ``predict(*x_batch)`` against ``u``; returns per-epoch
    losses (the last epoch's over the batches it ran when ``max_steps`` ends it)."""
    gen = torch.Generator().manual_seed(seed)
    opt = torch.optim.Adam(module.parameters(), lr=lr)
    n = u.shape[0]
    history = []
    start = time.perf_counter()
    steps = 0
    module.train()
    for _ in range(epochs):
        order = torch.randperm(n, generator=gen)
        total, seen = 0.0, 0
        for b in range(0, n, batch):
            idx = order[b : b + batch]
            loss = (predict(*(t[idx] if t is not None else None for t in x)) - u[idx]).pow(2).mean()
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            total, seen, steps = total + float(loss.detach()) * len(idx), seen + len(idx), steps + 1
            if max_steps is not None and steps >= max_steps:
                break
        history.append(total / seen)
        if (max_seconds is not None and time.perf_counter() - start > max_seconds) or (max_steps is not None and steps >= max_steps):
            break
    module.eval()
    return history


def train_supervised_net(robot: Robot, features: torch.Tensor, labels: torch.Tensor, settings: SupervisedSettings | None = None) -> SupervisedNet:
    """Train a :class:`SupervisedNet` on ``features (N, N_h, F)`` -> ``labels (N, n)`` [rad].

    Deterministic from ``settings.seed`` (weights and batch order).
    """
    s = settings or SupervisedSettings()
    lo, hi = robot.lower_limits.float().cpu(), robot.upper_limits.float().cpu()
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(s.seed)
        net = SupervisedNet(int(features[0].numel()), lo, hi, s.hidden)
    u = ((labels.float().cpu() - net.q_mid) / net.q_half).clamp(-1, 1)
    start = time.perf_counter()
    history = _fit(net, net.normalized, (features.float().cpu(),), u, s.epochs, s.batch_size, s.lr, s.seed, None)
    net.info = {"train_seconds": time.perf_counter() - start, "history": history, "samples": int(u.shape[0])}
    return net


def train_supervised_model(model: RetargetModel, inputs: EncoderInput | RetargetInputs, labels: torch.Tensor, *, epochs: int, batch_size: int = 64, lr: float = 1e-3,
                           seed: int = 0, max_seconds: float | None = None, max_steps: int | None = None) -> list[float]:
    """Train a :class:`~nlo_lab.model.RetargetModel` (encoder + decoder) supervised on
    ``labels (N, n)`` (paper Eq. ``L_sup``: squared error of the angles, here
    normalised by the half range of each joint): the 'AE'/'GAE' of Table III.
    ``inputs``: the encoder's input of the N frames (or frames carrying it); training
    stops after ``epochs``, ``max_seconds`` or ``max_steps`` optimiser steps, whichever comes first.

    Returns:
        Mean training loss per epoch. The model is left in eval mode.
    """
    lo, hi = model.decoder.lower, model.decoder.upper
    mid, half = (hi + lo) / 2, ((hi - lo) / 2).clamp_min(1e-9)
    u = ((labels.to(lo.dtype) - mid) / half).clamp(-1, 1)
    x = inputs.encoder if isinstance(inputs, RetargetInputs) else inputs

    def predict(x, e):
        return (model(x, e)[0].to(lo.dtype) - mid) / half

    torch.manual_seed(seed)
    return _fit(model, predict, (x.node_features.to(lo.dtype), x.edge_features.to(lo.dtype)), u, epochs, batch_size, lr, seed, max_seconds, max_steps)


def cache_dir() -> Path:
    """The user cache folder of nlo_lab (``$NLO_LAB_CACHE``, else ``$XDG_CACHE_HOME/nlo_lab``, else ``~/.cache/nlo_lab``)."""
    env = os.environ.get("NLO_LAB_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "nlo_lab"


def _cache_key(robot, settings: SupervisedSettings, data: RetargetInputs) -> str:
    """Robot joints, limits and collision margins, settings and the training frames' content (a changed corpus is a new key)."""
    ident = {
        "data": hashlib.sha256(data.encoder.node_features.detach().cpu().float().numpy().tobytes()).hexdigest(),
        "robot": robot.name,
        "joints": list(robot.joint_names),
        "lower": [round(float(v), 6) for v in robot.lower_limits],
        "upper": [round(float(v), 6) for v in robot.upper_limits],
        "margins": [round(float(v), 6) for v in robot.collision_margins],
        "settings": asdict(settings),
        # 2: labels from the neutral start with the fixed-shoulder end-effector term; 3: frames
        # labelled independently (no smoothness term between unrelated sample frames). Bump on
        # any change to the objective or to optimize_joints, or stale labels are reused. 4: the paper's
        # objective without our hand terms (LossWeights.paper(); version 3 labelled YuMi's fingers with them)
        "version": 4,
    }
    return hashlib.sha256(json.dumps(ident, sort_keys=True).encode()).hexdigest()[:16]


_NETWORKS: dict[str, SupervisedNet] = {}


def supervised_dataset(robot: Robot, settings: SupervisedSettings | None = None, *, use_cache: bool = True, progress: bool = False) -> tuple[RetargetInputs, torch.Tensor, float]:
    """Training frames (every ``frame_stride``-th of the train split) and their
    joint-space optimisation labels ``(N, n)`` [rad], float32.

    The labels are cached as a file under :func:`cache_dir` (keyed like the
    network, without the training settings). Returns ``(targets, labels,
    label_seconds)``: the frames' targets and encoder input, the labels, and the time the labels took when made.
    """
    s = settings or SupervisedSettings()
    data = corpus_inputs("train", seed=s.corpus_seed).index(slice(0, None, s.frame_stride))
    label_key = _cache_key(robot, SupervisedSettings(frame_stride=s.frame_stride, label_iterations=s.label_iterations, corpus_seed=s.corpus_seed), data)
    path = cache_dir() / f"labels_{robot.name}_{label_key}.pt"
    if use_cache and path.is_file():
        try:
            blob = load_torch_file(path, kind="cache file")
            if blob["labels"].shape == (len(data), robot.n_joints):
                return data, blob["labels"], float(blob["seconds"])
        except Exception:  # a damaged cache file is rebuilt, never trusted
            pass
    start = time.perf_counter()
    labels = supervised_labels(robot.to(dtype=torch.float32), data.targets, s.label_iterations, progress=progress).float()
    seconds = time.perf_counter() - start
    if use_cache:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(path.name + ".tmp")
            torch.save({"labels": labels, "seconds": seconds}, tmp)
            tmp.replace(path)
        except OSError:
            pass
    return data, labels, seconds


def supervised_network(robot: Robot, settings: SupervisedSettings | None = None, *, use_cache: bool = True, progress: bool = False) -> SupervisedNet:
    """The ``nn_supervised`` network of ``robot``: labels by joint-space optimisation
    over the training split (every ``frame_stride``-th frame), then supervised training.

    Cached per process and, with ``use_cache``, as a file under :func:`cache_dir`
    (keyed by the robot's joints and limits, the settings and the training frames). ``net.info`` holds
    ``label_seconds`` and ``train_seconds``.
    """
    s = settings or SupervisedSettings()
    data, labels, label_seconds = supervised_dataset(robot, s, use_cache=use_cache, progress=progress)
    key = _cache_key(robot, s, data)
    if use_cache and key in _NETWORKS:
        return _NETWORKS[key]
    path = cache_dir() / f"nn_supervised_{robot.name}_{key}.pt"
    lo, hi = robot.lower_limits.float().cpu(), robot.upper_limits.float().cpu()
    if use_cache and path.is_file():
        try:
            blob = load_torch_file(path, kind="cache file")
            net = SupervisedNet(int(blob["in_features"]), lo, hi, s.hidden)
            net.load_state_dict(blob["state_dict"])
            net.info = json.loads(blob["info"])
            net.eval()
            _NETWORKS[key] = net
            return net
        except Exception:  # a damaged cache file is rebuilt, never trusted
            pass
    r32 = robot.to(dtype=torch.float32)
    net = train_supervised_net(r32, data.encoder.node_features, labels, s)
    net.info["label_seconds"] = label_seconds
    if use_cache:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(path.name + ".tmp")
            torch.save({"in_features": int(data.encoder.node_features[0].numel()), "state_dict": net.state_dict(), "info": json.dumps(net.info)}, tmp)
            tmp.replace(path)
        except OSError:  # an unwritable cache only costs time
            pass
        _NETWORKS[key] = net
    return net

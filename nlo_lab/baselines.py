"""The method and its baselines behind one interface (paper, "Comparative Study").

Every method is a function ``method(robot, demo, settings=None, **context) ->
MethodResult`` that turns a human :class:`~nlo_lab.human.Demonstration` into
joint angles ``(T, n)`` inside the limits, and measures its own wall time (from
the demonstration to the angles: targets, mapping and features included;
training of a network excluded):

* ``latent_encoder``: the method: encoder initialisation + latent optimisation.
* ``encoder_only``: the encoder's latent decoded, no optimisation (the paper's 'Init').
* ``latent_random``: latent optimisation from ``N(0, random_sigma²)``.
* ``joint_space``: Adam on the angles themselves, same objective, clamped to the limits,
  from the robot's neutral pose (:func:`nlo_lab.optimize.optimize_joints`).
* ``nn_supervised``: a feed-forward network from the human node features to the
  angles, trained supervised on joint-space optimisation results over the
  training split (the paper's 'NN'); trained once per settings, cached in memory
  and under the user cache folder (:func:`supervised_network`).
* ``ik``: damped least squares on the two wrist positions only (the human
  wrists mapped into the robot frame, :func:`nlo_lab.human.map_to_robot`),
  limits by clamping after every step; fingers stay at the neutral pose.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Optional

import numpy as np
import torch
from torch import nn

from nlo_lab.errors import SettingsError
from nlo_lab.losses import LossWeights, Targets, objective, targets_from_demonstration
from nlo_lab.optimize import JointOptimizeSettings, OptimizeSettings, optimize_joints, optimize_latent
from nlo_lab.settings import check_int, check_positive

__all__ = [
    "METHODS",
    "LATENT_METHODS",
    "BaselineSettings",
    "SupervisedSettings",
    "MethodResult",
    "SupervisedNet",
    "latent_encoder",
    "encoder_only",
    "latent_random",
    "joint_space",
    "nn_supervised",
    "ik",
    "ik_wrists",
    "wrist_positions",
    "run_method",
    "supervised_labels",
    "train_supervised_net",
    "train_supervised_model",
    "VARIANTS",
    "train_variant",
    "supervised_network",
    "supervised_dataset",
    "cache_dir",
]

METHODS = ("latent_encoder", "encoder_only", "latent_random", "joint_space", "nn_supervised", "ik")
LATENT_METHODS = ("latent_encoder", "encoder_only", "latent_random")  # need a trained model


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
        corpus_seed: seed of the synthetic corpus (:func:`nlo_lab.human.corpus.sign_corpus`).
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
        for name, minimum in (("frame_stride", 1), ("label_iterations", 0), ("epochs", 1), ("batch_size", 1), ("seed", 0), ("corpus_seed", 0)):
            object.__setattr__(self, name, check_int(name, getattr(self, name), minimum))
        hidden = tuple(self.hidden)
        if not hidden or any(isinstance(h, bool) or not isinstance(h, (int, np.integer)) or h < 1 for h in hidden):
            raise SettingsError(f"hidden must be a non-empty tuple of widths >= 1, got {self.hidden!r}")
        object.__setattr__(self, "hidden", tuple(int(h) for h in hidden))
        object.__setattr__(self, "lr", check_positive("lr", self.lr))


@dataclass(frozen=True)
class BaselineSettings:
    """Settings shared by the methods (override with ``dataclasses.replace``).

    Attributes:
        iterations: Adam steps of the latent methods and of ``joint_space`` (same budget).
        patience: early stop after this many evaluations without improvement.
        random_sigma: σ of ``latent_random``'s start ``N(0, σ²)`` (1 = the latent prior).
        seed: seed of the random initialisation.
        joint_lr: Adam step size of ``joint_space`` [rad].
        ik_iterations: damped-least-squares steps of ``ik``.
        ik_damping: λ of ``ik`` [m]: ``dq = Jᵀ (J Jᵀ + λ² I)⁻¹ e``.
        ik_tolerance: ``ik`` stops when every wrist error is below this [m].
        supervised: :class:`SupervisedSettings` of ``nn_supervised``.
    """

    iterations: int = 100
    patience: int = 5
    random_sigma: float = 1.0
    seed: int = 0
    joint_lr: float = 0.05
    ik_iterations: int = 50
    ik_damping: float = 0.05
    ik_tolerance: float = 1e-4
    supervised: SupervisedSettings = field(default_factory=SupervisedSettings)

    def __post_init__(self) -> None:
        check_int("iterations", self.iterations, 0)
        check_int("patience", self.patience, 1)
        check_int("seed", self.seed, 0)
        check_int("ik_iterations", self.ik_iterations, 0)
        for name in ("random_sigma", "joint_lr", "ik_damping", "ik_tolerance"):
            object.__setattr__(self, name, check_positive(name, getattr(self, name)))
        if not isinstance(self.supervised, SupervisedSettings):
            raise SettingsError(f"supervised must be a SupervisedSettings, got {type(self.supervised).__name__}")


@dataclass
class MethodResult:
    """What every method returns.

    Attributes:
        method: the method's name (one of :data:`METHODS`).
        angles: ``(T, n)`` float64 joint angles [rad], inside the limits.
        seconds: wall time from the demonstration to the angles [s].
        history: mean loss per iteration where the method iterates (else empty).
        iterations: iterations taken.
    """

    method: str
    angles: np.ndarray
    seconds: float
    history: list[float] = field(default_factory=list)
    iterations: int = 0


def _numpy(q: torch.Tensor) -> np.ndarray:
    return q.detach().cpu().double().numpy()


def _model(robot, model):
    if model is not None:
        return model
    from nlo_lab.train import load_pretrained

    return load_pretrained(robot)


def _latent(name: str, robot, demo, settings: BaselineSettings, model, init: str, iterations: int) -> MethodResult:
    model = _model(robot, model)
    start = time.perf_counter()
    targets = targets_from_demonstration(demo, dtype=robot.lower_limits.dtype, device=robot.lower_limits.device)
    opt = OptimizeSettings(init=init, iterations=iterations, patience=settings.patience, latent_sigma=settings.random_sigma, seed=settings.seed)
    r = optimize_latent(model, robot, targets, opt)
    return MethodResult(name, _numpy(r.q), time.perf_counter() - start, list(r.history), r.iterations)


def latent_encoder(robot, demo, settings: BaselineSettings | None = None, *, model=None, **_) -> MethodResult:
    """The method: encoder initialisation, then ``settings.iterations`` latent steps.

    Args:
        robot: a loaded robot.
        demo: the human demonstration (T frames).
        settings: :class:`BaselineSettings`.
        model: the robot's :class:`~nlo_lab.model.RetargetModel` (default: the shipped checkpoint).
    """
    s = settings or BaselineSettings()
    return _latent("latent_encoder", robot, demo, s, model, "encoder", s.iterations)


def encoder_only(robot, demo, settings: BaselineSettings | None = None, *, model=None, **_) -> MethodResult:
    """The encoder's latent decoded, no optimisation (the paper's 'Init'). Args as :func:`latent_encoder`."""
    s = settings or BaselineSettings()
    return _latent("encoder_only", robot, demo, s, model, "encoder", 0)


def latent_random(robot, demo, settings: BaselineSettings | None = None, *, model=None, **_) -> MethodResult:
    """Latent optimisation from ``N(0, settings.random_sigma²)``. Args as :func:`latent_encoder`."""
    s = settings or BaselineSettings()
    return _latent("latent_random", robot, demo, s, model, "random", s.iterations)


def joint_space(robot, demo, settings: BaselineSettings | None = None, **_) -> MethodResult:
    """Adam on the angles from the robot's neutral pose (``JointOptimizeSettings`` default), same objective, clamped to the limits."""
    s = settings or BaselineSettings()
    start = time.perf_counter()
    targets = targets_from_demonstration(demo, dtype=robot.lower_limits.dtype, device=robot.lower_limits.device)
    r = optimize_joints(robot, targets, JointOptimizeSettings(iterations=s.iterations, patience=s.patience, lr=s.joint_lr))
    return MethodResult("joint_space", _numpy(r.q), time.perf_counter() - start, list(r.history), r.iterations)


# ---------------------------------------------------------------------- inverse kinematics
def wrist_positions(robot, q: torch.Tensor) -> torch.Tensor:
    """``q (B, n)`` -> ``(B, 2, 3)`` wrist link positions (left, right) in the robot frame [m]."""
    poses = robot.forward_kinematics(q)
    return torch.stack([poses[robot.arm(side).wrist][..., :3, 3] for side in ("left", "right")], dim=-2)


def ik_wrists(
    robot,
    wrists: torch.Tensor,
    mask: torch.Tensor | None = None,
    *,
    q0: torch.Tensor | None = None,
    iterations: int = 50,
    damping: float = 0.05,
    tolerance: float = 1e-4,
    max_error: float = 0.1,
) -> tuple[torch.Tensor, int]:
    """Damped least squares on the two wrist positions, batched over frames.

    ``dq = Jᵀ (J Jᵀ + λ² I)⁻¹ e`` with ``J (B, 6, n)`` the autograd Jacobian of
    both wrist positions and ``e`` the position error; after every step the
    angles are clamped into the limits.

    Args:
        robot: a loaded robot.
        wrists: ``(B, 2, 3)`` target wrist positions (left, right) [m].
        mask: ``(B, 2)`` bool: which targets count (a masked wrist has zero error).
        q0: ``(B, n)`` or ``(n,)`` start angles (default ``robot.neutral_q``).
        iterations: maximum steps.
        damping: λ [m].
        tolerance: stop when every counted wrist error is below this [m].
        max_error: the error of a wrist is shortened to at most this per step [m].

    Returns:
        ``q (B, n)`` inside the limits and the number of steps taken.
    """
    lo, hi = robot.lower_limits, robot.upper_limits
    B = wrists.shape[0]
    wrists = wrists.to(dtype=lo.dtype, device=lo.device)
    if mask is None:
        mask = torch.isfinite(wrists).all(-1)
    mask = mask.to(device=lo.device)
    target = torch.where(mask[..., None], torch.nan_to_num(wrists), torch.zeros_like(wrists))
    q = (robot.neutral_q if q0 is None else q0).to(dtype=lo.dtype, device=lo.device).expand(B, -1).clone()
    q = torch.maximum(torch.minimum(q, hi), lo)
    eye = torch.eye(6, dtype=lo.dtype, device=lo.device)
    steps = 0
    for _ in range(iterations):
        x = q.detach().requires_grad_(True)
        p = wrist_positions(robot, x).reshape(B, 6)  # (B, 6) [m]
        err = (target.reshape(B, 6) - p.detach()) * mask.repeat_interleave(3, dim=1)  # (B, 6)
        if float(err.view(B, 2, 3).norm(dim=-1).max()) < tolerance:
            break
        # Clamp the error per wrist (Buss's "clamping the target distance"): far targets
        # otherwise give huge steps that bounce off the limits.
        e3 = err.view(B, 2, 3)
        err = (e3 * (max_error / e3.norm(dim=-1, keepdim=True).clamp_min(max_error))).reshape(B, 6)
        rows = [torch.autograd.grad(p[:, k].sum(), x, retain_graph=k < 5)[0] for k in range(6)]  # frames are independent
        J = torch.stack(rows, dim=1) * mask.repeat_interleave(3, dim=1)[..., None]  # (B, 6, n)
        JJt = J @ J.transpose(1, 2) + (damping**2) * eye
        dq = (J.transpose(1, 2) @ torch.linalg.solve(JJt, err[..., None]))[..., 0]  # (B, n)
        q = torch.maximum(torch.minimum(q + dq, hi), lo)
        steps += 1
    return q.detach(), steps


def ik(robot, demo, settings: BaselineSettings | None = None, **_) -> MethodResult:
    """Inverse kinematics of the wrists only: the human wrists mapped into the robot
    frame (:func:`nlo_lab.human.map_to_robot`), damped least squares with clamping
    (:func:`ik_wrists`), every frame from the neutral pose."""
    from nlo_lab.human import map_to_robot

    s = settings or BaselineSettings()
    start = time.perf_counter()
    mapped = map_to_robot(demo, robot)[:, :, 2]  # (T, 2, 3) wrists [m], NaN where masked
    wrists = torch.as_tensor(mapped, dtype=robot.lower_limits.dtype, device=robot.lower_limits.device)
    q, steps = ik_wrists(robot, wrists, iterations=s.ik_iterations, damping=s.ik_damping, tolerance=s.ik_tolerance)
    return MethodResult("ik", _numpy(q), time.perf_counter() - start, [], steps)


# ---------------------------------------------------------------------- supervised network
class SupervisedNet(nn.Module):
    """Feed-forward network: flattened human node features -> angles inside the limits.

    It regresses ``u = (q - mid) / half_range``; the output is clamped to
    ``[-1, 1]`` and mapped back, so the angles never leave the limits.
    """

    def __init__(self, in_features: int, lower: torch.Tensor, upper: torch.Tensor, hidden: tuple[int, ...] = (256, 256)):
        super().__init__()
        dims = (in_features, *hidden, lower.shape[0])
        layers: list[nn.Module] = []
        for i, (a, b) in enumerate(zip(dims[:-1], dims[1:])):
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


def supervised_labels(robot, targets: Targets, iterations: int, *, progress: bool = False) -> torch.Tensor:
    """The supervised 'ground truth': joint-space optimisation results ``(N, n)`` for every frame of ``targets``."""
    chunk = 2048  # bounded memory; frames are independent
    out = []
    for i in range(0, len(targets), chunk):
        r = optimize_joints(robot, targets.index(slice(i, i + chunk)), JointOptimizeSettings(iterations=iterations, patience=iterations + 1))
        out.append(r.q.detach())
    return torch.cat(out)


def _fit(module: nn.Module, predict: Callable, x: tuple, u: torch.Tensor, epochs: int, batch: int, lr: float, seed: int, max_seconds: float | None) -> list[float]:
    """Adam on the mean squared error of ``predict(*x_batch)`` against ``u``; returns per-epoch losses."""
    gen = torch.Generator().manual_seed(seed)
    opt = torch.optim.Adam(module.parameters(), lr=lr)
    n = u.shape[0]
    history = []
    start = time.perf_counter()
    module.train()
    for _ in range(epochs):
        order = torch.randperm(n, generator=gen)
        total = 0.0
        for b in range(0, n, batch):
            idx = order[b : b + batch]
            loss = (predict(*(t[idx] if t is not None else None for t in x)) - u[idx]).pow(2).mean()
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            total += float(loss.detach()) * len(idx)
        history.append(total / n)
        if max_seconds is not None and time.perf_counter() - start > max_seconds:
            break
    module.eval()
    return history


def train_supervised_net(robot, features: torch.Tensor, labels: torch.Tensor, settings: SupervisedSettings | None = None) -> SupervisedNet:
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


def train_supervised_model(model, targets: Targets, labels: torch.Tensor, *, epochs: int, batch_size: int = 64, lr: float = 1e-3, seed: int = 0, max_seconds: float | None = None) -> list[float]:
    """Train a :class:`~nlo_lab.model.RetargetModel` (encoder + decoder) supervised on
    ``labels (N, n)`` (paper Eq. ``L_sup``: squared error of the angles, here
    normalised by the half range of each joint): the 'AE'/'GAE' of Table III.

    Returns:
        Mean training loss per epoch. The model is left in eval mode.
    """
    lo, hi = model.decoder.lower, model.decoder.upper
    mid, half = (hi + lo) / 2, ((hi - lo) / 2).clamp_min(1e-9)
    u = ((labels.to(lo.dtype) - mid) / half).clamp(-1, 1)
    ef = targets.edge_features

    def predict(x, e):
        return (model(x, e)[0].to(lo.dtype) - mid) / half

    torch.manual_seed(seed)
    return _fit(model, predict, (targets.node_features.to(lo.dtype), None if ef is None else ef.to(lo.dtype)), u, epochs, batch_size, lr, seed, max_seconds)


VARIANTS = {  # Table III of the paper: name -> (model kind, training objective)
    "AE": ("mlp", "supervised"),
    "GAE": ("graph", "supervised"),
    "AE+FK": ("mlp", "fk"),
    "GAE+FK": ("graph", "fk"),
}


def train_variant(robot, name: str, data: Targets, labels: torch.Tensor | None, seconds: float, *, val_data: Targets | None = None, seed: int = 0):
    """Train one Table III variant for a wall-clock budget.

    Args:
        robot: a loaded robot.
        name: ``"AE"``, ``"GAE"`` (supervised on ``labels``) or ``"AE+FK"``, ``"GAE+FK"``
            (the objective through forward kinematics, :func:`nlo_lab.train.train_model`).
        data: training frames (with encoder features).
        labels: ``(N, n)`` joint-space labels of ``data`` (supervised variants only).
        seconds: training budget [s] (the same for every variant makes them comparable).
        val_data: validation frames of the FK variants (default: ``data``).
        seed: initial weights and batch order.

    Returns:
        ``(model, seconds, steps)``: the model in eval mode, in the robot's dtype.
    """
    from nlo_lab.train import TrainSettings, new_model, train_model

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


def cache_dir() -> Path:
    """The user cache folder of nlo_lab (``$NLO_LAB_CACHE``, else ``$XDG_CACHE_HOME/nlo_lab``, else ``~/.cache/nlo_lab``)."""
    env = os.environ.get("NLO_LAB_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "nlo_lab"


def _cache_key(robot, settings: SupervisedSettings, data: Targets) -> str:
    """Robot joints, limits and collision margins, settings and the training frames' content (a changed corpus is a new key)."""
    ident = {
        "data": hashlib.sha256(data.node_features.detach().cpu().float().numpy().tobytes()).hexdigest(),
        "robot": robot.name,
        "joints": list(robot.joint_names),
        "lower": [round(float(v), 6) for v in robot.lower_limits],
        "upper": [round(float(v), 6) for v in robot.upper_limits],
        "margins": [round(float(v), 6) for v in robot.collision_margins],
        "settings": asdict(settings),
        # 2: labels from the neutral start with the fixed-shoulder end-effector term; bump on any
        # change to the objective or to optimize_joints, or stale labels are reused
        "version": 2,
    }
    return hashlib.sha256(json.dumps(ident, sort_keys=True).encode()).hexdigest()[:16]


_NETWORKS: dict[str, SupervisedNet] = {}


def supervised_dataset(robot, settings: SupervisedSettings | None = None, *, use_cache: bool = True, progress: bool = False) -> tuple[Targets, torch.Tensor, float]:
    """Training frames (every ``frame_stride``-th of the train split) and their
    joint-space optimisation labels ``(N, n)`` [rad], float32.

    The labels are cached as a file under :func:`cache_dir` (keyed like the
    network, without the training settings). Returns ``(targets, labels,
    label_seconds)``; ``label_seconds`` is the time the labels took when made.
    """
    from nlo_lab.train import corpus_targets

    s = settings or SupervisedSettings()
    data = corpus_targets("train", seed=s.corpus_seed).index(slice(0, None, s.frame_stride))
    label_key = _cache_key(robot, SupervisedSettings(frame_stride=s.frame_stride, label_iterations=s.label_iterations, corpus_seed=s.corpus_seed), data)
    path = cache_dir() / f"labels_{robot.name}_{label_key}.pt"
    if use_cache and path.is_file():
        try:
            blob = torch.load(path, map_location="cpu", weights_only=True)
            if blob["labels"].shape == (len(data), robot.n_joints):
                return data, blob["labels"], float(blob["seconds"])
        except Exception:  # a damaged cache file is rebuilt, never trusted
            pass
    start = time.perf_counter()
    labels = supervised_labels(robot.to(dtype=torch.float32), data, s.label_iterations, progress=progress).float()
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


def supervised_network(robot, settings: SupervisedSettings | None = None, *, use_cache: bool = True, progress: bool = False) -> SupervisedNet:
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
            blob = torch.load(path, map_location="cpu", weights_only=True)
            net = SupervisedNet(int(blob["in_features"]), lo, hi, s.hidden)
            net.load_state_dict(blob["state_dict"])
            net.info = json.loads(blob["info"])
            net.eval()
            _NETWORKS[key] = net
            return net
        except Exception:  # a damaged cache file is rebuilt, never trusted
            pass
    r32 = robot.to(dtype=torch.float32)
    net = train_supervised_net(r32, data.node_features, labels, s)
    net.info["label_seconds"] = label_seconds
    if use_cache:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(path.name + ".tmp")
            torch.save({"in_features": int(data.node_features[0].numel()), "state_dict": net.state_dict(), "info": json.dumps(net.info)}, tmp)
            tmp.replace(path)
        except OSError:  # an unwritable cache only costs time
            pass
        _NETWORKS[key] = net
    return net


def nn_supervised(robot, demo, settings: BaselineSettings | None = None, *, network: Optional[SupervisedNet] = None, **_) -> MethodResult:
    """The paper's 'NN': one forward pass of :func:`supervised_network` per frame.

    Args:
        network: a trained :class:`SupervisedNet` (default: :func:`supervised_network`
            with ``settings.supervised``; training time is not part of ``seconds``).
    """
    from nlo_lab.human import node_features

    s = settings or BaselineSettings()
    net = network if network is not None else supervised_network(robot, s.supervised)
    start = time.perf_counter()
    x = torch.as_tensor(np.nan_to_num(node_features(demo)), dtype=torch.float32)
    with torch.no_grad():
        q = net(x)
    q = torch.maximum(torch.minimum(q.double(), robot.upper_limits.double().cpu()), robot.lower_limits.double().cpu())  # round-off of float32
    return MethodResult("nn_supervised", q.numpy(), time.perf_counter() - start)


_FUNCTIONS: dict[str, Callable[..., MethodResult]] = {
    "latent_encoder": latent_encoder,
    "encoder_only": encoder_only,
    "latent_random": latent_random,
    "joint_space": joint_space,
    "nn_supervised": nn_supervised,
    "ik": ik,
}


def run_method(name: str, robot, demo, settings: BaselineSettings | None = None, *, model=None, network=None) -> MethodResult:
    """Run the method ``name`` (one of :data:`METHODS`) on ``demo``.

    Raises:
        SettingsError: an unknown method name.
    """
    if name not in _FUNCTIONS:
        raise SettingsError(f"unknown method {name!r}; expected one of {', '.join(METHODS)}")
    return _FUNCTIONS[name](robot, demo, settings, model=model, network=network)


def mean_objective(robot, demo, angles, weights: LossWeights | None = None) -> float:
    """Mean over frames of ``L(D, K(q))`` (no latent term) of ``angles (T, n)``."""
    targets = targets_from_demonstration(demo, dtype=robot.lower_limits.dtype, device=robot.lower_limits.device)
    q = torch.as_tensor(np.asarray(angles), dtype=robot.lower_limits.dtype, device=robot.lower_limits.device)
    with torch.no_grad():
        total, _ = objective(robot, q, targets, weights)
    return float(total.mean())


__all__.append("mean_objective")

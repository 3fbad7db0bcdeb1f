"""Training of encoder and decoder end to end on the objective, and checkpoints.

Paper Eq. 10: ``min_{psi,phi} L(D, K(f_psi(f_phi(D)))) + ||f_phi(D)||²/σ²`` over
per-frame samples of the synthetic training split (``sign_corpus("train")``);
validation (encoder + decoder, no latent optimisation) on sequences held out of
the training split (:func:`train_validation_split`): the test split stays
unseen until evaluation, so the checkpoint is not chosen on test data;
Adam, gradient-norm clip 10, the best validation state kept.

Departures from the paper's settings, measured on this 2-core CPU (see
``assets/checkpoints/README.md``): batch 64 instead of 16 and lr 1e-3 instead
of 1e-4, because the training budget is minutes of CPU, not a GPU for 20
minutes; a wall-clock budget ``max_seconds`` ends training early.

Command (the same function behind ``nlo-lab train``)::

    python -m nlo_lab.train --robot yumi --out assets/checkpoints/yumi.pt
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch

from nlo_lab.errors import CheckpointError, NloLabError, SettingsError
from nlo_lab.human import sign_corpus
from nlo_lab.losses import COLLISION_FORMS, LossWeights, Targets, latent_loss, objective, targets_from_demonstration
from nlo_lab.model import MODEL_KINDS, RetargetModel, build_model
from nlo_lab.paths import BUNDLED_ROBOTS, CHECKPOINTS_DIR, is_bundled, is_editable_checkout, repair_hint

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
    "main",
]

CHECKPOINT_FORMAT_VERSION = 2  # 2: the decoder's rest offset (decoder.rest_pre) is part of the state


@dataclass(frozen=True)
class TrainSettings:
    """Settings of :func:`train_model`.

    Attributes:
        epochs: passes over the training frames (upper bound; see ``max_seconds``).
        batch_size: frames per step (paper: 16).
        lr: Adam learning rate (paper: 1e-4).
        clip: gradient-norm clip (paper: 10).
        seed: seeds the initial weights and the batch order.
        kind: ``"graph"`` (the paper) or ``"mlp"`` (ablation).
        latent_per_node: ``k`` of ``z (B, N_robot, k)``.
        max_seconds: wall-clock budget [s]; training stops after the step that exceeds it.
        val_every: steps between validations (and at the end of every epoch).
        val_frames: at most this many evenly spaced test frames are validated.
        collision_form: see :func:`nlo_lab.losses.collision_loss`.
        progress: show a tqdm progress bar.
    """

    epochs: int = 30
    batch_size: int = 64
    lr: float = 1e-3
    clip: float = 10.0
    seed: int = 0
    kind: str = "graph"
    latent_per_node: int = 4
    max_seconds: float = 500.0
    val_every: int = 200
    val_frames: int = 1500
    collision_form: str = "hinge"
    progress: bool = True

    def __post_init__(self) -> None:
        for name in ("epochs", "batch_size", "latent_per_node", "val_every", "val_frames"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise SettingsError(f"{name} must be an integer >= 1, got {v!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise SettingsError(f"seed must be an integer >= 0, got {self.seed!r}")
        for name in ("lr", "clip", "max_seconds"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise SettingsError(f"{name} must be finite and > 0, got {v!r}")
        if self.kind not in MODEL_KINDS:
            raise SettingsError(f"unknown model kind {self.kind!r}; expected one of {MODEL_KINDS}")
        if self.collision_form not in COLLISION_FORMS:
            raise SettingsError(f"unknown collision_form {self.collision_form!r}; expected one of {COLLISION_FORMS}")


@dataclass
class TrainResult:
    """What :func:`train_model` returns.

    Attributes:
        model: the best-validation model (eval mode, latent statistics filled in).
        val_loss: its mean validation objective (incl. the latent term).
        history: ``[{"step", "epoch", "train", "val", "seconds"}, ...]`` at each validation.
        seconds: training wall time [s].
        steps: optimiser steps taken.
    """

    model: RetargetModel
    val_loss: float
    history: list[dict[str, float]]
    seconds: float
    steps: int


def _resolve_robot(robot):
    if isinstance(robot, str):
        from nlo_lab.robot import load_robot

        return load_robot(robot)
    return robot


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
    """All frames of ``demos`` as one :class:`Targets`."""
    return Targets.cat([targets_from_demonstration(d, dtype=dtype) for d in demos])


def corpus_targets(split: str, dtype: torch.dtype = torch.float32, seed: int = 0) -> Targets:
    """All frames of ``sign_corpus(split)`` as one :class:`Targets`."""
    return demos_targets(sign_corpus(split, seed=seed), dtype)


def new_model(robot, settings: TrainSettings | None = None, in_features: int | None = None) -> RetargetModel:
    """An untrained model for ``robot`` on the human skeleton graph."""
    from nlo_lab.human import skeleton_graph

    settings = settings or TrainSettings()
    human = skeleton_graph()
    if in_features is None:
        from nlo_lab.human.skeleton import NODE_FEATURES

        in_features = NODE_FEATURES
    return build_model(
        robot.name,
        robot.graph,
        robot.lower_limits,
        robot.upper_limits,
        human,
        in_features=in_features,
        edge_features=int(human.edge_attr.shape[-1]),
        kind=settings.kind,
        latent_per_node=settings.latent_per_node,
        rest=robot.neutral_q,
    )


def _batch_loss(model, robot, batch: Targets, weights: LossWeights, form: str) -> torch.Tensor:
    """Per-frame Eq. 10: objective of the decoded encoder latent + ``||z||²/σ²`` -> ``(B,)``."""
    q, z = model(batch.node_features, batch.edge_features)
    total, _ = objective(robot, q.to(robot.lower_limits.dtype), batch, weights, collision_form=form)
    return total + weights.latent * latent_loss(z)


@torch.no_grad()
def _evaluate(model, robot, data: Targets, weights: LossWeights, form: str, chunk: int = 512) -> float:
    model.eval()
    total = 0.0
    for i in range(0, len(data), chunk):
        total += float(_batch_loss(model, robot, data.index(slice(i, i + chunk)), weights, form).sum())
    model.train()
    return total / len(data)


@torch.no_grad()
def latent_statistics(model: RetargetModel, data: Targets, chunk: int = 1024) -> tuple[torch.Tensor, torch.Tensor]:
    """Mean and standard deviation ``(N_r, k)`` of the encoder's latents over ``data``."""
    zs = [model.encode(data.node_features[i : i + chunk], data.edge_features[i : i + chunk]) for i in range(0, len(data), chunk)]
    z = torch.cat(zs)
    return z.mean(0), z.std(0).clamp_min(1e-3)


def train_model(
    robot,
    settings: TrainSettings | None = None,
    *,
    weights: LossWeights | None = None,
    train_data: Targets | None = None,
    val_data: Targets | None = None,
    model: RetargetModel | None = None,
) -> TrainResult:
    """Train encoder and decoder for ``robot`` (paper Eq. 10).

    Args:
        robot: a ``Robot`` or a robot name.
        settings: :class:`TrainSettings`.
        weights: :class:`LossWeights` (defaults of the paper).
        train_data, val_data: :class:`Targets` with encoder features; default the
            two parts of :func:`train_validation_split` (never the test split).
        model: a model to continue training; a new one otherwise.

    Returns:
        :class:`TrainResult` with the best-validation model.
    """
    settings = settings or TrainSettings()
    weights = weights or LossWeights()
    robot = _resolve_robot(robot)
    dtype = torch.float32
    robot = robot.to(dtype=dtype)
    if train_data is None or val_data is None:
        fit, val = train_validation_split(settings.seed)
        train_data = train_data if train_data is not None else demos_targets(fit)
        val_data = val_data if val_data is not None else demos_targets(val)
    train_data, val_data = train_data.to(dtype=dtype), val_data.to(dtype=dtype)
    if train_data.node_features is None or val_data.node_features is None:
        raise SettingsError("training needs targets with encoder features (node_features)")
    if len(val_data) > settings.val_frames:  # evenly spaced subset, fixed across runs
        val_data = val_data.index(torch.linspace(0, len(val_data) - 1, settings.val_frames).long())

    torch.manual_seed(settings.seed)
    if model is None:
        model = new_model(robot, settings, in_features=int(train_data.node_features.shape[-1]))
    model = model.to(dtype=dtype).train()
    opt = torch.optim.Adam(model.parameters(), lr=settings.lr)
    gen = torch.Generator().manual_seed(settings.seed)
    n = len(train_data)
    steps_per_epoch = max(1, n // settings.batch_size)  # drop the ragged last batch
    total_steps = settings.epochs * steps_per_epoch

    from tqdm.auto import tqdm

    bar = tqdm(total=total_steps, desc=f"train {robot.name}", disable=not settings.progress, leave=False)
    start = time.perf_counter()
    best_val, best_state = _evaluate(model, robot, val_data, weights, settings.collision_form), None
    best_state = {k: v.detach().clone() for k, v in model.state_dict().items()}
    history = [{"step": 0, "epoch": 0, "train": float("nan"), "val": best_val, "seconds": 0.0}]
    step, running, out_of_time = 0, [], False
    for epoch in range(settings.epochs):
        order = torch.randperm(n, generator=gen)
        for b in range(steps_per_epoch):
            batch = train_data.index(order[b * settings.batch_size : (b + 1) * settings.batch_size])
            loss = _batch_loss(model, robot, batch, weights, settings.collision_form).mean()
            opt.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), settings.clip)
            opt.step()
            step += 1
            running.append(float(loss.detach()))
            bar.update(1)
            out_of_time = time.perf_counter() - start > settings.max_seconds
            last_of_epoch = b == steps_per_epoch - 1
            if step % settings.val_every == 0 or last_of_epoch or out_of_time:
                val = _evaluate(model, robot, val_data, weights, settings.collision_form)
                train_mean = sum(running) / len(running)
                running = []
                history.append({"step": step, "epoch": epoch, "train": train_mean, "val": val, "seconds": time.perf_counter() - start})
                bar.set_postfix(train=f"{train_mean:.2f}", val=f"{val:.2f}")
                if val < best_val:
                    best_val = val
                    best_state = {k: v.detach().clone() for k, v in model.state_dict().items()}
            if out_of_time:
                break
        if out_of_time:
            break
    bar.close()
    model.load_state_dict(best_state)
    model.eval()
    mean, std = latent_statistics(model, train_data)
    model.latent_mean.copy_(mean)
    model.latent_std.copy_(std)
    model.train_info = {  # recorded in the checkpoint
        "settings": dataclasses.asdict(settings),
        "weights": weights.as_dict(),
        "val_loss": best_val,
        "history": history,
        "seconds": time.perf_counter() - start,
        "steps": step,
    }
    return TrainResult(model, best_val, history, time.perf_counter() - start, step)


# ---------------------------------------------------------------------- checkpoints
def save_checkpoint(model: RetargetModel, path, robot=None, **info: Any) -> Path:
    """Write ``model`` (float32) with its robot name, format version and settings.

    Args:
        model: the trained model (``model.train_info`` is recorded when present).
        path: destination file (``.pt``); parent folders are created.
        robot: the robot (its joint names are recorded); optional.
        **info: extra JSON-like entries.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    state = {k: v.detach().to("cpu", torch.float32 if v.is_floating_point() else None) for k, v in model.state_dict().items()}
    train_info = dict(getattr(model, "train_info", {}))
    ckpt = {
        "format_version": CHECKPOINT_FORMAT_VERSION,
        "robot": model.robot_name,
        "joint_names": list(robot.joint_names) if robot is not None else None,
        "model_config": dict(model.config),
        "state_dict": state,
        "latent_mean": state["latent_mean"],
        "latent_std": state["latent_std"],
        "val_loss": train_info.get("val_loss"),
        "train_settings": train_info.get("settings"),
        "weights": train_info.get("weights"),
        "history": train_info.get("history"),
        "train_seconds": train_info.get("seconds"),
        "steps": train_info.get("steps"),
        "torch_version": str(torch.__version__),
        **info,
    }
    tmp = path.with_name(path.name + ".tmp")
    torch.save(ckpt, tmp)
    tmp.replace(path)  # never a half-written checkpoint under the real name
    return path


def load_checkpoint(path, robot) -> RetargetModel:
    """Load a checkpoint for ``robot`` (a ``Robot`` or a name).

    Raises:
        CheckpointError: missing or corrupt file, another format version, or a
            checkpoint made for another robot (the message names both).
    """
    path = Path(path)
    robot = _resolve_robot(robot)
    if not path.is_file():
        raise CheckpointError(f"checkpoint {path} not found")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for a damaged file
        raise CheckpointError(f"checkpoint {path} cannot be read (corrupt or not a checkpoint): {type(exc).__name__}") from None
    if not isinstance(ckpt, dict) or "format_version" not in ckpt or "robot" not in ckpt:
        raise CheckpointError(f"checkpoint {path} is not an nlo_lab checkpoint (no format_version/robot)")
    if ckpt["format_version"] != CHECKPOINT_FORMAT_VERSION:
        raise CheckpointError(
            f"checkpoint {path} has format version {ckpt['format_version']!r}, this nlo_lab reads version {CHECKPOINT_FORMAT_VERSION}"
        )
    if ckpt["robot"] != robot.name:
        raise CheckpointError(f"checkpoint {path} was trained for robot {ckpt['robot']!r}, not for {robot.name!r}")
    names = ckpt.get("joint_names")
    if names is not None and (not isinstance(names, (list, tuple)) or list(names) != list(robot.joint_names)):
        raise CheckpointError(f"checkpoint {path} was made for other joints of {robot.name!r} (the robot description changed)")
    try:
        from nlo_lab.human import skeleton_graph

        cfg = ckpt["model_config"]
        model = build_model(
            robot.name,
            robot.graph,
            robot.lower_limits,
            robot.upper_limits,
            skeleton_graph(),
            in_features=cfg["in_features"],
            edge_features=cfg["edge_features"],
            kind=cfg["kind"],
            latent_per_node=cfg["latent_per_node"],
        )
        model.load_state_dict(ckpt["state_dict"])
    except (KeyError, RuntimeError, TypeError, NloLabError) as exc:
        raise CheckpointError(f"checkpoint {path} does not fit the model for {robot.name!r}: {exc}") from None
    model.train_info = {k: ckpt.get(k) for k in ("val_loss", "train_settings", "weights", "history", "train_seconds", "steps")}
    return model.to(dtype=robot.lower_limits.dtype).eval()


def checkpoint_path(name: str) -> Path:
    """``assets/checkpoints/{name}.pt``."""
    return CHECKPOINTS_DIR / f"{name}.pt"


def load_pretrained(robot) -> RetargetModel:
    """The shipped checkpoint of ``robot`` (a ``Robot`` or a name).

    Raises:
        CheckpointError: no shipped checkpoint for this robot (or a bad one).
    """
    robot = _resolve_robot(robot)
    path = checkpoint_path(robot.name)
    if not path.is_file() and not (robot.name in BUNDLED_ROBOTS and is_bundled(path)):
        raise CheckpointError(f"no trained checkpoint for robot {robot.name!r} ({path}); run `nlo-lab train --robot {robot.name}`")
    try:
        return load_checkpoint(path, robot)
    except CheckpointError as exc:
        if robot.name in BUNDLED_ROBOTS and is_bundled(path) and is_bundled(robot.spec.path):  # a shipped file is missing or damaged
            retrain = f" (or retrain it: `nlo-lab train --robot {robot.name}`)" if is_editable_checkout() else ""
            raise CheckpointError(f"{exc}; {repair_hint(path)}{retrain}") from None
        raise


# ---------------------------------------------------------------------- command
def main(argv: list[str] | None = None) -> int:
    """``python -m nlo_lab.train --robot NAME [--epochs N] [--out CKPT] ...``; returns the exit status."""
    p = argparse.ArgumentParser(prog="python -m nlo_lab.train", description=__doc__.splitlines()[0])
    d = TrainSettings()
    p.add_argument("--robot", required=True)
    p.add_argument("--epochs", type=int, default=d.epochs)
    p.add_argument("--batch-size", type=int, default=d.batch_size)
    p.add_argument("--lr", type=float, default=d.lr)
    p.add_argument("--seed", type=int, default=d.seed)
    p.add_argument("--kind", default=d.kind, choices=MODEL_KINDS)
    p.add_argument("--latent-per-node", type=int, default=d.latent_per_node)
    p.add_argument("--max-seconds", type=float, default=d.max_seconds)
    p.add_argument("--threads", type=int, default=1, help="torch threads (1 avoids oversubscription)")
    p.add_argument("--out", default=None, help="checkpoint file (default: assets/checkpoints/NAME.pt in a checkout, ./NAME.pt in an installed package)")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    torch.set_num_threads(max(1, args.threads))
    settings = TrainSettings(
        epochs=args.epochs,
        batch_size=args.batch_size,
        lr=args.lr,
        seed=args.seed,
        kind=args.kind,
        latent_per_node=args.latent_per_node,
        max_seconds=args.max_seconds,
        progress=not args.quiet,
    )
    robot = _resolve_robot(args.robot)
    result = train_model(robot, settings)
    # A checkout retrains the shipped file in place; an installed package is never written to.
    out = Path(args.out) if args.out else checkpoint_path(robot.name) if is_editable_checkout() else Path(f"{robot.name}.pt")
    save_checkpoint(result.model, out, robot)
    print(
        f"trained {robot.name}: {result.steps} steps in {result.seconds:.1f} s, "
        f"best validation loss {result.val_loss:.4f}; wrote {out} ({out.stat().st_size / 1e6:.2f} MB)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Training of the networks on the objective: encoder and decoder end to end (paper Eq. 10), or the auto-decoder.

Mode ``"encoder"`` (the default, the paper's final method):
``min_{psi,phi} L(D, K(f_psi(f_phi(D)))) + ||f_phi(D)||²/σ²`` over per-frame
samples of the synthetic training split; validation (encoder + decoder, no
latent optimisation) on sequences held out of the training split
(:func:`nlo_lab.training.train_validation_split`); Adam, gradient-norm clip 10,
the best validation state kept.

Mode ``"autodecoder"`` (the paper's Eq. ``autodecoder``,
:mod:`nlo_lab.training.autodecoder`): ``min_{z,psi} L(D, K(f_psi(z))) + ||z||²/σ²`` with
one latent code per training frame, optimised with the decoder; validation is latent
optimisation on the held-out frames with the decoder frozen.

Departures from the paper's settings, measured on a 2-core CPU (see
``assets/checkpoints/README.md`` and docs/PAPER.md): batch 64 instead of 16 and lr 1e-3
instead of 1e-4, because the training budget is minutes of CPU, not a GPU for 20
minutes; a wall-clock budget ``max_seconds`` ends training early, and ``max_steps``
gives a budget that does not depend on the machine (what the benchmarks use).

Command: ``nlo-lab train --robot yumi [--epochs N] [--max-seconds S] [--out CKPT]``.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch
from tqdm.auto import tqdm

from nlo_lab.errors import SettingsError
from nlo_lab.human import skeleton_graph
from nlo_lab.human.skeleton import NODE_FEATURES
from nlo_lab.inference import FastPaths, RetargetInputs, fast_paths
from nlo_lab.model import ACTIVATIONS, DEFAULT_ACTIVATION, MODEL_KINDS, EncoderInput, RetargetModel, build_model
from nlo_lab.objective import COLLISION_FORMS, LossWeights, latent_loss, objective
from nlo_lab.robot import as_robot
from nlo_lab.settings import (
    BATCH_RANGE,
    COUNT_RANGE,
    EPOCHS_RANGE,
    ITERATIONS_RANGE,
    LATENT_RANGE,
    RATE_RANGE,
    SECONDS_RANGE,
    SEED_RANGE,
    check_bool,
    check_choice,
    check_int,
    check_range,
)
from nlo_lab.training.autodecoder import LatentCodes, autodecoder_loss, validate_autodecoder
from nlo_lab.training.data import demos_inputs, train_validation_split

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["TRAIN_MODES", "DEFAULT_STARTS", "TrainSettings", "TrainResult", "new_model", "train_model", "latent_statistics"]

TRAIN_MODES = ("encoder", "autodecoder")
# Candidate starts of a robot without a shipped checkpoint, and each one's steps before the choice (TrainSettings.starts).
# A drafted Romeo's elbows swung out on a real recording in 3 of 5 single-start seeds; which basin a start ends in shows
# in its validation objective (on the default corpus: about 42,170-42,220 against 42,320-42,460 after 1000 steps,
# the two less apart and in another order after 300), so the choice waits 1000 steps (at most a third of the training).
DEFAULT_STARTS = 3
DEFAULT_START_STEPS = 1000
STARTS_RANGE = (1, 16)
DECODER_RESTS = ("neutral", "midpoint")  # TrainSettings.decoder_rest  # paper Eq. 10 (encoder + decoder), Eq. autodecoder (decoder + codes)

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
        val_frames: at most this many evenly spaced validation frames are validated.
        collision_form: see :func:`nlo_lab.objective.collision_loss`.
        progress: show a tqdm progress bar.
        activation: the networks' message activation, one of
            :data:`~nlo_lab.model.ACTIVATIONS` (paper: LeakyReLU; its Table II compares the others).
        max_steps: stop after this many optimiser steps (None: ``epochs`` decide); a budget
            that, unlike ``max_seconds``, gives the same model on a busy or an idle machine.
        mode: ``"encoder"`` (paper Eq. 10, encoder and decoder end to end) or
            ``"autodecoder"`` (the paper's Eq. ``autodecoder``: decoder and one latent code
            per training frame, :mod:`nlo_lab.training.autodecoder`).
        code_lr: auto-decoder only: Adam step size of the latent codes (each code moves
            only when its frame is in the batch, about once an epoch, so it needs a larger
            step than the decoder's weights).
        code_init_std: auto-decoder only: the codes start at ``N(0, code_init_std²)``.
        val_iterations: auto-decoder only: latent optimisation steps per validation.
        decoder_rest: what a new decoder decodes before training: ``"neutral"`` (the robot's
            collision-free neutral pose; ``assets/checkpoints/README.md`` says why) or
            ``"midpoint"`` (the middle of every joint's limits: the paper's remap).
        starts: candidate starts: so many models, from seeds ``seed``, ``seed + 1``, ..., each train
            ``start_steps`` steps (at most a third of the training, in at most its share of half of
            ``max_seconds``) on the same data; the one with the lowest validation objective goes on
            to the full training (a start that falls into a poor basin of the objective stays in it:
            a drafted Romeo's elbows swung out in 2 of 3 seeds, ``docs/ARCHITECTURE.md``). None: 1 for a
            robot with a shipped checkpoint (its recipe, ``assets/checkpoints/README.md``), else
            :data:`DEFAULT_STARTS`. 1: today's single start.
        start_steps: steps each candidate start trains before the choice (see ``starts``).
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
    activation: str = DEFAULT_ACTIVATION
    max_steps: int | None = None
    mode: str = "encoder"
    code_lr: float = 0.01
    code_init_std: float = 0.01
    val_iterations: int = 30
    decoder_rest: str = "neutral"
    starts: int | None = None
    start_steps: int = DEFAULT_START_STEPS

    def __post_init__(self) -> None:
        for name, bounds in (("epochs", EPOCHS_RANGE), ("batch_size", BATCH_RANGE), ("latent_per_node", LATENT_RANGE),
                             ("val_every", COUNT_RANGE), ("val_frames", COUNT_RANGE), ("val_iterations", (1, ITERATIONS_RANGE[1])),
                             ("seed", SEED_RANGE)):
            check_int(name, getattr(self, name), *bounds)
        if self.max_steps is not None:
            check_int("max_steps", self.max_steps, 1, EPOCHS_RANGE[1] * BATCH_RANGE[1])
        if self.starts is not None:
            check_int("starts", self.starts, *STARTS_RANGE)
        check_int("start_steps", self.start_steps, 1, EPOCHS_RANGE[1] * BATCH_RANGE[1])
        for name in ("lr", "clip", "code_lr", "code_init_std"):
            object.__setattr__(self, name, check_range(name, getattr(self, name), *RATE_RANGE))
        object.__setattr__(self, "max_seconds", check_range("max_seconds", self.max_seconds, *SECONDS_RANGE))
        object.__setattr__(self, "progress", check_bool("progress", self.progress))
        check_choice("model kind", self.kind, MODEL_KINDS)
        check_choice("collision_form", self.collision_form, COLLISION_FORMS)
        check_choice("activation", self.activation, ACTIVATIONS)
        check_choice("training mode", self.mode, TRAIN_MODES)
        check_choice("decoder_rest", self.decoder_rest, DECODER_RESTS)


@dataclass
class TrainResult:
    """What :func:`train_model` returns.

    Attributes:
        model: the best-validation model (eval mode, latent statistics filled in).
        val_loss: its mean validation objective (incl. the latent term).
        history: ``[{"step", "epoch", "train", "val", "seconds"}, ...]`` at each validation.
        seconds: training wall time [s].
        steps: optimiser steps taken.
        codes: auto-decoder mode: the learned latent code of every training frame
            ``(N, N_r, k)``, in the order of the training frames (at the best validation); else None.
        starts: the candidate starts (``TrainSettings.starts``): ``[{"seed", "steps", "val"}, ...]``, each
            with the steps it trained before the choice and its best validation objective by then; the one
            of lowest ``val`` went on (``history`` and ``steps`` are its own). Without candidates, one entry
            with the training's steps and best validation.
    """

    model: RetargetModel
    val_loss: float
    history: list[dict[str, float]]
    seconds: float
    steps: int
    codes: torch.Tensor | None = None
    starts: list[dict[str, float]] = dataclasses.field(default_factory=list)



def new_model(robot: Robot, settings: TrainSettings | None = None, in_features: int | None = None) -> RetargetModel:
    """An untrained model for ``robot`` on the human skeleton graph."""
    settings = settings or TrainSettings()
    human = skeleton_graph()
    if in_features is None:
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
        rest=robot.neutral_q if settings.decoder_rest == "neutral" else None,
        activation=settings.activation,
    )


def _batch_loss(model, robot, batch: RetargetInputs, weights: LossWeights, form: str, fast: bool | FastPaths) -> torch.Tensor:
    """Per-frame Eq. 10: objective of the decoded encoder latent + ``||z||²/σ²`` -> ``(B,)``."""
    paths = fast_paths(fast, len(batch), batch.targets.shoulder.device)
    q, z = model(batch.encoder.node_features, batch.encoder.edge_features, form=paths.decoder)
    total, _ = objective(robot, q.to(robot.lower_limits.dtype), batch.targets, weights, collision_form=form, **paths.objective_options())
    return total + weights.latent * latent_loss(z)


@torch.no_grad()
def _evaluate(model, robot, data: RetargetInputs, weights: LossWeights, form: str, fast: bool | FastPaths = True, chunk: int = 512) -> float:
    model.eval()
    total = 0.0
    for i in range(0, len(data), chunk):
        total += float(_batch_loss(model, robot, data.index(slice(i, i + chunk)), weights, form, fast).sum())
    model.train()
    return total / len(data)


@torch.no_grad()
def latent_statistics(model: RetargetModel, data: EncoderInput | RetargetInputs, chunk: int = 1024) -> tuple[torch.Tensor, torch.Tensor]:
    """Mean and standard deviation ``(N_r, k)`` of the encoder's latents over ``data``."""
    x = data.encoder if isinstance(data, RetargetInputs) else data
    zs = [model.encode(x.node_features[i : i + chunk], x.edge_features[i : i + chunk]) for i in range(0, len(x), chunk)]
    z = torch.cat(zs)
    return z.mean(0), z.std(0).clamp_min(1e-3)


def _start_count(settings: TrainSettings, robot: Robot, model: RetargetModel | None) -> int:
    """How many candidate starts ``train_model`` tries (``TrainSettings.starts``): one to continue a given model."""
    if model is not None:
        return 1
    if settings.starts is not None:
        return settings.starts
    from nlo_lab.model import checkpoint_path
    from nlo_lab.paths import is_bundled

    shipped = is_bundled(robot.spec.path) and checkpoint_path(robot.name).is_file()
    return 1 if shipped else DEFAULT_STARTS


class _Run:
    """One start of a training: its model (and auto-decoder codes), optimisers, batch order and best validation."""

    def __init__(self, robot, settings: TrainSettings, weights: LossWeights, train_data: RetargetInputs, val_data: RetargetInputs,
                 fast, seed: int, model: RetargetModel | None, start: float, bar) -> None:
        self.settings, self.seed, self.start, self.bar = settings, seed, start, bar
        self.n = n = len(train_data)
        self.steps_per_epoch = max(1, n // settings.batch_size)  # drop the ragged last batch
        torch.manual_seed(seed)
        if model is None:
            model = new_model(robot, settings, in_features=int(train_data.encoder.node_features.shape[-1]))
        self.model = model = model.to(dtype=train_data.targets.dtype).train()
        form = settings.collision_form
        if settings.mode == "autodecoder":  # Eq. autodecoder: the decoder and one code per frame; the encoder takes no part
            model.config["training"] = "autodecoder"
            codes = LatentCodes(n, model.latent_shape, settings.code_init_std, seed)
            self.codes: LatentCodes | None = codes
            self.params = list(model.decoder.parameters())
            self.code_opt: torch.optim.Optimizer | None = torch.optim.SparseAdam(list(codes.parameters()), lr=settings.code_lr)

            def batch_loss(idx):
                return autodecoder_loss(model, robot, codes, idx, train_data.targets.index(idx), weights, form, fast)

            def validate():
                return validate_autodecoder(model, robot, val_data, codes.all().mean(0), weights, form, settings.val_iterations, fast)
        else:
            self.codes, self.code_opt, self.params = None, None, list(model.parameters())

            def batch_loss(idx):
                return _batch_loss(model, robot, train_data.index(idx), weights, form, fast)

            def validate():
                return _evaluate(model, robot, val_data, weights, form, fast)

        self.batch_loss, self.validate = batch_loss, validate
        self.opt = torch.optim.Adam(self.params, lr=settings.lr)
        self.gen = torch.Generator().manual_seed(seed)
        self.step, self.epoch, self.b, self.running = 0, 0, 0, []
        self.order = torch.empty(0, dtype=torch.long)
        self.best_val = validate()
        self.best_state, self.best_codes = self.snapshot()
        self.history = [{"step": 0, "epoch": 0, "train": float("nan"), "val": self.best_val, "seconds": time.perf_counter() - start}]

    def snapshot(self):
        state = {k: v.detach().clone() for k, v in self.model.state_dict().items()}
        return state, None if self.codes is None else self.codes.all()

    def advance(self, last_step: int, deadline: float) -> None:
        """Train until step ``last_step``, or until the step that passes ``deadline`` (a ``time.perf_counter()``)."""
        s = self.settings
        while self.step < last_step:
            if self.b == 0:
                self.order = torch.randperm(self.n, generator=self.gen)
            idx = self.order[self.b * s.batch_size : (self.b + 1) * s.batch_size]
            loss = self.batch_loss(idx).mean()
            self.opt.zero_grad(set_to_none=True)
            if self.code_opt is not None:
                self.code_opt.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(self.params, s.clip)
            self.opt.step()
            if self.code_opt is not None:
                self.code_opt.step()
            self.step += 1
            self.running.append(float(loss.detach()))
            self.bar.update(1)
            stop = time.perf_counter() > deadline or self.step >= last_step
            epoch, self.b = self.epoch, self.b + 1
            last_of_epoch = self.b == self.steps_per_epoch
            if last_of_epoch:
                self.epoch, self.b = self.epoch + 1, 0
            if self.step % s.val_every == 0 or last_of_epoch or stop:
                val = self.validate()
                train_mean = sum(self.running) / len(self.running)
                self.running = []
                self.history.append({"step": self.step, "epoch": epoch, "train": train_mean, "val": val,
                                     "seconds": time.perf_counter() - self.start})
                self.bar.set_postfix(train=f"{train_mean:.2f}", val=f"{val:.2f}")
                if val < self.best_val:
                    self.best_val = val
                    self.best_state, self.best_codes = self.snapshot()
            if stop:
                break

def train_model(
    robot: Robot | str,
    settings: TrainSettings | None = None,
    *,
    weights: LossWeights | None = None,
    train_data: RetargetInputs | None = None,
    val_data: RetargetInputs | None = None,
    model: RetargetModel | None = None,
    fast: bool | FastPaths = True,
) -> TrainResult:
    """Train the networks of ``robot``: encoder and decoder (paper Eq. 10), or the auto-decoder (``settings.mode``).

    Args:
        robot: a ``Robot`` or a robot name.
        settings: :class:`TrainSettings`.
        weights: :class:`LossWeights`; default ``LossWeights().latent_stage()``, the pipeline's latent optimisation's
            objective (without the hand stage's terms).
        train_data, val_data: :class:`~nlo_lab.inference.RetargetInputs` (targets and encoder input); default the
            two parts of :func:`train_validation_split` (never the test split).
        model: a model to continue training; a new one otherwise.
        fast: the evaluations each step runs (same numbers): True (the default) the fastest
            for the batch size (:meth:`~nlo_lab.inference.FastPaths.for_frames`), False the
            readable forms, or a :class:`~nlo_lab.inference.FastPaths`.

    Returns:
        :class:`TrainResult` with the best-validation model (and, auto-decoder, the codes).
    """
    settings = settings or TrainSettings()
    weights = weights or LossWeights().latent_stage()  # the decoder serves the latent optimisation: its objective
    robot = as_robot(robot)
    dtype = torch.float32
    robot = robot.to(dtype=dtype)
    if train_data is None or val_data is None:
        fit, val = train_validation_split(settings.seed)
        train_data = train_data if train_data is not None else demos_inputs(fit)
        val_data = val_data if val_data is not None else demos_inputs(val)
    if not isinstance(train_data, RetargetInputs) or not isinstance(val_data, RetargetInputs):
        raise SettingsError("training needs frames with targets and encoder input (nlo_lab.inference.RetargetInputs)")
    train_data, val_data = train_data.to(dtype=dtype), val_data.to(dtype=dtype)
    if len(val_data) > settings.val_frames:  # evenly spaced subset, fixed across runs
        val_data = val_data.index(torch.linspace(0, len(val_data) - 1, settings.val_frames).long())

    n_starts = _start_count(settings, robot, model)
    autodecoder = settings.mode == "autodecoder"
    n = len(train_data)
    steps_per_epoch = max(1, n // settings.batch_size)  # drop the ragged last batch
    total_steps = settings.epochs * steps_per_epoch
    if settings.max_steps is not None:
        total_steps = min(total_steps, settings.max_steps)
    trial_steps = min(settings.start_steps, total_steps // 3) if n_starts > 1 else 0
    if trial_steps == 0:  # too short a training to try starts
        n_starts = 1

    label = "train" if not autodecoder else "auto-decode"
    bar = tqdm(total=total_steps + (n_starts - 1) * trial_steps, desc=f"{label} {robot.name}", disable=not settings.progress, leave=False)
    start = time.perf_counter()
    runs = []
    for c in range(n_starts):  # the candidate starts: each trains trial_steps, in at most its share of half the budget
        run = _Run(robot, settings, weights, train_data, val_data, fast, (settings.seed + c) % (SEED_RANGE[1] + 1), model, start, bar)
        if n_starts > 1:
            bar.set_description(f"{label} {robot.name} (start {c + 1} of {n_starts})")
            run.advance(trial_steps, start + settings.max_seconds * (c + 1) / (2 * n_starts))
        runs.append(run)
    run = min(runs, key=lambda r: r.best_val)  # the lowest validation objective continues (the first on a tie)
    starts = [{"seed": r.seed, "steps": r.step, "val": r.best_val} for r in runs]
    del runs
    if n_starts > 1:
        bar.set_description(f"{label} {robot.name} (start seed {run.seed})")
    run.advance(total_steps, start + settings.max_seconds)
    bar.close()
    if n_starts == 1:
        starts = [{"seed": run.seed, "steps": run.step, "val": run.best_val}]
    model, best_val, history, step, best_codes = run.model, run.best_val, run.history, run.step, run.best_codes
    model.load_state_dict(run.best_state)
    model.eval()
    if autodecoder:  # train-stats starts from the learned codes' distribution
        mean, std = best_codes.mean(0), best_codes.std(0).clamp_min(1e-3)
    else:
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
        "starts": starts,
    }
    return TrainResult(model, best_val, history, time.perf_counter() - start, step, best_codes, starts)

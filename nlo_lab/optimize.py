"""Inference: latent optimisation with a frozen decoder, and the joint-space baseline.

Latent optimisation (paper Eq. 9/12): ``z* = argmin_z L(D, K(f_psi(z))) + ||z||²/σ²``
with Adam on ``z`` only; the decoder's parameters are frozen
(``requires_grad`` off for the duration). The whole sequence is one batch:
frames are independent (per-frame losses are summed, and Adam's update is per
coordinate), so one batched step advances every frame at once.

Iterations: the loss is evaluated at the start point and after every Adam step;
``history[0]`` is the initial mean loss, ``history[i]`` the mean after ``i``
steps. At most ``iterations`` steps; the loop stops early after ``patience``
evaluations in a row without improving the best mean loss. The *best* latent is
kept per frame (each frame keeps the ``z`` of its own lowest loss), so the
result is never worse than the start for any frame.

Temporal coherence. With ``weights.smooth > 0`` and a frame rate in the targets, the
objective also holds :func:`nlo_lab.objective.smoothness_loss` over consecutive frames, so
frames are no longer independent: the best point is then tracked for the whole sequence
(the iteration with the lowest mean), not per frame, which could stitch together frames
from different iterations. And the start is warm along the sequence
(:func:`sequence_start`): each frame may start from its own encoder latent or from one of
its ``settings.warm_window`` neighbours' on either side, the choice over the whole sequence
minimising objective + smoothness by dynamic programming (Viterbi). The encoder maps
every frame on its own and, where two arm configurations fit about equally, it can
alternate between them from frame to frame; gradient steps do not cross from one to the
other, the start does.

Step size: Adam ``lr = 0.01`` on ``z``. Measured on 4 clips of the synthetic
test split with a YuMi model (mean Fréchet, encoder alone 0.216 m): lr 0.003
-> 0.179 m, 0.01 -> 0.172 m, 0.03 -> 0.172 m but the patience stop fires
after a few steps on some clips (Adam's first steps overshoot), 0.1 -> 0.207 m
(stops after 5 steps on most clips). With the smoothness term (issue 14) the default
(``lr=None``) is 0.005 instead (:data:`SMOOTH_LR`): at 0.01 Adam's first steps, the same size for every latent coordinate,
make neighbouring frames move apart, the coupled loss jumps (NAO, introduction_12: mean
84 -> 267 after two steps) and the patience stop ends the run after 5 steps with the
jumps still in; at 0.005 YuMi's mean Fréchet on the test split is 0.0568 m (0.0582 m
before issue 14), and the loss descends from the first step.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass, field
from typing import Callable, Optional

import torch

from nlo_lab.errors import SettingsError
from nlo_lab.objective import COLLISION_FORMS, TERMS, LossWeights, Objective, Targets, smoothness_loss, step_cost

__all__ = [
    "INITS",
    "OptimizeSettings",
    "JointOptimizeSettings",
    "OptimizeResult",
    "initial_latent",
    "sequence_start",
    "optimize_latent",
    "optimize_stream",
    "optimize_joints",
]

INITS = ("encoder", "random", "train-stats", "zeros")
PAPER_LR = 0.01  # Adam step on z, frames independent (module docstring, "Step size")
SMOOTH_LR = 0.005  # the same with the smoothness term coupling the frames
JOINT_INITS = ("neutral", "midpoint", "zeros")
JOINT_LIMITS = ("clamp", "penalty")


def _check_int(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise SettingsError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return value


def _check_positive(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SettingsError(f"{name} must be a number, got {value!r}") from None
    if not v > 0 or v == float("inf"):
        raise SettingsError(f"{name} must be finite and > 0, got {value!r}")
    return v


@dataclass(frozen=True)
class OptimizeSettings:
    """Settings of latent optimisation.

    Attributes:
        init: initial latent: ``"encoder"`` (neural initialisation), ``"random"``
            (N(0, latent_sigma²)), ``"train-stats"`` (N(mean, std²) of the
            training latents) or ``"zeros"``.
        iterations: maximum number of Adam steps (>= 0; 0 = the start point).
        patience: stop after this many evaluations without improvement.
        lr: Adam step size on ``z``; None: :data:`PAPER_LR` (0.01) when the frames are
            independent, :data:`SMOOTH_LR` (0.005) with the smoothness term (module docstring).
        latent_sigma: σ of the random initialisation.
        warm_start: in :func:`optimize_stream`, frame t starts from frame t-1's best z;
            in :func:`optimize_latent` with smoothing on, the start latents are chosen
            along the sequence (:func:`sequence_start`).
        warm_window: how many neighbours on each side a frame may borrow its start
            latent from in :func:`sequence_start` (0 = its own only).
        seed: seed of the random initialisations.
        collision_form: ``"hinge"`` or ``"paper"`` (see :func:`nlo_lab.objective.collision_loss`).
    """

    init: str = "encoder"
    iterations: int = 100
    patience: int = 5
    lr: float | None = None
    latent_sigma: float = 1.0
    warm_start: bool = True
    warm_window: int = 2
    seed: int = 0
    collision_form: str = "hinge"

    def __post_init__(self) -> None:
        if self.init not in INITS:
            raise SettingsError(f"unknown init {self.init!r}; expected one of {', '.join(INITS)}")
        _check_int("iterations", self.iterations, 0)
        _check_int("patience", self.patience, 1)
        _check_int("seed", self.seed, 0)
        _check_int("warm_window", self.warm_window, 0)
        if self.lr is not None:
            object.__setattr__(self, "lr", _check_positive("lr", self.lr))
        object.__setattr__(self, "latent_sigma", _check_positive("latent_sigma", self.latent_sigma))
        if self.collision_form not in COLLISION_FORMS:
            raise SettingsError(f"unknown collision_form {self.collision_form!r}; expected one of {COLLISION_FORMS}")


@dataclass(frozen=True)
class JointOptimizeSettings:
    """Settings of the joint-space baseline (the same objective on the angles).

    Attributes:
        iterations, patience, lr: as :class:`OptimizeSettings` (lr in rad).
        init: the robot's collision-free ``"neutral"`` pose (the spec's
            ``neutral_pose``, where the decoders start too), the ``"midpoint"``
            of the limits, or ``"zeros"`` (clipped into the limits). The start
            decides the arm configuration: on three YuMi test clips
            (hospital_03, hospital_05, introduction_04; 600 iterations) the
            midpoint ended at mean Fréchet 0.24 m, the neutral pose at 0.13 m.
        limits: ``"clamp"`` (projected gradient: clamp after every step) or
            ``"penalty"`` (soft ``penalty * sum(violation²)``, the paper's L_lim;
            the result may then leave the limits).
        penalty: weight of the soft limit penalty (paper: 10000).
        collision_form: as :class:`OptimizeSettings`.
    """

    iterations: int = 100
    patience: int = 5
    lr: float = 0.05
    init: str = "neutral"
    limits: str = "clamp"
    penalty: float = 10000.0
    collision_form: str = "hinge"

    def __post_init__(self) -> None:
        _check_int("iterations", self.iterations, 0)
        _check_int("patience", self.patience, 1)
        object.__setattr__(self, "lr", _check_positive("lr", self.lr))
        object.__setattr__(self, "penalty", _check_positive("penalty", self.penalty))
        if self.init not in JOINT_INITS:
            raise SettingsError(f"unknown joint init {self.init!r}; expected one of {JOINT_INITS}")
        if self.limits not in JOINT_LIMITS:
            raise SettingsError(f"unknown limits mode {self.limits!r}; expected one of {JOINT_LIMITS}")
        if self.collision_form not in COLLISION_FORMS:
            raise SettingsError(f"unknown collision_form {self.collision_form!r}; expected one of {COLLISION_FORMS}")


@dataclass
class OptimizeResult:
    """What the optimisers return.

    Attributes:
        q: ``(T, n)`` joint angles [rad] at each frame's best point (detached).
        z: ``(T, N_r, k)`` best latents, or None for the joint-space baseline.
        history: mean optimised loss per evaluation (``history[0]`` = start).
        terms: unweighted objective terms at the best point, each ``(T,)``.
        loss: ``(T,)`` best optimised loss per frame (objective + latent term).
        iterations: Adam steps taken.
        seconds: wall time [s].
        init: the initialisation used.
    """

    q: torch.Tensor
    z: Optional[torch.Tensor]
    history: list[float]
    terms: dict[str, torch.Tensor]
    loss: torch.Tensor
    iterations: int
    seconds: float
    init: str = ""
    extra: dict = field(default_factory=dict)


@contextlib.contextmanager
def _frozen(module: torch.nn.Module):
    """Turn off parameter gradients (and training mode) for the duration."""
    flags = [p.requires_grad for p in module.parameters()]
    was_training = module.training
    module.eval()
    for p in module.parameters():
        p.requires_grad_(False)
    try:
        yield module
    finally:
        for p, f in zip(module.parameters(), flags):
            p.requires_grad_(f)
        module.train(was_training)


def _model_dtype(model: torch.nn.Module) -> torch.dtype:
    return next(model.parameters()).dtype


def _model_device(model: torch.nn.Module) -> torch.device:
    return next(model.parameters()).device


def initial_latent(model, targets: Targets, settings: OptimizeSettings) -> torch.Tensor:
    """The start latent ``z0 (T, N_r, k)`` for ``settings.init``.

    Raises:
        SettingsError: ``"encoder"`` on targets without encoder features.
    """
    T = len(targets)
    shape = (T, *model.latent_shape)
    dtype, device = _model_dtype(model), _model_device(model)
    if settings.init == "zeros":
        return torch.zeros(shape, dtype=dtype, device=device)
    if settings.init == "encoder":
        if targets.node_features is None:
            raise SettingsError("init 'encoder' needs the targets' node_features (nlo_lab.human.node_features)")
        with torch.no_grad(), _frozen(model):
            ef = None if targets.edge_features is None else targets.edge_features.to(device=device, dtype=dtype)
            return model.encode(targets.node_features.to(device=device, dtype=dtype), ef).detach()
    gen = torch.Generator().manual_seed(settings.seed)
    noise = torch.randn(shape, generator=gen, dtype=torch.float64).to(device=device, dtype=dtype)
    if settings.init == "random":
        return noise * settings.latent_sigma
    return model.latent_mean.to(dtype) + model.latent_std.to(dtype) * noise  # "train-stats"


def _smoothness(robot, targets: Targets, weights: LossWeights, anchor: torch.Tensor | None = None):
    """``q (T, n) -> (T,)`` the weighted smoothness term, or None when it does not apply.

    ``anchor (n,)``: fixed angles of the frame just before ``targets`` (the previous
    chunk's last frame); frame 0 then pays its step from there.
    """
    if weights.smooth == 0 or targets.fps is None or len(targets) + (anchor is not None) < 2:
        return None
    limits, fps, w = robot.velocity_limits, float(targets.fps), weights.smooth
    if anchor is None:
        return lambda q: w * smoothness_loss(q, fps, limits)
    anchor = anchor.detach().to(robot.lower_limits.dtype).reshape(1, -1)
    return lambda q: w * smoothness_loss(torch.cat([anchor, q]), fps, limits)[1:]


@torch.no_grad()
def sequence_start(model, robot, targets: Targets, z0: torch.Tensor, weights: LossWeights | None = None,
                   window: int = 2, collision_form: str = "hinge", anchor: torch.Tensor | None = None) -> torch.Tensor:
    """Warm start along the sequence: per frame, its own start latent or a neighbour's.

    Frame t's candidates are ``z0[t - window .. t + window]``. Each candidate costs its
    objective at frame t (plus the latent term); consecutive choices cost the
    smoothness term between their decoded angles (frame 0 also its step from the fixed
    ``anchor (n,)`` when given). The cheapest sequence of choices
    is found exactly by dynamic programming (Viterbi), ``O(T (2 window + 1)²)``.

    Returns:
        ``(T, N_r, k)`` start latents (``z0`` itself when smoothing does not apply).
    """
    weights = weights or LossWeights()
    smooth = _smoothness(robot, targets, weights, anchor)
    T = len(targets)
    if smooth is None or window == 0:
        return z0
    dtype = robot.lower_limits.dtype
    targets = targets.to(dtype=dtype)
    loss_fn = Objective(robot, targets, weights, collision_form)
    K = 2 * window + 1
    idx = (torch.arange(T)[:, None] + torch.arange(-window, window + 1)[None]).clamp(0, T - 1)  # (T, K)
    unary, angles = [], []
    with _frozen(model):
        for k in range(K):
            z = z0[idx[:, k]]
            q = model.decode(z).to(dtype)
            total, _ = loss_fn(q)
            unary.append(total + weights.latent * z.pow(2).flatten(1).sum(1).to(dtype))
            angles.append(q)
    unary_np = torch.stack(unary, 1).double().numpy()  # (T, K)
    Q = torch.stack(angles, 1).double()  # (T, K, n)
    step = Q[1:, None] - Q[:-1, :, None]  # (T-1, K_prev, K_next, n)
    pair = (weights.smooth * step_cost(step, float(targets.fps), robot.velocity_limits.double())).numpy()
    if anchor is not None:  # frame 0's step from the fixed frame before it
        first = step_cost(Q[0] - anchor.detach().double().reshape(1, -1), float(targets.fps), robot.velocity_limits.double())
        unary_np[0] += weights.smooth * first.numpy()
    cost, back = unary_np[0], []
    for t in range(1, T):
        total = cost[:, None] + pair[t - 1]  # (K_prev, K_next)
        arg = total.argmin(0)
        back.append(arg)
        cost = total[arg, range(K)] + unary_np[t]
    k = int(cost.argmin())
    path = [k]
    for arg in reversed(back):
        k = int(arg[k])
        path.append(k)
    path.reverse()
    return z0[idx[torch.arange(T), torch.tensor(path)]]


def _select(better: torch.Tensor, new, old):
    """Per sample ``new`` where ``better (B,)`` else ``old``; tensors ``(B, ...)`` or dicts of them."""
    if isinstance(new, dict):
        return {k: _select(better, new[k], old[k]) for k in old}
    return torch.where(better.view(-1, *([1] * (new.ndim - 1))), new.detach(), old)


class _Adam:
    """Adam on one tensor, the same arithmetic as ``torch.optim.Adam``'s default
    (single-tensor) step, without the optimiser's per-step bookkeeping (a few
    hundred microseconds matter when one iteration at batch 1 is about a millisecond)."""

    def __init__(self, x: torch.Tensor, lr: float, betas=(0.9, 0.999), eps: float = 1e-8):
        self.lr, self.betas, self.eps, self.step = lr, betas, eps, 0
        self.m, self.v = torch.zeros_like(x), torch.zeros_like(x)

    @torch.no_grad()
    def update(self, x: torch.Tensor, grad: torch.Tensor) -> None:
        b1, b2 = self.betas
        self.step += 1
        self.m.lerp_(grad, 1 - b1)
        self.v.mul_(b2).addcmul_(grad, grad, value=1 - b2)
        bias1, bias2 = 1 - b1**self.step, 1 - b2**self.step
        denom = (self.v.sqrt() / math.sqrt(bias2)).add_(self.eps)
        x.addcdiv_(self.m, denom, value=-self.lr / bias1)


def _descend(
    params: torch.Tensor,
    evaluate: Callable[[torch.Tensor], tuple[torch.Tensor, torch.Tensor, torch.Tensor | dict]],
    project: Callable[[torch.Tensor], None] | None,
    iterations: int,
    patience: int,
    lr: float,
    callback,
    per_sample: bool = True,
):
    """Adam on ``params`` (B, ...) with per-sample best tracking and patience.

    ``evaluate(x)`` returns ``loss (B,)``, ``q (B, n)`` and the terms (a ``(B, K)``
    tensor or a dict of ``(B,)``), all tracked at each sample's best point; with
    ``per_sample=False`` (samples coupled by a sequence term) at the best mean instead.
    """
    x = params.detach().clone().requires_grad_(True)
    adam = _Adam(x, lr)
    best_loss = best_x = best_q = best_terms = None
    history: list[float] = []
    best_mean, stale, steps = float("inf"), 0, 0
    for it in range(iterations + 1):
        loss, q, terms = evaluate(x)  # loss (B,)
        with torch.no_grad():
            mean = float(loss.mean())
            history.append(mean)
            if best_loss is None:
                best_loss, best_x, best_q = loss.detach().clone(), x.detach().clone(), q.detach().clone()
                best_terms = {k: v.detach().clone() for k, v in terms.items()} if isinstance(terms, dict) else terms.detach().clone()
            elif per_sample:
                better = loss < best_loss  # (B,)
                best_loss, best_x, best_q, best_terms = (
                    _select(better, new, old) for new, old in ((loss, best_loss), (x, best_x), (q, best_q), (terms, best_terms))
                )
            elif mean < best_mean:  # coupled samples: the whole point at the best mean (no per-sample select)
                best_loss, best_x, best_q = loss.detach(), x.detach().clone(), q.detach().clone()  # q may be x
                best_terms = {k: v.detach() for k, v in terms.items()} if isinstance(terms, dict) else terms.detach()
            if mean < best_mean:
                best_mean, stale = mean, 0
            else:
                stale += 1
        if callback is not None:
            callback(it, mean)
        if it == iterations or stale >= patience:
            break
        (grad,) = torch.autograd.grad(loss.sum(), x)
        adam.update(x, grad)
        steps += 1
        if project is not None:
            with torch.no_grad():
                project(x)
    return best_x, best_q, best_loss, best_terms, history, steps


def optimize_latent(
    model,
    robot,
    targets: Targets,
    settings: OptimizeSettings | None = None,
    *,
    weights: LossWeights | None = None,
    z0: torch.Tensor | None = None,
    callback: Callable[[int, float], None] | None = None,
    anchor: torch.Tensor | None = None,
) -> OptimizeResult:
    """Optimise the latent of every frame of ``targets`` at once, decoder frozen.

    Args:
        model: a :class:`nlo_lab.model.RetargetModel` for ``robot``.
        robot: the robot (FK, capsules).
        targets: :class:`Targets` of T frames.
        settings: :class:`OptimizeSettings`.
        weights: :class:`LossWeights`; ``weights.latent`` scales ``||z||²``.
        z0: ``(T, N_r, k)`` start latents; overrides ``settings.init`` (warm start).
        callback: called as ``callback(iteration, mean_loss)`` after every evaluation.
        anchor: ``(n,)`` fixed joint angles of the frame just before ``targets`` (the
            previous chunk's last frame, :func:`nlo_lab.retarget.retarget`): with the
            smoothness term on, frame 0's step from it is part of the objective and of
            the warm start, so a sequence optimised in chunks has no seam.

    Returns:
        :class:`OptimizeResult` with ``q (T, n)`` in the robot's dtype.
    """
    settings = settings or OptimizeSettings()
    weights = weights or LossWeights()
    start = time.perf_counter()
    dtype = robot.lower_limits.dtype
    targets = targets.to(dtype=dtype)
    init = settings.init if z0 is None else "given"
    if z0 is None:
        z0 = initial_latent(model, targets, settings)
    elif z0.shape != (len(targets), *model.latent_shape):
        raise SettingsError(f"z0 must be {(len(targets), *model.latent_shape)}, got {tuple(z0.shape)}")

    loss_fn = Objective(robot, targets, weights, settings.collision_form)
    if anchor is not None and anchor.shape != robot.lower_limits.shape:
        raise SettingsError(f"anchor must be {tuple(robot.lower_limits.shape)}, got {tuple(anchor.shape)}")
    smooth = _smoothness(robot, targets, weights, anchor)
    if smooth is not None and settings.warm_start:
        z0 = sequence_start(model, robot, targets, z0, weights, settings.warm_window, settings.collision_form, anchor)

    def evaluate(z):
        q = model.decode(z).to(dtype)
        total, terms = loss_fn(q)
        if smooth is not None:
            total = total + smooth(q)
        # + weights.latent * latent_loss(z), in one op
        return torch.add(total, z.pow(2).flatten(1).sum(1).to(dtype), alpha=weights.latent), q, terms

    with _frozen(model):
        lr = settings.lr if settings.lr is not None else (PAPER_LR if smooth is None else SMOOTH_LR)
        z, q, loss, terms, history, steps = _descend(
            z0.to(_model_dtype(model)), evaluate, None, settings.iterations, settings.patience, lr, callback,
            per_sample=smooth is None,
        )
    return OptimizeResult(q, z, history, dict(zip(TERMS, terms.unbind(1))), loss, steps, time.perf_counter() - start, init)


def optimize_stream(
    model,
    robot,
    targets: Targets,
    settings: OptimizeSettings | None = None,
    *,
    weights: LossWeights | None = None,
    z0: torch.Tensor | None = None,
    callback: Callable[[int, float], None] | None = None,
) -> OptimizeResult:
    """Frame by frame, as a live stream: with ``settings.warm_start`` frame t starts
    from frame t-1's best latent (frame 0 from ``z0`` or ``settings.init``).

    ``history`` is the mean over frames of each evaluation (a frame that stopped
    early contributes its last value); ``iterations`` the total steps.
    """
    settings = settings or OptimizeSettings()
    start = time.perf_counter()
    inits = initial_latent(model, targets, settings) if z0 is None else z0
    prev = None
    parts: list[OptimizeResult] = []
    for t in range(len(targets)):
        start_z = prev if (settings.warm_start and prev is not None) else inits[t : t + 1]
        r = optimize_latent(model, robot, targets.index(slice(t, t + 1)), settings, weights=weights, z0=start_z)
        prev = r.z
        parts.append(r)
        if callback is not None:
            callback(t, r.history[-1])
    n = max(len(r.history) for r in parts)
    history = [sum(r.history[min(i, len(r.history) - 1)] for r in parts) / len(parts) for i in range(n)]
    return OptimizeResult(
        q=torch.cat([r.q for r in parts]),
        z=torch.cat([r.z for r in parts]),
        history=history,
        terms={k: torch.cat([r.terms[k] for r in parts]) for k in TERMS},
        loss=torch.cat([r.loss for r in parts]),
        iterations=sum(r.iterations for r in parts),
        seconds=time.perf_counter() - start,
        init=settings.init,
    )


def optimize_joints(
    robot,
    targets: Targets,
    settings: JointOptimizeSettings | None = None,
    *,
    weights: LossWeights | None = None,
    q0: torch.Tensor | None = None,
    callback: Callable[[int, float], None] | None = None,
) -> OptimizeResult:
    """The joint-space baseline: Adam on the angles themselves, same objective.

    Limits by projection (``clamp``) or a soft penalty (``penalty``); see
    :class:`JointOptimizeSettings`. Returns an :class:`OptimizeResult` with ``z=None``.
    """
    settings = settings or JointOptimizeSettings()
    weights = weights or LossWeights()
    start = time.perf_counter()
    lo, hi = robot.lower_limits, robot.upper_limits
    dtype = lo.dtype
    targets = targets.to(dtype=dtype)
    T = len(targets)
    if q0 is None:
        starts = {"neutral": lambda: robot.neutral_q, "midpoint": lambda: (lo + hi) / 2, "zeros": lambda: torch.zeros_like(lo).clamp(lo, hi)}
        base = starts[settings.init]().to(dtype=lo.dtype, device=lo.device)
        q0 = base.expand(T, -1)
    elif q0.shape != (T, lo.shape[0]):
        raise SettingsError(f"q0 must be {(T, lo.shape[0])}, got {tuple(q0.shape)}")

    loss_fn = Objective(robot, targets, weights, settings.collision_form)
    smooth = _smoothness(robot, targets, weights)

    def evaluate(q):
        total, terms = loss_fn(q)
        if smooth is not None:
            total = total + smooth(q)
        if settings.limits == "penalty":
            violation = torch.relu(q - hi) + torch.relu(lo - q)
            total = total + settings.penalty * violation.pow(2).sum(-1)
        return total, q, terms

    def clamp(q):
        q.copy_(torch.maximum(torch.minimum(q, hi), lo))

    project = clamp if settings.limits == "clamp" else None
    _, q, loss, terms, history, steps = _descend(
        q0.to(dtype), evaluate, project, settings.iterations, settings.patience, settings.lr, callback,
        per_sample=smooth is None,
    )
    terms = dict(zip(TERMS, terms.unbind(1)))
    return OptimizeResult(q, None, history, terms, loss, steps, time.perf_counter() - start, f"joints-{settings.init}")

"""The one descent every optimiser runs: Adam, best point kept, patience stop.

Iterations: the loss is evaluated at the start point and after every Adam step;
``history[0]`` is the initial mean loss, ``history[i]`` the mean after ``i`` steps. At
most ``iterations`` steps; the loop stops early after ``patience`` evaluations in a row
without improving the best mean loss. The *best* point is kept per sample (each frame
keeps the parameters of its own lowest loss), so the result is never worse than the
start for any frame; when a sequence term couples the frames, the best point is the
iteration with the lowest mean instead (per-frame picks could stitch together frames
from different iterations).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import torch

from nlo_lab.objective import LossWeights, Targets, smoothness_loss
from nlo_lab.settings import check_choice

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["OptimizeResult", "Adam", "Rprop", "STEPPERS", "descend", "frozen", "smoothness_term", "join_results"]

STEPPERS = ("adam", "rprop")  # descend's step rules: the paper's Adam, or Rprop (class Rprop)


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
    z: torch.Tensor | None
    history: list[float]
    terms: dict[str, torch.Tensor]
    loss: torch.Tensor
    iterations: int
    seconds: float
    init: str = ""
    extra: dict = field(default_factory=dict)


def join_results(parts: list[OptimizeResult], init: str, seconds: float, frames_weighted: bool = False) -> OptimizeResult:
    """Results of consecutive frame ranges as one result.

    ``history`` is the mean over parts of each evaluation (a part that stopped early
    contributes its last value), weighted by the parts' frames when ``frames_weighted``;
    ``iterations`` the total steps, or with ``frames_weighted`` (parts optimised as
    batches, :func:`nlo_lab.pipeline.retarget`) the most steps any part took.
    """
    n = max(len(r.history) for r in parts)
    weight = [len(r.q) if frames_weighted else 1 for r in parts]
    total = sum(weight)
    history = [sum(r.history[min(i, len(r.history) - 1)] * w for r, w in zip(parts, weight, strict=True)) / total for i in range(n)]
    steps = [r.iterations for r in parts]
    return OptimizeResult(
        q=torch.cat([r.q for r in parts]),
        z=torch.cat([r.z for r in parts]),
        history=history,
        terms={k: torch.cat([r.terms[k] for r in parts]) for k in parts[0].terms},
        loss=torch.cat([r.loss for r in parts]),
        iterations=max(steps) if frames_weighted else sum(steps),
        seconds=seconds,
        init=init,
    )


@contextlib.contextmanager
def frozen(module: torch.nn.Module):
    """Turn off parameter gradients (and training mode) for the duration.

    Touches only what is on (the module tree is walked once: at batch 1 the walks and
    ``eval()``'s recursion were a third of a frame's fixed cost)."""
    thawed = [p for p in module.parameters() if p.requires_grad]
    was_training = module.training
    if was_training:
        module.eval()
    for p in thawed:
        p.requires_grad_(False)
    try:
        yield module
    finally:
        for p in thawed:
            p.requires_grad_(True)
        if was_training:
            module.train(True)


def smoothness_term(robot: Robot, targets: Targets, weights: LossWeights, anchor: torch.Tensor | None = None):
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


def _copy(a):
    """A detached copy of a tensor, an array, or a dict of them."""
    if isinstance(a, dict):
        return {k: _copy(v) for k, v in a.items()}
    return a.copy() if isinstance(a, np.ndarray) else a.detach().clone()


def _select(better, new, old):
    """Per sample ``new`` where ``better (B,)`` else ``old``; tensors or arrays ``(B, ...)``, or dicts of them."""
    if isinstance(new, dict):
        return {k: _select(better, new[k], old[k]) for k in old}
    where = np.where if isinstance(new, np.ndarray) else torch.where
    return where(better.reshape(-1, *([1] * (new.ndim - 1))), new, old)


class Adam:
    """Adam on one tensor (or numpy array), the same arithmetic as ``torch.optim.Adam``'s
    default (single-tensor) step, without the optimiser's per-step bookkeeping (a few
    hundred microseconds matter when one iteration at batch 1 is about a millisecond)."""

    def __init__(self, x: torch.Tensor | np.ndarray, lr: float, betas=(0.9, 0.999), eps: float = 1e-8):
        self.lr, self.betas, self.eps, self.step = lr, betas, eps, 0
        zeros = np.zeros_like if isinstance(x, np.ndarray) else torch.zeros_like
        self.m, self.v = zeros(x), zeros(x)

    @torch.no_grad()
    def update(self, x: torch.Tensor | np.ndarray, grad: torch.Tensor | np.ndarray) -> None:
        b1, b2 = self.betas
        self.step += 1
        bias1, bias2 = 1 - b1**self.step, 1 - b2**self.step
        if isinstance(x, np.ndarray):  # the same steps on arrays (the numpy descent)
            self.m += (1 - b1) * (grad - self.m)
            self.v *= b2
            self.v += (1 - b2) * grad * grad
            x += (-self.lr / bias1) * (self.m / (np.sqrt(self.v) / math.sqrt(bias2) + self.eps))
            return
        self.m.lerp_(grad, 1 - b1)
        self.v.mul_(b2).addcmul_(grad, grad, value=1 - b2)
        denom = (self.v.sqrt() / math.sqrt(bias2)).add_(self.eps)
        x.addcdiv_(self.m, denom, value=-self.lr / bias1)


class Rprop:
    """Resilient backpropagation (Riedmiller & Braun 1993, the iRprop- variant of Igel & Hüsken 2000) on one
    tensor or array: each coordinate moves by its own step against the sign of its gradient; the step grows by
    ``grow`` while the sign holds and shrinks by ``shrink`` where it flips (and that coordinate then waits one
    step), within ``[min_step, max_step]``; the first step is ``lr``.

    For a full-batch, deterministic loss (latent optimisation: every frame every step) the step adapts to each
    coordinate's own course: a latent that must travel far (an arm leaving a self-collision) speeds up
    geometrically where Adam's stays at ``lr``, and one that oscillates slows down. Only the gradient's sign is
    used, so the arithmetic is a handful of element-wise ops.
    """

    def __init__(self, x: torch.Tensor | np.ndarray, lr: float, grow: float = 1.2, shrink: float = 0.5,
                 min_step: float = 1e-6, max_step: float = 0.1):
        self.grow, self.shrink, self.min_step, self.max_step = grow, shrink, min_step, max_step
        if isinstance(x, np.ndarray):
            self.step_size, self.previous = np.full_like(x, lr), np.zeros_like(x)
        else:
            self.step_size, self.previous = torch.full_like(x, lr), torch.zeros_like(x)

    @torch.no_grad()
    def update(self, x: torch.Tensor | np.ndarray, grad: torch.Tensor | np.ndarray) -> None:
        agree = grad * self.previous  # > 0: the sign held, < 0: it flipped
        if isinstance(x, np.ndarray):  # the same steps on arrays (the numpy descent)
            step = np.where(agree > 0, np.minimum(self.step_size * self.grow, self.max_step),
                            np.where(agree < 0, np.maximum(self.step_size * self.shrink, self.min_step), self.step_size))
            grad = np.where(agree < 0, 0.0, grad)  # iRprop-: a coordinate whose sign flipped waits one step
            x -= step * np.sign(grad)
        else:
            step = torch.where(agree > 0, (self.step_size * self.grow).clamp_(max=self.max_step),
                               torch.where(agree < 0, (self.step_size * self.shrink).clamp_(min=self.min_step), self.step_size))
            grad = torch.where(agree < 0, 0.0, grad)
            x.sub_(step * grad.sign())
        self.step_size, self.previous = step, grad


def descend(
    params: torch.Tensor,
    evaluate: Callable[[torch.Tensor], tuple[torch.Tensor, torch.Tensor, torch.Tensor | dict]],
    project: Callable[[torch.Tensor], None] | None,
    iterations: int,
    patience: int,
    lr: float,
    callback,
    per_sample: bool = True,
    stepper: str = "adam",
):
    """Adam (or ``stepper="rprop"``: :class:`Rprop`, ``lr`` its first step) on ``params`` (B, ...) with per-sample
    best tracking and patience.

    ``params`` a tensor (autograd gives the gradient unless ``evaluate`` returns it), or a
    numpy array (``evaluate`` returns arrays and the gradient: a descent without torch,
    :mod:`nlo_lab.inference.numpy_descent`); the results are of the same kind.

    ``evaluate(x)`` returns ``loss (B,)``, ``q (B, n)`` and the terms (a ``(B, K)``
    tensor or a dict of ``(B,)``), all tracked at each sample's best point, and optionally
    a fourth item, the gradient of ``loss.sum()`` in ``x`` (else autograd computes it); with
    ``per_sample=False`` (samples coupled by a sequence term) at the best mean instead.
    ``project(x)`` runs in place after every step (the joint limits' clamp), or None.

    Returns:
        ``(best_x, best_q, best_loss, best_terms, history, steps)``.
    """
    x = params.copy() if isinstance(params, np.ndarray) else params.detach().clone().requires_grad_(True)
    check_choice("stepper", stepper, STEPPERS)
    adam = Adam(x, lr) if stepper == "adam" else Rprop(x, lr)
    best_loss = best_x = best_q = best_terms = None
    history: list[float] = []
    best_mean, stale, steps = float("inf"), 0, 0
    for it in range(iterations + 1):
        loss, q, terms, *grad = evaluate(x)  # loss (B,); grad: [dL/dx] when evaluate writes it out
        with torch.no_grad():
            mean = float(loss.mean())
            history.append(mean)
            if best_loss is None:
                best_loss, best_x, best_q, best_terms = _copy(loss), _copy(x), _copy(q), _copy(terms)
            elif per_sample:
                better = loss < best_loss  # (B,)
                if bool(better.all()):  # every sample improved (the rule while descending): plain copies
                    best_loss, best_x, best_q, best_terms = _copy(loss), _copy(x), _copy(q), _copy(terms)
                elif bool(better.any()):
                    best_loss, best_x, best_q, best_terms = (
                        _select(better, new, old) for new, old in ((loss, best_loss), (x, best_x), (q, best_q), (terms, best_terms))
                    )
            elif mean < best_mean:  # coupled samples: the whole point at the best mean (no per-sample select)
                best_loss, best_x, best_q, best_terms = _copy(loss), _copy(x), _copy(q), _copy(terms)  # q may be x
            if mean < best_mean:
                best_mean, stale = mean, 0
            else:
                stale += 1
        if callback is not None:
            callback(it, mean)
        if it == iterations or stale >= patience:
            break
        if not grad:
            grad = torch.autograd.grad(loss.sum(), x)
        adam.update(x, grad[0])
        steps += 1
        if project is not None:
            with torch.no_grad():
                project(x)
    return best_x, best_q, best_loss, best_terms, history, steps

"""Latent optimisation with a frozen decoder (paper Eq. 9/12).

``z* = argmin_z L(D, K(f_psi(z))) + ||z||²/σ²`` with Adam on ``z`` only; the decoder's
parameters are frozen (``requires_grad`` off for the duration). The whole sequence is
one batch: frames are independent (per-frame losses are summed, and Adam's update is per
coordinate), so one batched step advances every frame at once
(:func:`nlo_lab.inference.descend`).

The start (:func:`initial_latent`) is the encoder's latent of the demonstration (the
paper's neural initialisation, from :class:`nlo_lab.model.EncoderInput`, which the
objective's :class:`~nlo_lab.objective.Targets` do not carry), random, or zeros.

Temporal coherence. With ``weights.smooth > 0`` and a frame rate in the targets, the
objective also holds :func:`nlo_lab.objective.smoothness_loss` over consecutive frames, so
frames are no longer independent: the best point is then tracked for the whole sequence
(the iteration with the lowest mean), not per frame. And the start is warm along the
sequence (:func:`sequence_start`): each frame may start from its own encoder latent or
from one of its ``settings.warm_window`` neighbours' on either side, the choice over the
whole sequence minimising objective + smoothness by dynamic programming (Viterbi). The
encoder maps every frame on its own and, where two arm configurations fit about equally,
it can alternate between them from frame to frame; gradient steps do not cross from one
to the other, the start does.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.inference.descent import OptimizeResult, descend, frozen, join_results, smoothness_term
from nlo_lab.inference.fast_paths import FastPaths, fast_paths
from nlo_lab.inference.numpy_descent import NumpyLatentLoss, WrittenGradientLoss
from nlo_lab.inference.settings import OptimizeSettings
from nlo_lab.model import EncoderInput
from nlo_lab.objective import TERMS, LossWeights, Objective, Targets, step_cost

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.model import RetargetModel
    from nlo_lab.robot import Robot

__all__ = ["initial_latent", "sequence_start", "optimize_latent", "optimize_stream"]


def _model_dtype(model: torch.nn.Module) -> torch.dtype:
    return next(model.parameters()).dtype


def initial_latent(model: RetargetModel, inputs, settings: OptimizeSettings) -> torch.Tensor:
    """The start latent ``z0 (T, N_r, k)`` for ``settings.init``.

    Args:
        model: a :class:`nlo_lab.model.RetargetModel`.
        inputs: the encoder's :class:`~nlo_lab.model.EncoderInput` of the T frames
            (:func:`nlo_lab.model.encoder_input`); the other inits need only the number
            of frames, so anything with a length (e.g. the :class:`Targets`) will do.
        settings: :class:`OptimizeSettings` (``init``, ``seed``, ``latent_sigma``).

    Raises:
        SettingsError: ``"encoder"`` without an :class:`~nlo_lab.model.EncoderInput`.
    """
    shape = (len(inputs), *model.latent_shape)
    param = next(model.parameters())
    dtype, device = param.dtype, param.device
    if settings.init == "zeros":
        return torch.zeros(shape, dtype=dtype, device=device)
    if settings.init == "encoder":
        if not getattr(model, "has_encoder", True):
            raise SettingsError("init 'encoder': this model was trained as an auto-decoder and has no trained encoder; "
                                "start from 'train-stats', 'random' or 'zeros'")
        if not isinstance(inputs, EncoderInput):
            raise SettingsError("init 'encoder' needs the encoder's input: pass encoder_input=nlo_lab.model.encoder_input(demo)")
        x = inputs.to(device=device, dtype=dtype)
        with torch.no_grad(), frozen(model):
            return model.encode(x.node_features, x.edge_features).detach()
    gen = torch.Generator().manual_seed(settings.seed)
    noise = torch.randn(shape, generator=gen, dtype=torch.float64).to(device=device, dtype=dtype)
    if settings.init == "random":
        return noise * settings.latent_sigma
    return model.latent_mean.to(dtype) + model.latent_std.to(dtype) * noise  # "train-stats"


@torch.no_grad()
def sequence_start(model: RetargetModel, robot: Robot, targets: Targets, z0: torch.Tensor, weights: LossWeights | None = None,
                   window: int = 2, collision_form: str = "hinge", anchor: torch.Tensor | None = None,
                   fast: bool | FastPaths = False, objective: Objective | None = None) -> torch.Tensor:
    """Warm start along the sequence: per frame, its own start latent or a neighbour's.

    Frame t's candidates are ``z0[t - window .. t + window]``. Each candidate costs its
    objective at frame t (plus the latent term); consecutive choices cost the
    smoothness term between their decoded angles (frame 0 also its step from the fixed
    ``anchor (n,)`` when given). The cheapest sequence of choices
    is found exactly by dynamic programming (Viterbi), ``O(T (2 window + 1)²)``.
    ``fast``: the decoder's and the objective's forms (:func:`~nlo_lab.inference.fast_paths.fast_paths`).
    ``objective``: the :class:`Objective` of ``targets``, ``weights``, ``collision_form`` and ``fast``'s options,
    when the caller has it (:func:`optimize_latent`; building one takes a millisecond or two), else built here.

    Returns:
        ``(T, N_r, k)`` start latents (``z0`` itself when smoothing does not apply).
    """
    weights = weights or LossWeights()
    smooth = smoothness_term(robot, targets, weights, anchor)
    T = len(targets)
    if smooth is None or window == 0:
        return z0
    dtype = robot.lower_limits.dtype
    targets = targets.to(dtype=dtype)
    paths = fast_paths(fast, T, targets.shoulder.device)
    loss_fn = objective or Objective(robot, targets, weights, collision_form, **paths.objective_options())
    K = 2 * window + 1
    idx = (torch.arange(T)[:, None] + torch.arange(-window, window + 1)[None]).clamp(0, T - 1)  # (T, K)
    unary, angles = [], []
    with frozen(model):
        if loss_fn.numpy_terms is not None:  # the numpy terms: each start latent decoded and mapped once
            unary, angles = _candidate_costs(model, loss_fn, z0, idx, weights.latent, paths.decoder, paths.analytic_fk)
        for k in range(len(angles), K):  # the readable form: every candidate decoded and its objective taken
            z = z0[idx[:, k]]
            q = model.decode(z, paths.decoder).to(dtype)
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


def _candidate_costs(model: RetargetModel, loss_fn: Objective, z0: torch.Tensor, idx: torch.Tensor, latent_weight: float,
                     decoder_form: str, analytic_fk: bool) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
    """:func:`sequence_start`'s unary costs ``[(T,)] * K`` and angles ``[(T, n)] * K`` with the objective's numpy
    terms (a faster form of its loop, the same numbers).

    Candidate k of frame t is the start latent of frame ``idx[t, k]``: its angles, its points, its collision term
    (the robot's own, no target in it) and its latent term do not depend on t. So each of the T start latents is
    decoded and mapped once, the collision term measured once, and per k only the terms that compare with frame
    t's targets are taken on the gathered points. Measured (2026-11-26, YuMi, the 4 recordings of
    ``benchmarks/hands.py``, CPU): 16 -> 5 ms per recording.
    """
    terms_of = loss_fn.numpy_terms
    assert terms_of is not None
    q = model.decode(z0, decoder_form).to(loss_fn.weights.dtype)  # (T, n)
    points = loss_fn.plan.map(q, analytic_fk).numpy()  # (T, k, 3)
    latent = latent_weight * z0.pow(2).flatten(1).sum(1).to(q.dtype)  # (T,)
    column = TERMS.index("collision")
    collision = terms_of.forward(points)[0][:, column]  # (T,): each start latent's
    unary, angles = [], []
    for k in range(idx.shape[1]):
        at = idx[:, k]
        terms, _ = terms_of.forward(points[at.numpy()], pairs=False)
        terms[:, column] = collision[at.numpy()]
        unary.append(torch.from_numpy(terms) @ loss_fn.weights + latent[at])
        angles.append(q[at])
    return unary, angles


def optimize_latent(
    model: RetargetModel,
    robot: Robot,
    targets: Targets,
    settings: OptimizeSettings | None = None,
    *,
    weights: LossWeights | None = None,
    z0: torch.Tensor | None = None,
    callback: Callable[[int, float], None] | None = None,
    anchor: torch.Tensor | None = None,
    encoder_input: EncoderInput | None = None,
    fast: bool | FastPaths = False,
) -> OptimizeResult:
    """Optimise the latent of every frame of ``targets`` at once, decoder frozen.

    Args:
        model: a :class:`nlo_lab.model.RetargetModel` for ``robot``.
        robot: the robot (FK, capsules).
        targets: :class:`Targets` of T frames (what the objective compares).
        settings: :class:`OptimizeSettings`.
        weights: :class:`LossWeights`; ``weights.latent`` scales ``||z||²``.
        z0: ``(T, N_r, k)`` start latents; overrides ``settings.init`` (warm start).
        callback: called as ``callback(iteration, mean_loss)`` after every evaluation.
        anchor: ``(n,)`` fixed joint angles of the frame just before ``targets`` (the
            previous chunk's last frame, :func:`nlo_lab.pipeline.retarget`): with the
            smoothness term on, frame 0's step from it is part of the objective and of
            the warm start, so a sequence optimised in chunks has no seam.
        encoder_input: the encoder's input of the same T frames; needed for
            ``init="encoder"`` without ``z0``.
        fast: which evaluations run: False (the default) the readable forms (the paper's
            decoder, the term functions, autograd through FK), True the fastest for T frames
            (:meth:`FastPaths.for_frames`), or a :class:`FastPaths`. Same numbers either way.

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
        z0 = initial_latent(model, targets if encoder_input is None else encoder_input, settings)
    elif z0.shape != (len(targets), *model.latent_shape):
        raise SettingsError(f"z0 must be {(len(targets), *model.latent_shape)}, got {tuple(z0.shape)}")

    paths = fast_paths(fast, len(targets), targets.shoulder.device)
    loss_fn = Objective(robot, targets, weights, settings.collision_form, **paths.objective_options())
    if anchor is not None and anchor.shape != robot.lower_limits.shape:
        raise SettingsError(f"anchor must be {tuple(robot.lower_limits.shape)}, got {tuple(anchor.shape)}")
    smooth = smoothness_term(robot, targets, weights, anchor)
    if smooth is not None and settings.warm_start:
        z0 = sequence_start(model, robot, targets, z0, weights, settings.warm_window, settings.collision_form, anchor, paths,
                            objective=loss_fn)

    def evaluate(z):
        q = model.decode(z, paths.decoder).to(dtype)
        total, terms = loss_fn(q)
        if smooth is not None:
            total = total + smooth(q)
        # + weights.latent * latent_loss(z), in one op
        return torch.add(total, z.pow(2).flatten(1).sum(1).to(dtype), alpha=weights.latent), q, terms

    with frozen(model):
        stepper, lr, patience = settings.step_rule(coupled=smooth is not None)
        start_z = z0.to(_model_dtype(model))
        numpy_loss = NumpyLatentLoss.build(model, robot, loss_fn, weights.latent) if paths.numpy_iteration and smooth is None else None
        written = None
        if numpy_loss is None and paths.written_gradient and start_z.device.type == "cpu":
            written = WrittenGradientLoss.build(model, robot, loss_fn, weights.latent, targets, weights.smooth, anchor, paths.decoder)
        if numpy_loss is not None:  # the same descent on arrays, loss and gradient written out
            evaluate, start_z = numpy_loss, start_z.detach().cpu().numpy()
        elif written is not None:  # the same loss and gradient, FK and the terms without an autograd graph
            evaluate = written
        found = descend(start_z, evaluate, None, settings.iterations, patience, lr, callback, per_sample=smooth is None,
                        stepper=stepper)
    z, q, loss, terms, history, steps = (torch.from_numpy(a) if isinstance(a, np.ndarray) else a for a in found)
    return OptimizeResult(q, z, history, dict(zip(TERMS, terms.unbind(1), strict=True)), loss, steps, time.perf_counter() - start, init)


def optimize_stream(model: RetargetModel, robot: Robot, targets: Targets, settings: OptimizeSettings | None = None, *, weights: LossWeights | None = None,
                    z0: torch.Tensor | None = None, callback: Callable[[int, float], None] | None = None,
                    encoder_input: EncoderInput | None = None, fast: bool | FastPaths = False) -> OptimizeResult:
    """Frame by frame, as a live stream: with ``settings.warm_start`` frame t starts
    from frame t-1's best latent (frame 0 from ``z0`` or ``settings.init``).

    Arguments as :func:`optimize_latent`; ``callback`` is called as
    ``callback(frame, last_mean_loss)`` after every frame. ``history`` is the mean over
    frames of each evaluation (a frame that stopped early contributes its last value);
    ``iterations`` the total steps.
    """
    settings = settings or OptimizeSettings()
    start = time.perf_counter()
    inits = initial_latent(model, targets if encoder_input is None else encoder_input, settings) if z0 is None else z0
    prev = None
    parts: list[OptimizeResult] = []
    for t in range(len(targets)):
        start_z = prev if (settings.warm_start and prev is not None) else inits[t : t + 1]
        parts.append(optimize_latent(model, robot, targets.index(slice(t, t + 1)), settings, weights=weights, z0=start_z, fast=fast))
        prev = parts[-1].z
        if callback is not None:
            callback(t, parts[-1].history[-1])
    return join_results(parts, settings.init, time.perf_counter() - start)

"""One latent-optimisation iteration in numpy, loss and gradient written out: a faster
evaluation for a few frames (the live panel re-optimises one frame per slider move).

At batch 1 an iteration of :func:`nlo_lab.inference.optimize_latent` is some 150 torch
operations and an autograd graph, each costing microseconds of dispatch, far more than its
arithmetic. :class:`NumpyLatentLoss` evaluates the same latent loss

``L(z) = sum_i w_i L_i(D, K(f_psi(z))) + w_lat ||z||²``

and its gradient in ``z`` with the numpy forms the pieces already have, chained by hand:
the frozen decoder (:class:`~nlo_lab.model.numpy_backend.DecoderPlan`), FK's mapped points
(:class:`~nlo_lab.robot.point_gradient.NumpyPointMap`) and the terms
(:class:`~nlo_lab.objective.numpy_backend.PointTerms`, the hand terms included), each forward
then each backward in reverse order. The tests hold it equal to the readable torch path
(values and gradients) and the optimisation's result equal either way.

A recording's frames (a batch, coupled by the smoothness term) take :class:`WrittenGradientLoss`:
the same chain where the numpy decoder does not pay (its stacked small matmuls do not batch):
the decoder in torch (the node-major form with its gradient written out,
:class:`~nlo_lab.model.written_gradient.WrittenDecoder`; else its own small autograd graph), FK's points
and their closed-form gradient (:meth:`~nlo_lab.robot.point_gradient.MapPoints.points`, ``gradient``,
summed over the points the terms reach, :meth:`~nlo_lab.objective.numpy_backend.PointTerms.reached`), the
terms and the smoothness term (:class:`~nlo_lab.objective.numpy_backend.SmoothTerm`) in numpy, without an
autograd graph. Measured (2026-11-26, YuMi, the 4 recordings of ``benchmarks/hands.py``, one call at 170 /
47 frames, CPU): the decoder's forward and backward 1110 -> 990 / 457 -> 363 us written out; the points
with a gradient 25-71 of 174.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch

from nlo_lab.objective import Objective, Targets
from nlo_lab.objective.numpy_backend import SmoothTerm
from nlo_lab.robot.point_gradient import MapPoints, NumpyPointMap

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.model import RetargetModel
    from nlo_lab.robot import Robot

__all__ = ["NumpyLatentLoss", "WrittenGradientLoss"]


class NumpyLatentLoss:
    """``z (B, N_r, k)`` -> the latent loss ``(B,)``, the angles, the unweighted terms and ``dL/dz``, in numpy.

    Build it with :meth:`build`, which declines (None) where a piece has no numpy form.
    """

    def __init__(self, decoder_plan, point_map: NumpyPointMap, objective: Objective, latent_weight: float):
        self.decoder, self.points, self.terms = decoder_plan, point_map, objective.numpy_terms
        self.weights = objective.weights.numpy()  # (len(TERMS),) in the targets' dtype
        self.latent_weight = float(latent_weight)
        self.dtype = self.points.dtype
        self._g_terms: dict[int, np.ndarray] = {}  # batch -> d sum(loss) / d terms: each row the weights

    @classmethod
    def build(cls, model: RetargetModel, robot: Robot, objective: Objective, latent_weight: float) -> NumpyLatentLoss | None:
        """The numpy loss of ``model``'s frozen decoder and ``objective`` (built with ``fused=True``), or None
        when the decoder has no numpy form (weights not frozen, off the CPU, another kind) or the
        objective has terms its numpy form does not compute."""
        plan = getattr(model.decoder, "numpy_plan", lambda: None)()
        if plan is None or objective.numpy_terms is None or len(objective.weights) != objective.numpy_terms.n_terms:
            return None
        dtype = objective.weights.numpy().dtype
        key = ("numpy_point_map", np.dtype(dtype).str)
        point_map = objective.plan.__dict__.get(key)
        if point_map is None:  # one per point plan (robot and dtype), built on first use
            point_map = objective.plan.__dict__[key] = NumpyPointMap(robot.tree, objective.plan.body.numpy(), objective.plan.vectors.numpy(), dtype)
        return cls(plan, point_map, objective, latent_weight)

    def __call__(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``loss (B,)``, ``q (B, n)``, ``terms (B, len(TERMS))`` (unweighted) and ``dL/dz`` (``z``'s shape)."""
        q, decoder_state = self.decoder.forward(z)
        q = q.astype(self.dtype, copy=False)
        points, point_state = self.points.forward(q)
        terms, term_state = self.terms.forward(points)
        latent = (z * z).reshape(z.shape[0], -1).sum(1)
        loss = terms @ self.weights + (self.latent_weight * latent).astype(self.dtype, copy=False)
        g_terms = self._g_terms.get(len(terms))
        if g_terms is None:  # backward of sum(loss): each term's gradient is its weight
            g_terms = self._g_terms[len(terms)] = np.tile(self.weights, (len(terms), 1)).astype(terms.dtype)
        g_points = self.terms.backward(g_terms, term_state)
        g_q = self.points.backward(g_points, point_state)
        g_z = self.decoder.backward(g_q, decoder_state) + (2.0 * self.latent_weight) * z
        return loss, q, terms, g_z.astype(z.dtype, copy=False)


class WrittenGradientLoss:
    """``z (B, N_r, k)`` tensor -> the latent loss ``(B,)`` (+ the smoothness term), the angles, the unweighted
    terms and ``dL/dz``, as :func:`~nlo_lab.inference.optimize_latent`'s torch evaluation computes them.

    Build it with :meth:`build`, which declines (None) where the objective has no numpy terms.
    """

    def __init__(self, model: RetargetModel, robot: Robot, objective: Objective, latent_weight: float, smooth: SmoothTerm | None,
                 decoder_form: str):
        self.model, self.robot, self.objective, self.smooth, self.form = model, robot, objective, smooth, decoder_form
        # the node-major decoder with its gradient written out (frozen weights, LeakyReLU), else autograd through it
        written = getattr(model.decoder, "written", None) if decoder_form == "node-major" else None
        self.decoder = written() if written is not None else None
        self.latent_weight = float(latent_weight)
        self.weights = objective.weights.numpy()
        self.dtype = robot.lower_limits.dtype
        self._g_terms: dict[int, np.ndarray] = {}
        # Every frame's capsule pairs searched every call (NearPairs' slack 0): Rprop's steps move most frames'
        # capsules farther than the slack between calls, and checking the kept candidates cost more than the search
        # saved (2026-11-26, YuMi, the 164 calls of the 4 recordings of benchmarks/hands.py: 69 against 92 ms).
        # Its own copy of the terms: the objective the caller holds keeps its slack.
        self.terms = objective.numpy_terms.with_near_slack(0.0) if objective.numpy_terms is not None else None

    @classmethod
    def build(cls, model: RetargetModel, robot: Robot, objective: Objective, latent_weight: float, targets: Targets,
              smooth_weight: float, anchor: torch.Tensor | None, decoder_form: str) -> WrittenGradientLoss | None:
        """The loss of ``objective`` (built with ``fused=True``, on the CPU) and, where it applies
        (:func:`~nlo_lab.inference.smoothness_term`'s rule), the smoothness term; None without numpy terms."""
        if objective.numpy_terms is None or len(objective.weights) != objective.numpy_terms.n_terms:
            return None
        coupled = smooth_weight != 0 and targets.fps is not None and len(targets) + (anchor is not None) >= 2
        smooth = SmoothTerm(float(targets.fps), robot.velocity_limits, smooth_weight, anchor, robot.lower_limits.dtype) if coupled else None
        return cls(model, robot, objective, latent_weight, smooth, decoder_form)

    def __call__(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """``loss (B,)``, ``q (B, n)``, ``terms (B, len(TERMS))`` (unweighted) and ``dL/dz`` (``z``'s shape)."""
        plan = self.objective.plan
        tree = self.robot.tree
        if self.decoder is not None:  # no graph: the decoder's gradient written out too
            q_own, decoder_state = self.decoder.forward(z.detach())
            q = q_own.to(self.dtype)
        else:
            z_leaf = z.detach().requires_grad_(True)
            with torch.enable_grad():
                q_graph = self.model.decode(z_leaf, self.form).to(self.dtype)  # the decoder's own graph, for its backward
            q = q_graph.detach()
        poses, points = MapPoints.points(q, tree, plan.body, plan.vectors)
        terms, term_state = self.terms.forward(points.numpy())
        z_np = z.detach().numpy()
        latent = (z_np * z_np).reshape(len(z_np), -1).sum(1)
        loss = terms @ self.weights + (self.latent_weight * latent).astype(terms.dtype, copy=False)
        if self.smooth is not None:
            smooth, smooth_state = self.smooth.forward(q.numpy())
            loss = loss + smooth
        g_terms = self._g_terms.get(len(terms))
        if g_terms is None:  # backward of sum(loss): each term's gradient is its weight
            g_terms = self._g_terms[len(terms)] = np.tile(self.weights, (len(terms), 1)).astype(terms.dtype)
        g_points = torch.from_numpy(self.terms.backward(g_terms, term_state))
        columns = torch.from_numpy(self.terms.reached(term_state))  # the points with a gradient
        g_q = MapPoints.gradient(g_points, poses, points, tree, plan.body, plan.vectors, columns)
        if self.smooth is not None:
            g_q = g_q + torch.from_numpy(self.smooth.backward(np.ones(len(q), dtype=terms.dtype), smooth_state))
        if self.decoder is not None:
            g_z = self.decoder.backward(g_q.to(q_own.dtype).reshape(q_own.shape), decoder_state)
        else:
            (g_z,) = torch.autograd.grad(q_graph, z_leaf, g_q.reshape(q_graph.shape))
        g_z = g_z + (2.0 * self.latent_weight) * z.detach()
        return torch.from_numpy(np.ascontiguousarray(loss)), q, torch.from_numpy(terms), g_z

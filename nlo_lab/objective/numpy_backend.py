"""The objective's terms in numpy, with a written-out backward: a faster evaluation for small batches.

:class:`nlo_lab.objective.Objective` turns the robot's mapped points into the five
unweighted terms (:mod:`nlo_lab.objective.terms`) with some forty tensor ops. At batch 1 (the live panel, a
slider move re-optimises one frame) each torch op costs several microseconds of
dispatch and as much again in autograd's backward, far more than its
arithmetic. This module does the same arithmetic in numpy inside one
``torch.autograd.Function`` whose backward is written out:

* rows ``v = R p`` (ee, ori columns, elbow, finger rows: fixed combinations of
  the points ``p``); finger rows are normalised, ``u = v / |v|``;
* ``sq = mask * |v - v̂|²`` summed per term: ``d sq / d v = 2 (v - v̂)``, and
  through the normalisation ``d / d v = (I - u uᵀ) / |v| · d / d u``;
* capsule distances ``d = dist(ends) - r`` with the envelope-theorem gradient of
  :mod:`nlo_lab.robot.collision`, through the hinge ``((m - d)/m)²`` or the paper's
  ``exp(-d²)`` below ``m``;
* the gradient reaches the points as ``Rᵀ g_v + S g_ends`` (``S`` scatters the
  capsule end points back onto the points).

Every term is linear in the points up to the finger normalisation and the
squares, so the point plan becomes a few constant matrices (:meth:`PointTerms.build`).
``Objective(fused=True)`` takes this path (the pipeline asks for it on the CPU for few
frames, :class:`nlo_lab.inference.FastPaths`). The tests compare both, values and
gradients, on every robot.
First derivatives only (no double backward).
"""

from __future__ import annotations

import numpy as np
import torch
from torch.autograd.function import once_differentiable

from nlo_lab.objective.points import PointPlan
from nlo_lab.objective.targets import Targets
from nlo_lab.objective.terms import UNIT_EPS, unit
from nlo_lab.robot.collision import segment_closest_points

__all__ = ["PointTerms", "point_terms"]


class PointTerms:
    """Constant numpy arrays of one objective (robot plan, goals, masks).

    Args:
        rows: ``(V, K)`` residual rows as combinations of the K points.
        finger_row: ``(V,)`` bool, rows normalised to unit length.
        row_term: ``(V,)`` int, the term (0..3) each row belongs to.
        goal: ``(T, V, 3)`` human side of every row.
        mask: ``(T, V)`` bool, rows observed.
        pair_points: ``(4P,)`` point index of the ends a0, a1, b0, b1 of each pair.
        pair_radii: ``(P,)`` summed capsule radii [m].
        margins: ``(P,)`` d_min per pair [m].
        form: ``"hinge"`` or ``"paper"`` (see :func:`nlo_lab.objective.terms.collision_loss`).
    """

    n_terms = 5  # the paper's five: ee, ori, elbow, finger, collision

    def __init__(self, rows, finger_row, row_term, goal, mask, pair_points, pair_radii, margins, form: str):
        self.rows = np.ascontiguousarray(rows)
        self.rows_t = np.ascontiguousarray(self.rows.T)
        self.fingers = np.flatnonzero(finger_row)
        self.term_of_row = np.eye(4, dtype=self.rows.dtype)[np.asarray(row_term, dtype=np.int64)]  # (V, 4)
        self.goal = np.ascontiguousarray(goal)
        self.mask = np.asarray(mask, dtype=bool)[..., None]  # (T, V, 1)
        self.pair_points = np.asarray(pair_points, dtype=np.int64)
        self.radii = np.asarray(pair_radii, dtype=np.float64)
        self.margins = np.asarray(margins, dtype=np.float64)
        self.form = form
        K, n_ends = self.rows.shape[1], self.pair_points.shape[0]
        scatter = np.zeros((K, n_ends))  # (K, 4P): sums the end-point gradients onto the points
        scatter[self.pair_points, np.arange(n_ends)] = 1.0
        self.scatter = scatter.astype(self.rows.dtype)

    @classmethod
    def build(cls, plan: PointPlan, targets: Targets, form: str) -> PointTerms:
        """The terms of :mod:`nlo_lab.objective.terms` as rows over ``plan``'s points, for ``targets``.

        Residual rows (each a fixed combination of points, minus the human side):
        ee ``(w - s)/l`` (2), ori the columns of ``R_wrist R_align`` (6), elbow
        ``(w - e)/l_fore`` (2), finger ``tip - base`` (K, normalised).
        """
        t, K = targets, plan.vectors.shape[0]
        rows, goals, masks, term, finger = [], [], [], [], []

        def row(entries, term_index: int, is_finger: bool = False) -> None:
            r = np.zeros(K)
            for k, v in entries:
                r[k] += v
            rows.append(r)
            term.append(term_index)
            finger.append(is_finger)

        at = {name: range(*rows_.indices(K)) for name, rows_ in plan.rows.items()}
        l_arm, l_fore = plan.arm_length.tolist(), plan.fore_length.tolist()
        for s in range(2):
            row([(at["wrist"][s], 1.0 / l_arm[s]), (at["shoulder"][s], -1.0 / l_arm[s])], 0)
        for k in at["wrist_axes"]:  # side-major: the three columns of each side
            row([(k, 1.0)], 1)
        for s in range(2):
            row([(at["wrist"][s], 1.0 / l_fore[s]), (at["elbow"][s], -1.0 / l_fore[s])], 2)
        for base, tip in zip(at["finger_base"], at["finger_tip"], strict=True):
            row([(tip, 1.0), (base, -1.0)], 3, is_finger=True)
        am = t.arm_mask
        with torch.no_grad():
            goals = [
                (t.wrist - t.shoulder) / t.arm_length[..., None],  # (T, 2, 3)
                t.wrist_rotation.mT.reshape(-1, 6, 3),  # (T, 6, 3): columns of R̂, side-major
                (t.wrist - t.elbow) / t.fore_length[..., None],
            ]
            masks = [am[..., 0] & am[..., 2], t.wrist_mask.repeat_interleave(3, dim=1), am[..., 1] & am[..., 2]]
            if len(plan.finger_side):
                sel = (slice(None), plan.finger_side, plan.finger_index)
                goals.append(unit(t.finger_tip[sel] - t.finger_base[sel]))  # (T, K_f, 3)
                masks.append(t.finger_mask[sel])
            goal, mask = torch.cat(goals, 1), torch.cat(masks, 1)
        return cls(
            torch.as_tensor(np.array(rows), dtype=plan.vectors.dtype).numpy(), np.array(finger), np.array(term),
            goal.cpu().numpy(), mask.cpu().numpy(), plan.pair_points.cpu().numpy(), plan.pair_radii.cpu().numpy(),
            plan.margins.cpu().numpy(), form,
        )

    def forward(self, P: np.ndarray):
        """Terms ``(B, 5)`` and what the backward needs, for points ``P (B, K, 3)`` (B = T)."""
        goal, mask = self.goal, self.mask
        v = np.matmul(self.rows, P)  # (B, V, 3)
        f = self.fingers
        norm = unit = None
        if f.size:
            vf = v[:, f]
            norm = np.sqrt((vf * vf).sum(-1, keepdims=True) + UNIT_EPS)  # (B, F, 1)
            unit = vf / norm
            v[:, f] = unit
        r = np.where(mask, v - goal, 0.0).astype(P.dtype, copy=False)  # (B, V, 3), 0 where masked
        terms = np.empty((P.shape[0], 5), dtype=P.dtype)
        terms[:, :4] = (r * r).sum(-1) @ self.term_of_row
        B, n_pairs = P.shape[0], self.radii.shape[0]
        coll = None
        if n_pairs:
            E = P[:, self.pair_points].reshape(B * n_pairs, 4, 3).transpose(1, 2, 0).astype(np.float64)  # (4, 3, B*P)
            _, _, w, dist, u = segment_closest_points(E)
            d = dist.reshape(B, n_pairs) - self.radii  # (B, P) surface distance [m]
            if self.form == "paper":
                near = d < self.margins
                e = np.where(near, np.exp(-d * d), 0.0)
                terms[:, 4] = e.sum(-1)
                slope = -2.0 * d * e  # d term / d d
            else:
                h = np.clip((self.margins - d) / self.margins, 0.0, None)
                terms[:, 4] = (h * h).sum(-1)
                slope = -2.0 * h / self.margins
            coll = (slope, w.reshape(B, n_pairs, 4), u.reshape(B, n_pairs, 3))
        else:
            terms[:, 4] = 0.0
        return terms, (r, unit, norm, coll)

    def backward(self, g: np.ndarray, saved) -> np.ndarray:
        """Gradient ``(B, K, 3)`` of ``sum(g * terms)`` with respect to the points."""
        r, unit, norm, coll = saved
        gv = 2.0 * r * (g[:, :4] @ self.term_of_row.T)[..., None]  # (B, V, 3)
        f = self.fingers
        if f.size:
            gu = gv[:, f]
            gv[:, f] = (gu - unit * (unit * gu).sum(-1, keepdims=True)) / norm
        gP = np.matmul(self.rows_t, gv)  # (B, K, 3)
        if coll is not None:
            slope, w, u = coll
            gd = g[:, 4:5] * slope  # (B, P)
            g_ends = (gd[..., None] * w)[..., None] * u[:, :, None, :]  # (B, P, 4, 3)
            gP += np.matmul(self.scatter, g_ends.reshape(g.shape[0], -1, 3).astype(gP.dtype))
        return gP


class _PointTermsFn(torch.autograd.Function):
    @staticmethod
    def forward(ctx, points: torch.Tensor, plan: PointTerms):
        terms, saved = plan.forward(points.detach().numpy())
        ctx.plan, ctx.saved = plan, saved
        return torch.from_numpy(terms)

    @staticmethod
    @once_differentiable  # a second derivative raises instead of coming out wrong
    def backward(ctx, grad: torch.Tensor):
        g = grad.detach().numpy().astype(ctx.saved[0].dtype, copy=False)
        return torch.from_numpy(ctx.plan.backward(g, ctx.saved)), None


def point_terms(points: torch.Tensor, plan: PointTerms) -> torch.Tensor:
    """The unweighted terms ``(T, 5)`` (ee, ori, elbow, finger, collision) of CPU points ``(T, K, 3)``.

    Args:
        points: the robot's mapped points (``KinematicTree.map_points``), on the CPU.
        plan: the objective's :class:`PointTerms` (built for the same T frames).
    """
    return _PointTermsFn.apply(points, plan)

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
  ``exp(-d²)`` below ``m``, measured exactly only for the pairs a lower bound cannot clear
  of their margin (the others add exactly 0, as in :mod:`~nlo_lab.objective.near_pairs`);
* the gradient reaches the points as ``Rᵀ g_v``, plus the near pairs' end-point gradients
  added onto their points.

Every term is linear in the points up to the finger normalisation and the
squares, so the point plan becomes a few constant matrices (:meth:`PointTerms.build`).
``Objective(fused=True)`` takes this path (the pipeline asks for it on the CPU for few
frames, :class:`nlo_lab.inference.FastPaths`). The tests compare both, values and
gradients, on every robot.
First derivatives only (no double backward).
"""

from __future__ import annotations

import copy

import numpy as np
import torch
from torch.autograd.function import once_differentiable

from nlo_lab.objective.near_pairs import CULL_SLACK
from nlo_lab.objective.points import PointPlan
from nlo_lab.objective.targets import Targets
from nlo_lab.objective.terms import CHORD_EPS, UNIT_EPS, in_wrist_frame, pinch_activation, smoothness_scale, unit
from nlo_lab.objective.weights import CONTACT_SCALE, SMOOTH_MAX_STEP, SMOOTH_STEP_WIDTH, TERMS
from nlo_lab.robot.collision import segment_closest_points

__all__ = ["PointTerms", "HandTerms", "NearPairs", "NEAR_SLACK", "SmoothTerm", "point_terms", "maybe_near"]



def maybe_near(capsules: np.ndarray, pairs: np.ndarray, clearance: np.ndarray) -> np.ndarray:
    """Flat indices ``frame * P + pair`` (ascending) of the pairs whose segments may be closer than ``clearance``.

    A separating-axis lower bound of the distance of segments a, b: their extents along the
    line through their midpoints, ``|m_b - m_a| - (|(a1 - a0)·n| + |(b1 - b0)·n|)/2``
    (``n`` its direction), tighter than the spheres around them where long capsules lie side
    by side. A pair left out is at least ``clearance`` apart.

    The bound is taken only where the spheres around the segments may be that close,
    ``|m_b - m_a| - (l_a + l_b)/2 < clearance`` (``l``: the longest the segment is in any frame;
    by Cauchy-Schwarz each extent is at most ``l/2``, so the sphere bound is below the
    separating-axis bound): on the latent optimisation's points a tenth of the frame-pairs (from
    ``SMALL_BATCH`` frames; for fewer the bound on every pair: YuMi, 1 frame, 52 -> 28 us). Measured
    (2026-11-26, the 4 recordings of ``benchmarks/hands.py``, YuMi's 873 pairs, the 164 calls of one
    ``retarget`` each): 103 -> 53 ms, the same pairs.

    Args:
        capsules: ``(B, C, 2, 3)`` the capsules' axis end points [m].
        pairs: ``(P, 2)`` capsule indices; clearance: ``(P,)`` [m].
    """
    return _near_coordinates_first(np.ascontiguousarray(capsules.transpose(3, 1, 2, 0)), pairs, clearance)


def _near_coordinates_first(c: np.ndarray, pairs: np.ndarray, clearance: np.ndarray) -> np.ndarray:
    """:func:`maybe_near` of the capsules' end points given coordinates first, ``c (3, C, 2, B)`` (contiguous)."""
    # Coordinates first: every product below is on contiguous (P, B) planes (an einsum over a last
    # axis of 3 ran 3-4x slower at 170 frames), and np.take along axis 1 copies whole rows (fancy
    # indexing x[:, idx] ran 5x slower).
    B, n_pairs = c.shape[-1], len(pairs)
    twice_mid, axis = c[:, :, 0] + c[:, :, 1], c[:, :, 1] - c[:, :, 0]  # (3, C, B)
    a, b = pairs[:, 0], pairs[:, 1]
    gap = np.take(twice_mid, b, axis=1)
    gap -= np.take(twice_mid, a, axis=1)  # (3, P, B): G = 2 (m_b - m_a)
    if B < SMALL_BATCH:  # a few frames: the bound on every pair (the spheres' test costs more calls than it saves)
        twice_clearance = (2.0 * clearance).astype(c.dtype)[:, None]
        return np.flatnonzero(_bound_below(gap, np.take(axis, a, axis=1), np.take(axis, b, axis=1), twice_clearance).T)
    length2 = gap[0] * gap[0]
    length2 += gap[1] * gap[1]
    length2 += gap[2] * gap[2]  # |G|²
    longest = np.sqrt((axis * axis).sum(0)).max(1)  # (C,)
    reach = (longest[a] + longest[b] + 2.0 * clearance).astype(c.dtype)  # (P,): spheres apart <=> |G| > reach
    maybe = np.flatnonzero(length2 <= (reach * reach)[:, None])  # pair-major: pair * B + frame
    pair, frame = np.divmod(maybe, B)
    axis = axis.reshape(3, -1)
    twice_clearance = (2.0 * clearance).astype(c.dtype)[pair]  # in the points' dtype: no float64 planes
    near = _bound_below(np.take(gap.reshape(3, -1), maybe, axis=1), np.take(axis, a[pair] * B + frame, axis=1),
                        np.take(axis, b[pair] * B + frame, axis=1), twice_clearance)
    return np.sort(frame[near] * n_pairs + pair[near])  # frame-major: frame * P + pair


def _bound_below(gap: np.ndarray, axis_a: np.ndarray, axis_b: np.ndarray, twice_clearance: np.ndarray) -> np.ndarray:
    """:func:`maybe_near`'s test on coordinate-first planes ``(3, ...)``: ``gap`` = G = 2 (m_b - m_a), the axes
    ``a1 - a0``, ``b1 - b0``; True where the bound is below ``clearance``."""
    length2 = gap[0] * gap[0] + gap[1] * gap[1] + gap[2] * gap[2]  # |G|²
    extent = np.abs(axis_a[0] * gap[0] + axis_a[1] * gap[1] + axis_a[2] * gap[2])
    extent += np.abs(axis_b[0] * gap[0] + axis_b[1] * gap[1] + axis_b[2] * gap[2])
    # bound < clearance  <=>  |G|/2 - extent/(2|G|) < c  <=>  |G|² - extent < 2 c |G| (<=: midpoints that meet)
    return length2 - extent <= twice_clearance * np.sqrt(length2)


NEAR_SLACK = 0.02  # [m] NearPairs' candidates: the pairs that may come within their clearance plus this
# Below this many frames the short-cuts of this module (NearPairs' kept candidates, the hand backward's
# subsets, the written-out short sums) cost more numpy calls than they save: a frame alone (the live
# panel, Retargeter.optimize_frame) ran 12.2 -> 14.6 ms with them (30 iterations, CPU, 2026-11-26).
SMALL_BATCH = 16


class NearPairs:
    """:func:`maybe_near` for an optimisation, which calls it again and again on points that move a little.

    Per frame it keeps the candidates, the pairs whose bound is below ``clearance + slack``, found
    at that frame's reference points, and each call tests only those. Exact: a pair left out was
    at least ``clearance + slack`` apart there, and while no capsule end point of the frame has
    moved more than ``slack / 2`` from its reference no point of a segment has, so the pair is
    still at least ``clearance`` apart (a frame whose ends moved farther is searched again and
    becomes its own reference). So the pairs it returns are :func:`maybe_near`'s, less some
    whose segments are at least ``clearance`` apart, which add exactly 0 to the collision term
    and its gradient. On the 170-frame YuMi recording (``retarget``, 2026-11-26) a call tested about
    4,900 candidates of 148,000 frame-pairs and searched 51 of the 170 frames again (median 33).

    Args:
        capsule_rows: ``(2C,)`` the point rows of every capsule's two ends; pairs: ``(P, 2)`` capsule
            indices; clearance: ``(P,)`` [m]; slack: [m], 0 = search every frame every call.
    """

    def __init__(self, capsule_rows: np.ndarray, pairs: np.ndarray, clearance: np.ndarray, slack: float = NEAR_SLACK):
        self.capsule_rows, self.pairs, self.clearance, self.slack = capsule_rows, pairs, clearance, float(slack)
        rows = np.unique(capsule_rows)  # the distinct end points (capsules share some)
        whole = len(rows) and rows[-1] - rows[0] + 1 == len(rows)  # the point plan's: one block (a view, no gather)
        self.end_rows: np.ndarray | slice = slice(int(rows[0]), int(rows[-1]) + 1) if whole else rows
        ends = capsule_rows.reshape(-1, 2)[pairs]  # (P, 2, 2): the point rows of a0, a1 / b0, b1
        self.pair_rows = ends.reshape(-1, 4).T.copy()  # (4, P)
        self.reference: np.ndarray | None = None  # (B, E, 3) each frame's end points where it was last searched
        self.candidate = np.zeros((0, len(pairs)), dtype=bool)  # (B, P)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """Flat indices ``frame * P + pair`` (frame-major) of the pairs to measure, for points ``(B, K, 3)``."""
        B, K = points.shape[:2]
        n_pairs = len(self.pairs)
        if self.slack <= 0 or B < SMALL_BATCH:  # coordinates first, then whole rows of frames (a gather of the
            # (B, K, 3) points' rows of 3 floats took 112 us at 170 frames, the transpose and np.take 35 us)
            c = np.take(np.ascontiguousarray(points.transpose(2, 1, 0)), self.capsule_rows, axis=1)  # (3, 2C, B)
            return _near_coordinates_first(c.reshape(3, -1, 2, B), self.pairs, self.clearance)
        ends = points[:, self.end_rows]
        if self.reference is None or self.reference.shape != ends.shape or self.reference.dtype != ends.dtype:
            stale = np.arange(B)
            self.reference, self.candidate = ends.copy(), np.zeros((B, n_pairs), dtype=bool)
        else:
            moved = ends - self.reference
            moved *= moved
            moved2 = (moved[..., 0] + moved[..., 1] + moved[..., 2]).max(1)  # (B,) the farthest end's move, squared
            stale = np.flatnonzero(4.0 * moved2 > self.slack * self.slack)  # moved more than slack / 2
            self.reference[stale] = ends[stale]
        if stale.size:
            capsules = points[stale][:, self.capsule_rows].reshape(len(stale), -1, 2, 3)
            found = maybe_near(capsules, self.pairs, self.clearance + self.slack)
            self.candidate[stale] = False
            self.candidate[stale[found // n_pairs], found % n_pairs] = True
        items = np.flatnonzero(self.candidate)
        frame, pair = np.divmod(items, n_pairs)
        # the bound of the candidates alone, the same arithmetic as maybe_near's
        # one np.take of whole rows of the flat points for the four ends (four fancy indexes flat[rows] ran
        # 154 against 89 us for 4,900 candidates at 170 frames)
        ends = np.take(points.reshape(-1, 3), (self.pair_rows[:, pair] + frame * K).reshape(-1), axis=0)
        a0, a1, b0, b1 = ends.reshape(4, -1, 3).transpose(0, 2, 1)  # (3, n) each
        twice_clearance = (2.0 * self.clearance).astype(points.dtype)[pair]
        near = _bound_below((b0 + b1) - (a0 + a1), a1 - a0, b1 - b0, twice_clearance)
        return items[near]


def _dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(a * b).sum(-1)`` over a last axis of 3, written out: the same sum ((x + y) + z), 10x faster than numpy's
    reduction over a short last axis (9 against 134 us at (170, 38, 3)); for a few frames the five calls cost more."""
    if a.shape[0] < SMALL_BATCH:
        return (a * b).sum(-1)
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _rows_times(A: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``A (m, k) @ X (B, k, 3) -> (B, m, 3)`` (C-contiguous) as one 2-d product: ``np.matmul``
    broadcasts ``A`` into B small products (161 against 56 us at B = 170 on YuMi's rows)."""
    B, k, c = X.shape
    Y = X.transpose(0, 2, 1).reshape(B * c, k) @ A.T  # (B c, m)
    return np.ascontiguousarray(Y.reshape(B, c, -1).transpose(0, 2, 1))


def _add_rows(out: np.ndarray, index: np.ndarray, values: np.ndarray) -> None:
    """``out[index[i]] += values[i]`` for ``out (N, 3)``, indices repeating (np.add.at; per coordinate
    np.bincount for many rows: 0.9 against 4.1 ms for 33,000 rows)."""
    if index.size < 2048:
        np.add.at(out, index, values.astype(out.dtype, copy=False))
        return
    for k in range(out.shape[1]):
        out[:, k] += np.bincount(index, weights=values[:, k], minlength=out.shape[0]).astype(out.dtype, copy=False)


class HandTerms:
    """The hand terms (``HAND_TERMS``: ``tip``, ``thumb``, ``pinch``, ``tip_dir``, ``finger_dir``, ``thumb_gap``) in numpy, forward and backward.

    Every wrist -> fingertip vector (``tip``, ``tip_dir``), finger base -> tip vector (``finger_dir``)
    and thumb tip -> fingertip vector (``thumb``) is the difference of two points,
    ``d = p_plus - p_minus``, seen in its wrist
    frame, ``v_i = a_i · d / l`` (``a_i``: the mapped wrist axes, ``l``: the robot's hand length);
    ``tip`` compares the vectors, ``w = v``, the others their directions, ``w = v / n``,
    ``n = sqrt(|v|² + ε)``; the term sums ``mask |w - ŵ|²`` per kind (``tip_dir`` its chord,
    ``sqrt(|w - ŵ|² + ε_c²) - ε_c``, ``ε_c`` = ``CHORD_EPS``). The pinch reads the thumb
    vectors' lengths, ``δ = sqrt(|d|² + ε)/l``: ``active mask ((δ - goal)_+)²``; the thumb gap ``mask e²``,
    ``e = δ - goal`` (``(δ - goal)_+`` where the human's distance is below ``d_min``). Backward:
    ``g_w = 2 mask (w - ŵ)`` (the chord's ``mask (w - ŵ) / sqrt(|w - ŵ|² + ε_c²)``), ``g_v = g_w`` (vectors) or ``(g_w - w (w · g_w)) / n`` (directions),
    ``g_d = Σ_i g_v,i a_i / l`` and ``g_a_i = g_v,i d / l`` (summed per side onto the axes), and the
    pinch's ``2 active mask (δ - goal)_+ d / (l sqrt(|d|² + ε))`` (the gap's likewise with ``mask e``) onto ``d``;
    ``g_d`` onto both points.
    """

    def __init__(self, plus, minus, axes, side, length, kind, v_hat, mask, pinch_goal, pinch_weight, gap_below):
        self.plus, self.minus = np.asarray(plus, dtype=np.int64), np.asarray(minus, dtype=np.int64)  # d = p[plus] - p[minus]
        self.items = len(self.plus)  # K fingertip vectors, K fingertip directions, K finger directions, then J thumb vectors
        self.axes = np.asarray(axes, dtype=np.int64)  # (6,) the wrist axes' points, side-major
        self.side = np.asarray(side, dtype=np.int64)  # (M,)
        dtype = v_hat.dtype
        self.length = np.asarray(length, dtype=dtype)[:, None]  # (M, 1) the robot's hand length per item
        self.kind = np.eye(4, dtype=dtype)[np.asarray(kind, dtype=np.int64)]  # (M, 4) tip / thumb / tip_dir / finger_dir
        self.side_sum = np.eye(2, dtype=dtype)[self.side].T  # (2, M): sums the items of each side
        self.v_hat, self.mask = v_hat, mask[..., None]  # (T, M, 3), (T, M, 1)
        self.pinch_goal, self.pinch_weight = pinch_goal, pinch_weight  # (T, J): max(d̂, floor), activation x mask
        J = pinch_goal.shape[1]
        self.pair_mask = (mask[:, mask.shape[1] - J:]).astype(pinch_goal.dtype)  # (T, J) the thumb gap's
        self.gap_below = gap_below  # (T, J) bool: the human's distance below d_min (the gap only draws down to d_min)
        self.pairs = slice(self.items - pinch_goal.shape[1], self.items)  # the thumb vectors
        # (U, M) over the U points that end a vector: +1 at its plus point, -1 at its minus point, so g_d
        # goes onto the points in one matmul (np.add.at, unbuffered: 61 against 30 us for 97 frames)
        self.end_points, at = np.unique(np.concatenate([self.plus, self.minus]), return_inverse=True)
        self.ends = np.zeros((len(self.end_points), self.items), dtype=dtype)
        np.add.at(self.ends, (at[: self.items], np.arange(self.items)), 1.0)
        np.add.at(self.ends, (at[self.items :], np.arange(self.items)), -1.0)
        self._plans = {}  # (kinds with a gradient) -> the backward's items per set of kinds with a gradient
        # forward and backward work on coordinate planes, (B, 3, M): every op over contiguous rows of the items, the
        # gathers from contiguous rows, each kind a slice (YuMi, 97 frames, 38 items: forward 188 -> 118 us, backward
        # 346 -> 137 us against the (B, M, 3) layout; the same numbers bit for bit)
        kinds = self.kind.argmax(1)
        self.vectors = int(np.sum(kinds == 0))  # the tip vectors come first, each other kind's items are contiguous
        spans = [np.flatnonzero(kinds == k) for k in range(4)]
        if np.any(kinds[: self.vectors] != 0) or any(i.size and i[-1] - i[0] + 1 != i.size for i in spans):
            raise ValueError("HandTerms: the items must be grouped by kind, the tip vectors first")
        chord = np.flatnonzero(kinds == 2)
        self.chord_items = slice(int(chord[0]), int(chord[-1]) + 1) if chord.size else slice(0, 0)
        # A (B, 3, 3, M) as one product of the 6 axes' coordinates with their one-hot spread onto the items (exact: x 1 + 0s)
        spread = np.zeros((6, 3, self.items), dtype=dtype)
        spread[3 * self.side + np.arange(3)[:, None], np.arange(3)[:, None], np.arange(self.items)] = 1.0
        self.axes_spread = spread.reshape(6, -1)  # (6, 3 M): axis point s*3+i -> [i, m] of side s's items
        self.v_hat_planes = np.ascontiguousarray(v_hat.transpose(0, 2, 1))  # (T, 3, M)
        self.mask_planes = np.ascontiguousarray(mask[:, None, :])  # (T, 1, M)
        self.length_row = np.ascontiguousarray(self.length[:, 0])  # (M,)

    @classmethod
    def build(cls, plan: PointPlan, t: Targets, tip_mask: torch.Tensor, pair_mask: torch.Tensor, floor: torch.Tensor) -> HandTerms:
        """The constants for ``plan``'s fingers and thumb pairs and the targets ``t`` (the human side)."""
        K_points = plan.vectors.shape[0]
        wrist, tips = range(*plan.rows["wrist"].indices(K_points)), range(*plan.rows["finger_tip"].indices(K_points))
        bases = range(*plan.rows["finger_base"].indices(K_points))
        fingers, pairs = plan.finger_side.cpu(), plan.thumb_pairs.cpu()
        items = [(tips[k], wrist[int(s)], int(s), 0) for k, s in enumerate(fingers)]  # (plus, minus, side, kind)
        items += [(tips[k], wrist[int(s)], int(s), 2) for k, s in enumerate(fingers)]
        items += [(tips[k], bases[k], int(s), 3) for k, s in enumerate(fingers)]
        items += [(tips[int(f)], tips[int(th)], int(s), 1) for (th, f), s in zip(pairs, plan.pair_side.cpu(), strict=True)]
        side = [s for *_, s, _ in items]
        with torch.no_grad():
            sel = (slice(None), plan.finger_side, plan.finger_index)
            t_tip = t.finger_tip[sel]  # (T, K, 3): the human fingertips the robot has
            to_tip = t_tip - t.wrist[:, plan.finger_side]
            j = plan.thumb_pairs
            t_vec = torch.cat([to_tip, to_tip, t_tip - t.finger_base[sel], t_tip[:, j[:, 1]] - t_tip[:, j[:, 0]]], 1)
            v_hat = in_wrist_frame(t_vec, t.wrist_rotation, torch.as_tensor(side, dtype=torch.long), t.hand_length)
            v_hat[:, len(fingers):] = unit(v_hat[:, len(fingers):])  # all but the tip vectors: directions
            d_hat = (t_tip[:, j[:, 1]] - t_tip[:, j[:, 0]]).norm(dim=-1) / t.hand_length[:, plan.pair_side]
            goal, active, below = torch.maximum(d_hat, floor), pinch_activation(d_hat), d_hat < floor
            mask = torch.cat([tip_mask, tip_mask, tip_mask, pair_mask], 1)
        return cls(
            [i[0] for i in items], [i[1] for i in items], np.arange(*plan.rows["wrist_axes"].indices(K_points)), side,
            plan.hand_length.cpu().numpy()[side], [k for *_, k in items], v_hat.cpu().numpy(), mask.cpu().numpy(), goal.cpu().numpy(),
            (active * pair_mask).cpu().numpy().astype(plan.hand_length.cpu().numpy().dtype), below.cpu().numpy(),
        ).observed()

    def observed(self) -> HandTerms:
        """These terms without the items unobserved in every frame (a hand never seen in a clip: its
        fingers and thumb pairs), or themselves when all count somewhere. Those items add exactly 0 to
        every term and gradient (masked; the pinch's activation and the thumb gap carry the mask too)."""
        keep = self.mask[..., 0].any(0)  # (M,)
        if keep.all():
            return self
        pair = keep[self.pairs]  # the thumb vectors stay the last items
        return HandTerms(self.plus[keep], self.minus[keep], self.axes, self.side[keep], self.length[keep, 0],
                         self.kind[keep].argmax(1), self.v_hat[:, keep], self.mask[:, keep, 0], self.pinch_goal[:, pair],
                         self.pinch_weight[:, pair], self.gap_below[:, pair])

    columns = [0, 1, 3, 4]  # the output columns of the kinds tip, thumb, tip_dir, finger_dir (HAND_TERMS order; 2: pinch)

    def forward(self, P: np.ndarray, out: np.ndarray):
        """Writes the terms ``(B, 6)`` (``HAND_TERMS`` order) into ``out``; returns what the backward needs.

        On coordinate planes: ``d (B, 3, M)``, ``A (B, 3, 3, M)`` (``A[:, c, i]``: coordinate c of axis ``a_i``)."""
        B = P.shape[0]
        Q = np.ascontiguousarray(P.transpose(0, 2, 1))  # (B, 3, K): gathers from contiguous rows cost a third
        d = np.take(Q, self.plus, axis=2) - np.take(Q, self.minus, axis=2)  # (B, 3, M)
        A = (np.take(Q, self.axes, axis=2).reshape(3 * B, 6) @ self.axes_spread).reshape(B, 3, 3, self.items)  # [b, c, i, m]
        v = (A[:, 0] * d[:, 0:1] + A[:, 1] * d[:, 1:2] + A[:, 2] * d[:, 2:3]) / self.length_row  # (B, 3, M): v_i = Σ_c a_ic d_c / l
        n = np.ones((B, 1, self.items), dtype=v.dtype)  # 1 for the tip vectors, |v|_ε for the directions
        u = v[..., self.vectors :]
        n[:, 0, self.vectors :] = np.sqrt(u[:, 0] * u[:, 0] + u[:, 1] * u[:, 1] + u[:, 2] * u[:, 2] + UNIT_EPS)
        w = v / n
        r = np.where(self.mask_planes, w - self.v_hat_planes, 0.0)
        cost = r[:, 0] * r[:, 0] + r[:, 1] * r[:, 1] + r[:, 2] * r[:, 2]  # (B, M): |w - ŵ|², the chord's below
        distance = np.sqrt(cost[:, self.chord_items] + CHORD_EPS * CHORD_EPS)
        cost[:, self.chord_items] = distance - CHORD_EPS
        out[:, self.columns] = cost @ self.kind
        r[..., self.chord_items] /= 2.0 * distance[:, None]  # the backward's 2 r: the chord's r / distance
        gap = d[..., self.pairs]  # (B, 3, J)
        root = np.sqrt(gap[:, 0] * gap[:, 0] + gap[:, 1] * gap[:, 1] + gap[:, 2] * gap[:, 2] + UNIT_EPS)  # (B, J)
        diff = root / self.length_row[self.pairs] - self.pinch_goal  # (B, J): δ - goal
        over = np.maximum(diff, 0.0)
        out[:, 2] = (self.pinch_weight * over * over).sum(-1)
        gap = np.where(self.gap_below, over, diff)  # e of the thumb gap
        out[:, 5] = (self.pair_mask * gap * gap).sum(-1)
        return d, A, r, root, over, w, n, gap

    def _active(self, g: np.ndarray) -> tuple:
        """The items the gradient ``g (B, 6)`` reaches, and their constants (kept per set of kinds).

        A kind whose column of ``g`` is 0 in every frame (its weight 0: the latent optimisation runs the
        hand stage's terms at 0, ``LossWeights.latent_stage``) adds exactly 0: its items are left out of
        the backward (the thumb vectors stay while the pinch or the thumb gap counts).
        """
        # per HAND_TERMS column; for a few frames every item (the subsets' gathers cost more than they save)
        on = (True,) * 6 if g.shape[0] < SMALL_BATCH else tuple(bool(x) for x in np.any(g != 0, axis=0))
        plan = self._plans.get(on)
        if plan is None:
            kinds = [k for k, c in enumerate(self.columns) if on[c]]  # tip, thumb, tip_dir, finger_dir
            keep = self.kind[:, kinds].sum(1) > 0 if kinds else np.zeros(self.items, dtype=bool)
            if on[2] or on[5]:  # the pinch and the thumb gap read the thumb vectors' lengths
                keep[self.pairs] = True
            sel = np.flatnonzero(keep)
            is_pair = keep[self.pairs]  # the thumb vectors among the kept items are the last ones
            directions = slice(int(np.sum(sel < self.vectors)), len(sel))  # the tip vectors come first
            plan = self._plans[on] = (None if len(sel) == self.items else sel, self.kind[sel].T.copy(), self.length_row[sel], directions,
                                      np.ascontiguousarray(self.side_sum[:, sel].T), np.ascontiguousarray(self.ends[:, sel]),
                                      slice(len(sel) - int(is_pair.sum()), len(sel)) if is_pair.any() else None)
        return plan

    def backward(self, g: np.ndarray, saved, gP: np.ndarray) -> None:
        """Adds the gradient of ``sum(g * terms)`` (``g (B, 6)``) with respect to the points to ``gP``.

        Only the items of the kinds ``g`` reaches (:meth:`_active`): the same sum, without its zeros."""
        d, A, r, root, over, w, n, gap = saved
        sel, kind_t, length, directions, side_sum_t, ends, pairs = self._active(g)
        if ends.shape[1] == 0:
            return
        if sel is not None:
            d, A, r, w, n = d[..., sel], A[..., sel], r[..., sel], w[..., sel], n[..., sel]
        B, M = g.shape[0], ends.shape[1]
        g_w = 2.0 * r * (g[:, self.columns] @ kind_t)[:, None, :]  # (B, 3, M)
        u, g_u = w[..., directions], g_w[..., directions]  # the directions: (g_w - w (w · g_w)) / n
        along = u[:, 0] * g_u[:, 0] + u[:, 1] * g_u[:, 1] + u[:, 2] * g_u[:, 2]
        g_w[..., directions] = (g_u - u * along[:, None]) / n[..., directions]
        g_v = g_w / length  # with the 1/l of v
        g_d = A[:, :, 0] * g_v[:, 0:1] + A[:, :, 1] * g_v[:, 1:2] + A[:, :, 2] * g_v[:, 2:3]  # (B, 3, M): Σ_i g_v,i a_i
        g_A = d[:, :, None, :] * g_v[:, None, :, :]  # (B, 3, 3, M): onto axis i, coordinate c
        g_axes = (g_A.reshape(B * 9, M) @ side_sum_t).reshape(B, 3, 3, 2)  # summed per side: [b, c, i, side]
        if pairs is not None:
            pinch = 2.0 * (g[:, 2:3] * self.pinch_weight * over + g[:, 5:6] * self.pair_mask * gap) / (root * self.length_row[self.pairs])  # (B, J)
            g_d[..., pairs] += pinch[:, None, :] * d[..., pairs]
        # onto both ends of every vector (a point may end several): one product with the ends' ±1
        gP[:, self.end_points] += (ends @ g_d.transpose(2, 0, 1).reshape(M, 3 * B)).reshape(-1, B, 3).transpose(1, 0, 2)
        gP[:, self.axes] += g_axes.transpose(0, 3, 2, 1).reshape(B, 6, 3)


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
        hand: the hand terms' :class:`HandTerms`.
        capsule_rows: ``(2C,)`` point index of every capsule's two end points; pair_capsules:
            ``(P, 2)`` the capsules of each pair (for the culling bound).
    """

    n_terms = len(TERMS)  # the paper's five, then the hand terms

    def __init__(self, rows, finger_row, row_term, goal, mask, pair_points, pair_radii, margins, form: str, hand: HandTerms,
                 capsule_rows, pair_capsules):
        self.rows = np.ascontiguousarray(rows)
        # the rows combine a few of the points (YuMi: 32 of 174; the others are capsule ends): products over those only
        self.row_points = np.flatnonzero(np.any(self.rows != 0, axis=0))
        self.rows_used = np.ascontiguousarray(self.rows[:, self.row_points])  # (V, K_used)
        self.rows_used_t = np.ascontiguousarray(self.rows_used.T)
        self.fingers = np.flatnonzero(finger_row)
        self.term_of_row = np.eye(4, dtype=self.rows.dtype)[np.asarray(row_term, dtype=np.int64)]  # (V, 4)
        self.goal = np.ascontiguousarray(goal)
        self.mask = np.asarray(mask, dtype=bool)[..., None]  # (T, V, 1)
        self.pair_points = np.asarray(pair_points, dtype=np.int64)
        self.radii = np.asarray(pair_radii, dtype=np.float64)
        self.margins = np.asarray(margins, dtype=np.float64)
        self.form = form
        # Culling: a pair is measured exactly only where a lower bound of its segments' distance, minus
        # the radii, is below its margin (+ CULL_SLACK for rounding); the others add exactly 0. The
        # bound: the segments' extents along the line n through their midpoints m_a, m_b,
        # |m_b - m_a| - (|(a1 - a0)·n| + |(b1 - b0)·n|)/2 (a separating-axis bound; near_pairs' sphere
        # bound |m_b - m_a| - (l_a + l_b)/2 is looser for long capsules side by side).
        self.capsule_rows = np.asarray(capsule_rows, dtype=np.int64)  # (2C,) the capsules' end points, in pairs
        self.pair_capsules = np.asarray(pair_capsules, dtype=np.int64)  # (P, 2)
        self.clearance = self.radii + self.margins + CULL_SLACK  # (P,)
        self.near_pairs = NearPairs(self.capsule_rows, self.pair_capsules, self.clearance)  # kept across calls
        self.hand = hand
        self.collision_held: np.ndarray | None = None  # (T,) the collision term of the pairs :meth:`held` measured once

    def held(self, moving: np.ndarray, points: np.ndarray) -> PointTerms:
        """These terms for points that differ from ``points (T, K, 3)`` only in the rows ``moving`` (``(K,)`` bool):
        the hand stage, whose arms stay where they are.

        A capsule pair without a moving end point is measured once, here: its share of the collision
        term becomes a constant per frame, and its gradient, which reaches only points that do not move,
        is left out (YuMi: 47 of 873 pairs have an end on a hand). The other terms as they are.
        """
        fixed = ~np.asarray(moving, dtype=bool)[self.pair_points.reshape(-1, 4)].any(1)  # (P,)
        once = self._with_pairs(fixed)
        once.collision_held = None
        out = self._with_pairs(~fixed)
        out.collision_held = once.forward(points)[0][:, 4].astype(np.float64)
        if self.collision_held is not None:  # held twice: what the first held too
            out.collision_held += self.collision_held
        return out

    def with_near_slack(self, slack: float) -> PointTerms:
        """A copy whose own :class:`NearPairs` keeps its candidates within ``slack`` [m] (0: every frame's pairs searched
        every call), the arrays shared; the terms the same to the bit whatever the slack (the tests hold it)."""
        out = copy.copy(self)
        out.near_pairs = NearPairs(self.capsule_rows, self.pair_capsules, self.clearance, slack)
        return out

    def _with_pairs(self, keep: np.ndarray) -> PointTerms:
        """A copy measuring only the collision pairs ``keep`` (``(P,)`` bool), its own :class:`NearPairs`."""
        out = copy.copy(self)
        out.pair_points = self.pair_points.reshape(-1, 4)[keep].reshape(-1)
        out.radii, out.margins, out.clearance = self.radii[keep], self.margins[keep], self.clearance[keep]
        out.pair_capsules = self.pair_capsules[keep]
        out.near_pairs = NearPairs(self.capsule_rows, out.pair_capsules, out.clearance)
        return out

    @classmethod
    def build(cls, plan: PointPlan, targets: Targets, form: str, tip_mask: torch.Tensor, pair_mask: torch.Tensor,
              pinch_floor: torch.Tensor) -> PointTerms:
        """The terms of :mod:`nlo_lab.objective.terms` as rows over ``plan``'s points, for ``targets``.

        Residual rows (each a fixed combination of points, minus the human side):
        ee ``(w - s)/l`` (2), ori the columns of ``R_wrist R_align`` (6), elbow
        ``(w - e)/l_fore`` (2), finger ``tip - base`` (K, normalised); the hand terms:
        :class:`HandTerms` (``tip_mask``, ``pair_mask``, ``pinch_floor``: the objective's).
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
            plan.margins.cpu().numpy(), form, HandTerms.build(plan, targets, tip_mask, pair_mask, pinch_floor),
            plan.capsule_end_rows.cpu().numpy(), plan.robot.pair_capsules,
        )

    def reached(self, saved) -> np.ndarray:
        """Sorted indices of the points whose gradient :meth:`backward` can make non-zero, for the forward that
        returned ``saved``: the rows' points, the hand terms' and the ends of the capsule pairs it measured (the
        others' gradient is 0 in every frame)."""
        static = self.__dict__.get("_static_reached")
        if static is None:  # (K,) bool: the rows' and the hand terms' points
            hand = [self.hand.end_points, self.hand.axes] if self.hand.items else []
            static = self.__dict__["_static_reached"] = np.zeros(self.rows.shape[1], dtype=bool)
            static[np.concatenate([self.row_points, *hand]).astype(np.int64)] = True
        coll = saved[3]
        if coll is None:
            return np.flatnonzero(static)
        hit = static.copy()
        hit[self.pair_points.reshape(-1, 4)[coll[0] % self.radii.shape[0]]] = True  # a mask: no sort of the pairs
        return np.flatnonzero(hit)

    def forward(self, P: np.ndarray, pairs: bool = True):
        """Terms ``(B, len(TERMS))`` (``TERMS`` order) and what the backward needs, for points ``P (B, K, 3)`` (B = T).

        ``pairs=False``: the capsule pairs are not measured (the collision term reads 0, and adds no gradient): for
        a caller that has it already (:func:`~nlo_lab.inference.sequence_start`'s candidates)."""
        goal, mask = self.goal, self.mask
        # (B, V, 3): rows @ P, the unused points left out (np.take: a fancy index P[:, rows] ran 23 against 13 us, 170 frames, 2026-11-26)
        v = _rows_times(self.rows_used, np.take(P, self.row_points, axis=1))
        f = self.fingers
        norm = unit = None
        if f.size:
            vf = v[:, f]
            norm = np.sqrt(_dot3(vf, vf)[..., None] + UNIT_EPS)  # (B, F, 1)
            unit = vf / norm
            v[:, f] = unit
        r = np.where(mask, v - goal, 0.0).astype(P.dtype, copy=False)  # (B, V, 3), 0 where masked
        terms = np.zeros((P.shape[0], self.n_terms), dtype=P.dtype)
        terms[:, :4] = _dot3(r, r) @ self.term_of_row
        coll = None
        if self.radii.shape[0] and pairs:
            near = self.near_pairs(P)  # maybe_near's pairs (and some certainly clear), searched again only where points moved
            if near.size:  # the others add exactly 0
                frame, pair = np.divmod(near, self.radii.shape[0])
                # the ends a0, a1, b0, b1 as (4, 3, n): one np.take of whole rows of the flat points (a fancy
                # index P[frame, rows] ran twice as slow: 217 against 104 us for 5,000 pairs at 170 frames)
                at = (self.pair_points.reshape(-1, 4)[pair] + (frame * P.shape[1])[:, None]).T.reshape(-1)  # (4n,)
                ends = np.take(P.reshape(-1, 3), at, axis=0).reshape(4, -1, 3).transpose(0, 2, 1)
                _, _, w, dist, u = segment_closest_points(ends.astype(np.float64, order="C"))
                m = self.margins[pair]
                d = dist - self.radii[pair]  # surface distance [m]
                if self.form == "paper":
                    e = np.where(d < m, np.exp(-d * d), 0.0)
                    value, slope = e, -2.0 * d * e  # the term and d term / d d
                else:
                    s = np.where(m > 0, m, CONTACT_SCALE)  # collision_scale: a margin-0 pair's unit
                    h = np.clip((m - d) / s, 0.0, None)
                    value, slope = h * h, -2.0 * h / s
                terms[:, 4] = np.bincount(near // self.radii.shape[0], weights=value, minlength=P.shape[0])
                coll = (near, slope, w, u)
        if self.collision_held is not None and pairs:  # the pairs measured once (held)
            terms[:, 4] += self.collision_held
        hand = self.hand.forward(P, terms[:, 5:]) if self.hand.items else None
        return terms, (r, unit, norm, coll, hand)

    def backward(self, g: np.ndarray, saved) -> np.ndarray:
        """Gradient ``(B, K, 3)`` of ``sum(g * terms)`` with respect to the points."""
        r, unit, norm, coll, hand = saved
        gv = 2.0 * r * (g[:, :4] @ self.term_of_row.T)[..., None]  # (B, V, 3)
        f = self.fingers
        if f.size:
            gu = gv[:, f]
            gv[:, f] = (gu - unit * _dot3(unit, gu)[..., None]) / norm
        gP = np.zeros(g.shape[:1] + self.rows.shape[1:] + (3,), dtype=gv.dtype)  # (B, K, 3): the pairs' gradients are added in place
        gP[:, self.row_points] = _rows_times(self.rows_used_t, gv)  # rowsᵀ @ gv on the points the rows use
        if coll is not None:
            near, slope, w, u = coll
            frame, pair = np.divmod(near, self.radii.shape[0])
            gd = g[frame, 4] * slope  # (n,) for the near pairs
            g_ends = (gd[:, None] * w)[..., None] * u[:, None, :]  # (n, 4, 3): envelope gradient of each end
            at = frame[:, None] * gP.shape[1] + self.pair_points.reshape(-1, 4)[pair]  # (n, 4) rows of the flat points
            _add_rows(gP.reshape(-1, 3), at.reshape(-1), g_ends.reshape(-1, 3))
        if hand is not None:
            self.hand.backward(g[:, 5:], hand, gP)
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


class SmoothTerm:
    """The weighted smoothness term of a sequence in numpy, with its gradient written out.

    ``w * smoothness_loss(q)`` (:func:`~nlo_lab.objective.terms.smoothness_loss`; with ``anchor``, frame 0
    pays its step from that fixed frame, as :func:`nlo_lab.inference.smoothness_term`): per step
    ``Δ = q_t - q_{t-1}``, ``Σ_j (Δ_j c_j)² + Σ_j ((|Δ_j| - MAX_STEP)_+ / WIDTH)²`` with ``c = fps / s``;
    its derivative in ``Δ`` is ``2 Δ c² + 2 (|Δ| - MAX_STEP)_+ sign(Δ) / WIDTH²``, and ``Δ_t`` moves
    ``q_t`` up and ``q_{t-1}`` down. Tested equal to the torch term, values and gradients.

    Args:
        fps: frame rate [1/s]; velocity_limits: ``(n,)`` [rad/s]; weight: ``LossWeights.smooth``;
        anchor: ``(n,)`` the fixed frame before the first, or None; dtype: torch dtype of the angles.
    """

    def __init__(self, fps: float, velocity_limits: torch.Tensor, weight: float, anchor: torch.Tensor | None, dtype: torch.dtype):
        # the torch term's arithmetic: fps / s in the angles' dtype
        self.scale = (fps / smoothness_scale(velocity_limits.detach().cpu()).to(dtype)).numpy()
        self.weight = float(weight)
        self.anchor = None if anchor is None else anchor.detach().cpu().to(dtype).numpy().reshape(1, -1)

    def forward(self, q: np.ndarray):
        """``q (T, n)`` -> the weighted term per frame ``(T,)`` and what the backward needs."""
        full = q if self.anchor is None else np.concatenate([self.anchor, q])
        step = full[1:] - full[:-1]  # (S, n): S = T - 1, or T with the anchor
        speed = step * self.scale
        jump = np.maximum(np.abs(step) - SMOOTH_MAX_STEP, 0.0) / SMOOTH_STEP_WIDTH
        cost = (speed * speed).sum(-1) + (jump * jump).sum(-1)
        out = np.zeros(len(q), dtype=q.dtype)
        out[len(q) - len(cost):] = cost
        return self.weight * out, (step, speed, jump)

    def backward(self, g: np.ndarray, state) -> np.ndarray:
        """``(T, n)``: the gradient of ``sum(g * term)`` in ``q``, ``g (T,)``."""
        step, speed, jump = state
        T = len(g)
        g_cost = (self.weight * g[T - len(step):])[:, None]  # the frames that pay a step
        g_step = g_cost * (2.0 * speed * self.scale + (2.0 / SMOOTH_STEP_WIDTH) * jump * np.sign(step))
        g_q = np.zeros((T, step.shape[1]), dtype=step.dtype)
        g_q[T - len(step):] += g_step  # Δ_t = q_t - q_(t-1)
        g_q[: T - 1] -= g_step[len(step) - (T - 1):]  # ... and q_(t-1) down (with the anchor, Δ_0 moves no free frame)
        return g_q

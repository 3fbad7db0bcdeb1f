"""Closest distance between 3-D segments and between capsules, batched and differentiable.

The closest points are found with the clamped closed form of Ericson
(*Real-Time Collision Detection*, 5.1.9). The parameters ``s, t`` of the
closest points are detached: by the envelope theorem the gradient of a minimum
is the partial gradient at the minimiser, which keeps the backward pass cheap
and free of the ill-conditioned ``1 / denom`` of near-parallel segments. Every
division has a clamped denominator, so parallel and zero-length segments give
finite values and gradients.
"""

from __future__ import annotations

import numpy as np
import torch

__all__ = ["segment_distance", "segment_distance_ends", "closest_parameters", "capsule_distance", "segment_closest_points"]

_EPS = 1e-12  # [m^2] denominators below this are treated as degenerate
# rows d1 = a1 - a0, d2 = b1 - b0, r = a0 - b0 of the end points (a0, a1, b0, b1)
_DIFF = np.array([[-1.0, 1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 1.0], [1.0, 0.0, -1.0, 0.0]])
_DIFF_T: dict = {}  # device -> _DIFF as a float64 tensor
# segment pairs up to which the closest points are computed in numpy (the same
# function, segment_closest_points, in either library): crossover about 3000 pairs
NUMPY_MAX_PAIRS = 4096
# segment_closest_points forms its dot products one at a time above this many pairs (all nine at once held 36
# floats per pair: the peak of a long recording's collision metric, 1,000 frames x 873 pairs on YuMi); below,
# at once (fewer calls: the optimisers' few near pairs)
MANY_PAIRS = 65536


# (clamp below, clamp to [0, 1]) per library; np.clip's Python wrapper costs
# microseconds per call, the ufuncs do not (this runs every optimiser step)
_CLAMPS = {
    True: (np.maximum, lambda x: np.minimum(np.maximum(x, 0.0), 1.0)),
    False: (torch.clamp_min, lambda x: x.clamp(0.0, 1.0)),
}


def segment_closest_points(E):
    """Closest points and distance of segments, in float64, numpy or torch alike (no gradient).

    Ericson's clamped closed form, written as: ``s`` of the infinite lines
    (0 when parallel or when a is a point), ``t`` for that ``s`` clamped to
    [0, 1], then ``s`` again for the clamped ``t`` (the same minimiser).

    Args:
        E: ``(4, 3, n)`` float64 end points a0, a1, b0, b1 (coordinates first:
            every product below is on contiguous planes), a numpy array or a
            tensor; the arithmetic runs in its library.

    Returns:
        ``s, t (n,)``, ``w (n, 4)`` with ``p - q = sum_j w_j end_j``, ``dist (n,)``
        and ``u (n, 3)`` the unit vector ``(p - q)/dist`` (0 where the segments meet).
    """
    xp, diff = (np, _DIFF) if isinstance(E, np.ndarray) else (torch, _diff_tensor(E.device))
    # float64: a*e - b*b cancels badly in float32 for near-parallel segments
    D = (diff @ E.reshape(4, -1)).reshape(3, 1, 3, -1)  # (d1, d2, r) x 1 x (x, y, z) x n
    if D.shape[-1] <= MANY_PAIRS:
        G = (D * D.swapaxes(0, 1)).sum(2)  # (3, 3, n): every dot product of d1, d2, r
        a, e, b, c, f = G[0, 0], G[1, 1], G[0, 1], G[0, 2], G[1, 2]
    else:  # the five the formula reads, one at a time: the same sums, without 36 floats per pair at once
        d1, d2, r = D[:, 0]
        a, e, b, c, f = ((u * v).sum(0) for u, v in ((d1, d1), (d2, d2), (d1, d2), (d1, r), (d2, r)))
    lo, unit = _CLAMPS[xp is np]
    a_s, e_s = lo(a, _EPS), lo(e, _EPS)
    denom = a * e - b * b  # >= 0, 0 for parallel segments
    degenerate = (denom <= 1e-10 * a_s * e_s) | (a <= _EPS)  # parallel (relative to the lengths), or a is a point
    s = xp.where(degenerate, 0.0, unit((b * f - c * e) / lo(denom, _EPS * _EPS)))
    t = unit((b * s + f) / e_s)  # b a point: b = f = 0, so t = 0
    s = xp.where(a <= _EPS, 0.0, unit((b * t - c) / a_s))
    w = xp.stack([1.0 - s, s, t - 1.0, -t], -1)  # (n, 4)
    pq = (E * w.T[:, None, :]).sum(0)  # (3, n)
    d2 = (pq * pq).sum(0)
    meet = d2 <= _EPS  # sqrt has no gradient at 0: distance and gradient read as 0
    dist = xp.sqrt(lo(d2, _EPS))
    return s, t, w, xp.where(meet, 0.0, dist), xp.where(meet, 0.0, pq / dist).T


def _diff_tensor(device: torch.device) -> torch.Tensor:
    """:data:`_DIFF` as a float64 tensor on ``device`` (made once per device)."""
    diff = _DIFF_T.get(device)
    if diff is None:
        diff = _DIFF_T[device] = torch.as_tensor(_DIFF, device=device)
    return diff


def _distance_parts(ends: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """:func:`segment_closest_points` of ``ends (..., 4, 3)``; returns float64 tensors ``(n, ...)``.

    On the CPU and for few pairs the arithmetic runs in numpy: it is some 40
    tiny no-grad ops, and numpy's per-op overhead is a fraction of torch's (the
    objective calls this every iteration, at batch 1 in the live use); for many
    pairs torch's kernels are faster.
    """
    flat = ends.detach().reshape(-1, 4, 3)
    if flat.device.type == "cpu" and flat.shape[0] <= NUMPY_MAX_PAIRS:
        return _distance_parts_numpy(flat)
    return segment_closest_points(flat.to(torch.float64).permute(1, 2, 0))


def _distance_parts_numpy(flat: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """:func:`segment_closest_points` in numpy for ``flat (n, 4, 3)`` CPU end points (the fast path)."""
    E = flat.numpy().transpose(1, 2, 0).astype(np.float64)
    return tuple(torch.from_numpy(np.ascontiguousarray(x)) for x in segment_closest_points(E))


def _closest_st(ends: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``s, t`` (float64, no gradient) for end points ``(..., 4, 3)`` = (a0, a1, b0, b1)."""
    s, t, *_ = _distance_parts(ends)
    return s.view(ends.shape[:-2]), t.view(ends.shape[:-2])


def closest_parameters(a0: torch.Tensor, a1: torch.Tensor, b0: torch.Tensor, b1: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Parameters ``s, t`` in [0, 1] of the closest points ``a0 + s (a1 - a0)`` and ``b0 + t (b1 - b0)``.

    Args:
        a0, a1, b0, b1: ``(..., 3)`` segment end points (broadcastable).

    Returns:
        ``s, t``: ``(...)`` each, without gradient.
    """
    dtype = torch.promote_types(a0.dtype, b0.dtype)
    s, t = _closest_st(torch.stack(torch.broadcast_tensors(a0, a1, b0, b1), -2))
    return s.to(dtype), t.to(dtype)


class _SegmentDistance(torch.autograd.Function):
    """Distance from stacked end points with a hand-written backward.

    By the envelope theorem the gradient is the partial one at the closest
    points: ``d dist / d end_j = w_j u`` with ``w = (1 - s, s, t - 1, -t)`` and
    ``u`` the unit vector from the closest point on b to the one on a (0 when
    they meet). Two ops instead of autograd's chain through every step.
    """

    @staticmethod
    def forward(ctx, ends: torch.Tensor) -> torch.Tensor:
        _, _, w, dist, u = (x.to(ends.dtype) for x in _distance_parts(ends))
        ctx.save_for_backward(w.view(*ends.shape[:-1]), u.view(*ends.shape[:-2], 3))
        return dist.view(ends.shape[:-2])

    @staticmethod
    def backward(ctx, grad: torch.Tensor) -> torch.Tensor:
        w, u = ctx.saved_tensors
        return (grad[..., None] * w)[..., :, None] * u[..., None, :]  # (..., 4, 3)


def segment_distance_ends(ends: torch.Tensor) -> torch.Tensor:
    """Closest distance between segments given as stacked end points.

    Args:
        ends: ``(..., 4, 3)`` rows ``a0, a1, b0, b1`` [m].

    Returns:
        ``(...)`` distance [m] (>= 0), as :func:`segment_distance`.
    """
    return _SegmentDistance.apply(ends)


def segment_distance(a0: torch.Tensor, a1: torch.Tensor, b0: torch.Tensor, b1: torch.Tensor) -> torch.Tensor:
    """Closest distance between segments ``[a0, a1]`` and ``[b0, b1]``.

    Args:
        a0, a1, b0, b1: ``(..., 3)`` end points [m], broadcastable.

    Returns:
        ``(...)`` distance [m] (>= 0). Differentiable; distances below
        1e-6 m read as 0, with zero gradient (sqrt is not differentiable at 0).
    """
    return segment_distance_ends(torch.stack(torch.broadcast_tensors(a0, a1, b0, b1), -2))


def capsule_distance(
    a0: torch.Tensor, a1: torch.Tensor, ra: torch.Tensor | float, b0: torch.Tensor, b1: torch.Tensor, rb: torch.Tensor | float
) -> torch.Tensor:
    """Surface distance between two capsules (segment distance minus both radii).

    Args:
        a0, a1: ``(..., 3)`` axis end points of capsule a [m].
        ra: radius of a [m], scalar or ``(...)``.
        b0, b1: ``(..., 3)`` axis end points of capsule b [m].
        rb: radius of b [m].

    Returns:
        ``(...)`` [m]; negative when the capsules overlap.
    """
    return segment_distance(a0, a1, b0, b1) - ra - rb

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

import torch

__all__ = ["segment_distance", "segment_distance_ends", "closest_parameters", "capsule_distance"]

_EPS = 1e-12  # [m^2] denominators below this are treated as degenerate
# rows d1 = a1 - a0, d2 = b1 - b0, r = a0 - b0 of the end points (a0, a1, b0, b1)
_DIFF = ((-1.0, 1.0, 0.0, 0.0), (0.0, 0.0, -1.0, 1.0), (1.0, 0.0, -1.0, 0.0))
_CONSTS: dict = {}


def _diff_matrix(device) -> torch.Tensor:
    """``(3, 4)`` float64 :data:`_DIFF` on ``device`` (cached: a new tensor per call costs more than the math at batch 1)."""
    c = _CONSTS.get(device)
    if c is None:
        c = _CONSTS[device] = torch.tensor(_DIFF, dtype=torch.float64, device=device)
    return c


def _closest_st(ends: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``s, t`` (float64, no gradient) for end points ``(..., 4, 3)`` = (a0, a1, b0, b1).

    Ericson's clamped closed form, written as: ``s`` of the infinite lines
    (0 when parallel), ``t`` for that ``s`` clamped to [0, 1], then ``s`` again
    for the clamped ``t`` (the same minimiser, in few batched ops).
    """
    with torch.no_grad():
        diff = _diff_matrix(ends.device)
        # float64 here: a*e - b*b cancels badly in float32 for near-parallel segments.
        # Coordinates first: (4, 3 * rest), so that everything below is on contiguous planes.
        E = ends.detach().to(torch.float64).movedim((-2, -1), (0, 1))
        D = (diff @ E.reshape(4, -1)).view(3, 1, 3, -1)  # (d1, d2, r) x 1 x (x, y, z) x rest
        G = (D * D.transpose(0, 1)).sum(2)  # (3, 3, rest): every dot product of d1, d2, r
        a, e, b, c, f = G[0, 0], G[1, 1], G[0, 1], G[0, 2], G[1, 2]
        a_s, e_s = a.clamp_min(_EPS), e.clamp_min(_EPS)
        denom = a * e - b * b  # >= 0, 0 for parallel segments
        # Parallel (relative to the lengths) or a is a point: any s works; take 0.
        degenerate = (denom <= 1e-10 * a_s * e_s) | (a <= _EPS)
        s = ((b * f - c * e) / denom.clamp_min(_EPS * _EPS)).clamp(0.0, 1.0).masked_fill(degenerate, 0.0)
        t = ((b * s + f) / e_s).clamp(0.0, 1.0)  # b a point: b = f = 0, so t = 0
        s = ((b * t - c) / a_s).clamp(0.0, 1.0).masked_fill(a <= _EPS, 0.0)
    shape = ends.shape[:-2]
    return s.view(shape), t.view(shape)


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
        s, t = _closest_st(ends)
        w = torch.stack([1.0 - s, s, t - 1.0, -t], -1).to(ends.dtype)  # (..., 4)
        diff = (ends.mT * w[..., None, :]).sum(-1)  # (..., 3) p - q = sum_j w_j end_j
        d2 = diff.pow(2).sum(-1)
        meet = d2 <= _EPS  # sqrt has no gradient at 0: distance and gradient read as 0
        dist = d2.clamp_min(_EPS).sqrt().masked_fill(meet, 0.0)
        ctx.save_for_backward(w, (diff / dist.clamp_min(_EPS)[..., None]).masked_fill(meet[..., None], 0.0))
        return dist

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

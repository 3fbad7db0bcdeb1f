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
# the five dot products of Ericson's closed form, as (row, row) pairs of (d1, d2, r)
_DOT_LEFT, _DOT_RIGHT = (0, 1, 0, 0, 1), (0, 1, 1, 2, 2)  # a = d1.d1, e = d2.d2, b = d1.d2, c = d1.r, f = d2.r


def _closest_st(ends: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``s, t`` (float64, no gradient) for end points ``(..., 4, 3)`` = (a0, a1, b0, b1)."""
    with torch.no_grad():
        # float64 here: a*e - b*b cancels badly in float32 for near-parallel segments
        e64 = ends.detach().to(torch.float64)
        D = e64.mT @ torch.tensor(_DIFF, dtype=torch.float64, device=e64.device).T  # (..., 3, 3) columns d1, d2, r
        left = D.index_select(-1, torch.tensor(_DOT_LEFT, device=e64.device))
        right = D.index_select(-1, torch.tensor(_DOT_RIGHT, device=e64.device))
        a, e, b, c, f = (left * right).sum(-2).unbind(-1)  # (...) each
        a_s, e_s = a.clamp_min(_EPS), e.clamp_min(_EPS)
        denom = a * e - b * b  # >= 0, 0 for parallel segments
        # Parallel (relative to the lengths): any s works; take 0.
        parallel = (denom <= 1e-10 * a_s * e_s) | (a <= _EPS)
        s = torch.where(parallel, 0.0, ((b * f - c * e) / denom.clamp_min(_EPS * _EPS)).clamp(0.0, 1.0))
        t = (b * s + f) / e_s
        # t outside [0, 1]: clamp it and recompute s for the clamped t.
        s = torch.where(t < 0.0, (-c / a_s).clamp(0.0, 1.0), torch.where(t > 1.0, ((b - c) / a_s).clamp(0.0, 1.0), s))
        t = t.clamp(0.0, 1.0)
        # b is a point: t = 0 and s is the projection of b0 onto a.
        b_point = e <= _EPS
        t = torch.where(b_point, 0.0, t)
        s = torch.where(b_point, (-c / a_s).clamp(0.0, 1.0), s)
        # a is a point: s = 0 (t was computed for s = 0 above).
        s = torch.where(a <= _EPS, 0.0, s)
    return s, t


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


def segment_distance_ends(ends: torch.Tensor) -> torch.Tensor:
    """Closest distance between segments given as stacked end points.

    Args:
        ends: ``(..., 4, 3)`` rows ``a0, a1, b0, b1`` [m].

    Returns:
        ``(...)`` distance [m] (>= 0), as :func:`segment_distance`.
    """
    s, t = _closest_st(ends)
    # p - q = (1 - s) a0 + s a1 - (1 - t) b0 - t b1: one weighted sum over the end points
    w = torch.stack([1.0 - s, s, t - 1.0, -t], -1).to(ends.dtype)  # (..., 4)
    d2 = (w[..., None] * ends).sum(-2).pow(2).sum(-1)
    # clamp keeps sqrt's gradient finite when the segments intersect
    return torch.where(d2 > _EPS, d2.clamp_min(_EPS).sqrt(), 0.0)


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

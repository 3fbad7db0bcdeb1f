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

__all__ = ["segment_distance", "closest_parameters", "capsule_distance"]

_EPS = 1e-12  # [m^2] denominators below this are treated as degenerate


def closest_parameters(a0: torch.Tensor, a1: torch.Tensor, b0: torch.Tensor, b1: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Parameters ``s, t`` in [0, 1] of the closest points ``a0 + s (a1 - a0)`` and ``b0 + t (b1 - b0)``.

    Args:
        a0, a1, b0, b1: ``(..., 3)`` segment end points (broadcastable).

    Returns:
        ``s, t``: ``(...)`` each, without gradient.
    """
    dtype = torch.promote_types(a0.dtype, b0.dtype)
    with torch.no_grad():
        # float64 here: a*e - b*b cancels badly in float32 for near-parallel segments
        a0, a1, b0, b1 = (x.detach().to(torch.float64) for x in (a0, a1, b0, b1))
        d1, d2, r = a1 - a0, b1 - b0, a0 - b0
        a = (d1 * d1).sum(-1)
        e = (d2 * d2).sum(-1)
        b = (d1 * d2).sum(-1)
        c = (d1 * r).sum(-1)
        f = (d2 * r).sum(-1)
        a_s, e_s = a.clamp_min(_EPS), e.clamp_min(_EPS)
        denom = a * e - b * b  # >= 0, 0 for parallel segments
        # Parallel (relative to the lengths): any s works; take 0.
        parallel = denom <= 1e-10 * a_s * e_s
        s = torch.where(parallel, torch.zeros_like(denom), ((b * f - c * e) / denom.clamp_min(_EPS * _EPS)).clamp(0.0, 1.0))
        s = torch.where(a <= _EPS, torch.zeros_like(s), s)
        t = (b * s + f) / e_s
        # t outside [0, 1]: clamp it and recompute s for the clamped t.
        s = torch.where(t < 0.0, (-c / a_s).clamp(0.0, 1.0), torch.where(t > 1.0, ((b - c) / a_s).clamp(0.0, 1.0), s))
        t = t.clamp(0.0, 1.0)
        # b is a point: t = 0 and s is the projection of b0 onto a.
        t = torch.where(e <= _EPS, torch.zeros_like(t), t)
        s = torch.where(e <= _EPS, (-c / a_s).clamp(0.0, 1.0), s)
        # a is a point: s = 0 (t was computed for s = 0 above).
        s = torch.where(a <= _EPS, torch.zeros_like(s), s)
    return s.to(dtype), t.to(dtype)


def segment_distance(a0: torch.Tensor, a1: torch.Tensor, b0: torch.Tensor, b1: torch.Tensor) -> torch.Tensor:
    """Closest distance between segments ``[a0, a1]`` and ``[b0, b1]``.

    Args:
        a0, a1, b0, b1: ``(..., 3)`` end points [m], broadcastable.

    Returns:
        ``(...)`` distance [m] (>= 0). Differentiable; distances below
        1e-6 m read as 0, with zero gradient (sqrt is not differentiable at 0).
    """
    s, t = closest_parameters(a0, a1, b0, b1)
    p = a0 + s[..., None] * (a1 - a0)  # (..., 3) closest point on a
    q = b0 + t[..., None] * (b1 - b0)  # (..., 3) closest point on b
    d2 = ((p - q) ** 2).sum(-1)
    # clamp keeps sqrt's gradient finite when the segments intersect
    return torch.where(d2 > _EPS, d2.clamp_min(_EPS).sqrt(), torch.zeros_like(d2))


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

"""The synthetic signer's surface: signed distances to torso, neck and head (for clearance checks).

The torso is a rounded box, the neck a capsule, the head a sphere (``BodyParams.torso_center``
& co.); frame and units of :mod:`nlo_lab.corpus.body`. Negative inside.
"""

from __future__ import annotations

import numpy as np

from nlo_lab.corpus.body import BodyParams

__all__ = ["torso_signed_distance", "head_signed_distance", "body_signed_distance", "body_gradient"]


def _norm(v: np.ndarray) -> np.ndarray:
    """Euclidean norm over the last axis (cheaper than np.linalg.norm on small arrays)."""
    return np.sqrt(np.sum(v * v, axis=-1))


def torso_signed_distance(params: BodyParams, points: np.ndarray) -> np.ndarray:
    """Signed distance [m] of ``(..., 3)`` points to the torso (rounded box); < 0 inside."""
    q = np.abs(np.asarray(points) - params.torso_center) - (params.torso_half_extents - params.torso_rounding)
    outside = _norm(np.maximum(q, 0.0))
    inside = np.minimum(np.max(q, axis=-1), 0.0)
    return outside + inside - params.torso_rounding


def head_signed_distance(params: BodyParams, points: np.ndarray) -> np.ndarray:
    """Signed distance [m] of ``(..., 3)`` points to the head sphere and neck capsule; < 0 inside."""
    p = np.asarray(points)
    head = _norm(p - params.head_center) - params.head_radius
    a, b, r = params.neck
    t = np.clip(np.sum((p - a) * (b - a), axis=-1) / np.sum((b - a) ** 2), 0.0, 1.0)
    neck = _norm(p - (a + t[..., None] * (b - a))) - r
    return np.minimum(head, neck)


def body_signed_distance(params: BodyParams, points: np.ndarray) -> np.ndarray:
    """Signed distance [m] of ``(..., 3)`` points to torso, neck and head; < 0 inside."""
    return np.minimum(torso_signed_distance(params, points), head_signed_distance(params, points))


def body_gradient(params: BodyParams, points: np.ndarray, eps: float = 1e-4) -> np.ndarray:
    """``(..., 3)`` unit outward direction of :func:`body_signed_distance` (central differences)."""
    p = np.asarray(points, dtype=np.float64)[..., None, :]
    steps = np.concatenate([np.eye(3), -np.eye(3)]) * eps  # (6, 3): one call for all six probes
    sd = body_signed_distance(params, p + steps)  # (..., 6)
    g = sd[..., :3] - sd[..., 3:]
    return g / np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-12)

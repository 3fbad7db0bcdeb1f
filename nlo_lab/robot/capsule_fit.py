"""The smallest capsule that holds a set of points: the collision proxy fitted to a link's geometry.

A capsule is a segment swept by a sphere. :func:`fit_capsule` tries the three principal
axes of the points and the three axes of their frame; for each, it centres
the axis on the smallest circle holding the points seen along the axis, then shortens the
segment from both ends (the round caps take over) and keeps the radius every point needs.
The capsule of least volume wins. Every point lies inside the result (tested), so two
capsules apart means the geometry inside them is apart.

:func:`fit_link_capsules` gives a link a few such capsules, one per geometry element, merged
where one capsule fits two and cut where a capsule fits badly (a box).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

__all__ = ["MERGE_RATIO", "CUT_RATIO", "MAX_PER_LINK", "MIN_RADIUS", "MIN_CUT_EXCESS", "fit_capsule", "capsule_volume", "Piece", "fit_link_capsules", "cuts", "halves"]

_SHRINK_STEPS = 24  # segment lengths tried per axis


def capsule_volume(p0, p1, radius: float) -> float:
    """Volume [m³] of the capsule of axis ``p0``-``p1`` and ``radius``."""
    length = float(np.linalg.norm(np.asarray(p1, dtype=np.float64) - np.asarray(p0, dtype=np.float64)))
    return float(np.pi * radius**2 * length + 4.0 / 3.0 * np.pi * radius**3)


def _circle_centre(points2d: np.ndarray) -> np.ndarray:
    """Centre of the smallest circle around 2-D points (trimesh's minimum n-sphere)."""
    # lazy: trimesh loads its mesh formats on import: only where meshes are read
    from trimesh.nsphere import minimum_nsphere

    if len(points2d) >= 4:
        try:
            centre, _ = minimum_nsphere(points2d)
            return np.asarray(centre, dtype=np.float64)
        except Exception:  # qhull refuses collinear or repeated points: the box centre below will do
            pass
    return 0.5 * (points2d.min(0) + points2d.max(0))


def _axes(points: np.ndarray) -> list[np.ndarray]:
    centred = points - points.mean(0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    axes = [vt[i] for i in range(min(3, len(vt)))]
    axes += [np.eye(3)[i] for i in range(3)]  # the link frame's own axes: links are often drawn along one
    return [a / np.linalg.norm(a) for a in axes if np.linalg.norm(a) > 1e-12]


def fit_capsule(points) -> tuple[np.ndarray, np.ndarray, float]:
    """The capsule of least volume found that holds every point.

    Args:
        points: ``(N, 3)`` points [m] (e.g. the vertices of a link's convex hull), N >= 1.

    Returns:
        ``(p0, p1, radius)``: the segment's ends and the radius [m]; radius > 0.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(pts) == 0 or not np.isfinite(pts).all():
        raise ValueError("fit_capsule needs finite points")
    best = None
    for u in _axes(pts):
        # an orthonormal basis (u, v, w): the points seen along u are (p.v, p.w)
        v = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
        v /= np.linalg.norm(v)
        w = np.cross(u, v)
        centre2 = _circle_centre(np.column_stack([pts @ v, pts @ w]))
        along = pts @ u
        lo, hi = float(along.min()), float(along.max())
        base = centre2[0] * v + centre2[1] * w
        r_cyl = float(np.linalg.norm(np.column_stack([pts @ v, pts @ w]) - centre2, axis=1).max())
        # every segment length at once: the ends pulled in by s from the points' extent along u (meeting in the middle)
        s = np.linspace(0.0, max(r_cyl, 1e-9), _SHRINK_STEPS)
        a_t, b_t = lo + s, hi - s
        a_t, b_t = np.where(a_t > b_t, 0.5 * (lo + hi), a_t), np.where(a_t > b_t, 0.5 * (lo + hi), b_t)
        # every point's distance to each segment: the segments lie along u through base, so along u it is the
        # overshoot past the nearer end, and across u the distance from the axis
        across = np.linalg.norm(pts - base - np.outer(along - base @ u, u), axis=1)
        overshoot = np.maximum(np.maximum(a_t[:, None] - along, along - b_t[:, None]), 0.0)
        r = np.maximum(np.sqrt(overshoot**2 + across**2).max(1) * (1.0 + 1e-9), 1e-6)
        vol = np.pi * r**2 * (b_t - a_t) + 4.0 / 3.0 * np.pi * r**3
        k = int(np.argmin(vol))
        if best is None or vol[k] < best[0]:
            best = (float(vol[k]), base + a_t[k] * u, base + b_t[k] * u, float(r[k]))
    _, a, b, r = best
    return a, b, r


# ------------------------------------------------------------------ capsules for a link's geometry
MERGE_RATIO = 1.3  # merge two capsules of a link when one around both is at most this much bigger ...
CUT_RATIO = 2.0  # ... and still fits: a capsule holding more than this times its geometry's volume is cut in two
MAX_PER_LINK = 6  # capsules per link at most (a torso, a base, legs need several)
MIN_RADIUS = 0.002  # [m] a point-like or flat element still gets a capsule this thick
MIN_CUT_EXCESS = 5e-5  # [m^3] a capsule is cut only when it holds this much more than its geometry (50 cm^3: not a finger)


@dataclass
class Piece:
    """A capsule and the convex hull it holds (both in one link's frame).

    Attributes:
        link: the link.
        hull: a convex ``trimesh.Trimesh``.
        p0, p1, radius: the capsule [m].
    """

    link: str
    hull: Any
    p0: np.ndarray
    p1: np.ndarray
    radius: float

    @staticmethod
    def around(link: str, hull) -> Piece:
        """The smallest capsule found around ``hull`` (:func:`fit_capsule`), at least :data:`MIN_RADIUS` thick."""
        a, b, r = fit_capsule(np.asarray(hull.vertices))
        return Piece(link, hull, a, b, max(r, MIN_RADIUS))

    @property
    def volume(self) -> float:
        return capsule_volume(self.p0, self.p1, self.radius)

    @cached_property
    def polytope(self):
        """The hull as a :class:`~nlo_lab.robot.geometry_collision.Polytope` (its face planes), worked out once: the
        draft asks for it at every thinning bound and slack of the piece (iCub: 21,000 times, 6 % of its draft)."""
        from nlo_lab.robot.geometry_collision import polytope  # here: the fit itself needs numpy alone, not torch

        return polytope(self.link, self.hull)

    @property
    def excess(self) -> float:
        """Capsule volume over the hull's (1 = a perfect fit; inf for a flat hull)."""
        hull = float(self.hull.volume) if self.hull.is_volume else 0.0
        return self.volume / hull if hull > 1e-12 else np.inf


def _merged(link: str, hulls: list) -> list[Piece]:
    """One capsule per hull, merged while one capsule around two is cheap (:data:`MERGE_RATIO`) and
    still fits (:data:`CUT_RATIO`)."""
    # lazy: trimesh loads its mesh formats on import: only where meshes are read
    import trimesh

    pieces = [Piece.around(link, h) for h in hulls]
    while len(pieces) > 1:
        best = None
        for i in range(len(pieces)):
            for j in range(i + 1, len(pieces)):
                both = trimesh.convex.convex_hull(np.concatenate([pieces[i].hull.vertices, pieces[j].hull.vertices]))
                merged = Piece.around(link, both)
                ratio = merged.volume / (pieces[i].volume + pieces[j].volume)
                if merged.excess <= CUT_RATIO and (best is None or ratio < best[0]):
                    best = (ratio, i, j, merged)
        if best is None or (best[0] > MERGE_RATIO and len(pieces) <= MAX_PER_LINK):
            break
        _, i, j, merged = best
        pieces = [p for k, p in enumerate(pieces) if k not in (i, j)] + [merged]
    return pieces


def _cut(piece: Piece, point: np.ndarray, normal: np.ndarray) -> list[Piece] | None:
    """The piece's hull cut by the plane through ``point`` square to ``normal``: a capsule round each half, or None."""
    parts = []
    for n in (normal, -normal):
        half = piece.hull.slice_plane(point, n, cap=True)
        if half is None or len(half.faces) < 4 or not half.is_volume:
            return None
        parts.append(Piece.around(piece.link, half.convex_hull))
    return parts


def cuts(piece: Piece, toward=None) -> list[list[Piece]]:
    """The piece cut in two across each principal axis of its hull, through the middle; and, given a direction
    ``toward`` (link frame: where another part sits), across it at 0.2 to 0.8 of the hull's extent (its end near
    that part gets a capsule of its own). Only cuts that leave two solid halves."""
    v = np.asarray(piece.hull.vertices, dtype=np.float64)
    planes = []
    for axis in np.linalg.svd(v - v.mean(0), full_matrices=False)[2]:
        along = v @ axis
        planes.append((0.5 * (along.min() + along.max()) * axis, axis))
    if toward is not None and np.linalg.norm(toward) > 1e-12:
        d = np.asarray(toward, dtype=np.float64) / np.linalg.norm(toward)
        along = v @ d
        planes += [((along.min() + f * (along.max() - along.min())) * d, d) for f in (0.2, 0.35, 0.5, 0.65, 0.8)]
    return [parts for point, normal in planes if (parts := _cut(piece, point, normal)) is not None]


def halves(piece: Piece) -> list[Piece] | None:
    """The :func:`cuts` of the piece that leaves the least capsule volume (None: it cannot be cut)."""
    return min(cuts(piece), key=lambda parts: sum(h.volume for h in parts), default=None)


def fit_link_capsules(link: str, hulls: list) -> list[Piece]:
    """Capsules holding the convex ``hulls`` of one link's geometry elements (link frame).

    One capsule per hull; two merged while one capsule around both is at most :data:`MERGE_RATIO`
    times their volume and fits; then the worst fitting ones cut in two across a principal axis
    while a capsule holds more than :data:`CUT_RATIO` times its hull's volume and at least
    :data:`MIN_CUT_EXCESS` more (a box is fat in a capsule; a finger's few cm^3 are not worth a cut),
    and cutting saves a tenth of its volume, up to :data:`MAX_PER_LINK`. Every hull lies inside the capsules.
    """
    pieces = _merged(link, hulls)
    while len(pieces) < MAX_PER_LINK:
        excess = {id(p): p.volume - (float(p.hull.volume) if p.hull.is_volume else 0.0) for p in pieces}
        for worst in sorted(pieces, key=lambda p: -excess[id(p)]):  # the loosest first
            if worst.excess <= CUT_RATIO or excess[id(worst)] < MIN_CUT_EXCESS:
                continue
            cut = halves(worst)
            if cut is not None and sum(h.volume for h in cut) <= 0.9 * worst.volume:
                pieces = [p for p in pieces if p is not worst] + cut
                break
        else:
            return pieces
    return pieces

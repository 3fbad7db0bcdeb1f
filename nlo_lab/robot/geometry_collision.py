"""Self-collision by the URDF's own geometry, not by the spec's capsules: the independent check.

The optimiser keeps *capsules* apart (:mod:`~nlo_lab.robot.collision`); whether the robot
really stays clear of itself is a question for the geometry its URDF declares. Each
``<collision>`` element (or ``<visual>``, with ``role="visual"``) becomes a convex
polytope: boxes exactly, cylinders and spheres tessellated within 0.2 % of their radius,
meshes by their convex hull, which holds the mesh (a hull overlap is a bound: the mesh
itself may still be clear, never the reverse).

Two elements overlap when their polytopes share interior points. A linear programme
finds the largest ball inside both (its centre ``x`` and radius ``t`` maximise ``t``
under ``n·x + t <= d`` for every face plane of both); the **overlap depth** is that
ball's diameter ``2t`` (exact for two slabs or two spheres pressed into each other).
Bounding spheres skip pairs that are far apart.

Which pairs are checked: links on two different rigid bodies (an actuated joint between
them: the pose of two links on one body never changes), not adjacent (neither body hangs
directly from the other by one joint), not already overlapping at the robot's neutral pose
(``Robot.neutral_q``), and not disabled by the robot's SRDF when its spec names one (real
robots' makers disable the pairs their coarse shapes make collide where the robot does not:
:mod:`~nlo_lab.robot.srdf`).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import torch

from nlo_lab.robot.geometry import link_shapes, shape_mesh
from nlo_lab.robot.srdf import disabled_pairs

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot.robot import Robot

__all__ = ["DEPTH_TOLERANCE", "Polytope", "polytope", "overlap_depth", "overlap_depths", "overlaps", "overlap_prefilter",
           "GeometryCollision"]

DEPTH_TOLERANCE = 1e-4  # [m] overlaps up to 0.1 mm are round-off and contact, not collision
PREFILTER_SLACK = 1e-6  # [m] the prefilter decides only this far from its thresholds; nearer, the linear programme decides
PREFILTER_POINTS = np.linspace(0.0, 1.0, 21)  # where between the two corner means the prefilter looks for a point deep in both
BOUND_GUARD = 1e-12  # [m] round-off allowed for in the prefilter's bounding-sphere bounds
LP_BATCH = 16  # linear programmes solved as one by overlap_depths
PREFILTER_CHUNK = 2_000_000  # corner-plane products per numpy batch of the prefilter (memory, not speed)
WITNESSES = 16  # corners the prefilter's plane test measures first, to leave out the planes one of them lies short of


@dataclass(frozen=True)
class Polytope:
    """A convex piece of a link's geometry, in the link frame.

    Attributes:
        link: the link.
        normals: ``(m, 3)`` unit outward face normals; offsets: ``(m,)`` with ``normals @ x <= offsets`` inside [m].
        vertices: ``(k, 3)`` the corners [m].
        centre, radius: a bounding sphere [m].
    """

    link: str
    normals: np.ndarray
    offsets: np.ndarray
    vertices: np.ndarray
    centre: np.ndarray
    radius: float


def polytope(link: str, mesh) -> Polytope:
    """The convex hull of ``mesh`` (a ``trimesh.Trimesh`` in the frame of ``link``) as a :class:`Polytope`."""
    hull = mesh.convex_hull
    normals = np.asarray(hull.face_normals, dtype=np.float64)
    offsets = np.einsum("ij,ij->i", normals, np.asarray(hull.vertices)[hull.faces[:, 0]])
    keys = np.round(np.column_stack([normals, offsets]), 9)  # coplanar triangles give one plane
    _, keep = np.unique(keys, axis=0, return_index=True)
    v = np.asarray(hull.vertices, dtype=np.float64)
    centre = 0.5 * (v.min(0) + v.max(0))
    return Polytope(link, normals[keep], offsets[keep], v, centre, float(np.linalg.norm(v - centre, axis=1).max()))


def _face_separated(a: Polytope, Ta: np.ndarray, b: Polytope, Tb: np.ndarray) -> bool:
    """True when a face plane of one polytope has the other wholly outside (a quick exact "apart"): the plane test of
    :func:`_beyond_a_face` without its slack, each polytope in the other's frame (rigid poses)."""
    for p, Tp, o, To in ((a, Ta, b, Tb), (b, Tb, a, Ta)):
        Rp_T = Tp[:3, :3].T
        R, t = Rp_T @ To[:3, :3], Rp_T @ (To[:3, 3] - Tp[:3, 3])
        if _beyond_a_face(p.normals, p.offsets, o.vertices, R @ o.centre + t, o.radius, (R, t), slack=0.0):
            return True
    return False


def _ball_programme(a: Polytope, Ta: np.ndarray, b: Polytope, Tb: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The linear programme of :func:`overlap_depth` over ``(x, t)``: rows ``(m, 4)`` and right-hand sides ``(m,)`` of
    ``n·x + t <= d`` for every face plane of both posed polytopes, and the cap on ``t``."""
    rows, rhs = [], []
    for p, T in ((a, Ta), (b, Tb)):
        n = p.normals @ T[:3, :3].T  # (m, 3) world normals
        rows.append(np.column_stack([n, np.ones(len(n))]))
        rhs.append(p.offsets + n @ T[:3, 3])
    return np.concatenate(rows), np.concatenate(rhs), min(a.radius, b.radius)


def overlap_depth(a: Polytope, Ta: np.ndarray, b: Polytope, Tb: np.ndarray) -> float:
    """Overlap depth [m] of two posed polytopes (0 when they are apart or only touch)."""
    # lazy: scipy.optimize is slow to import: only here
    from scipy.optimize import linprog

    if _face_separated(a, Ta, b, Tb):
        return 0.0
    rows, rhs, cap = _ball_programme(a, Ta, b, Tb)
    res = linprog(c=[0.0, 0.0, 0.0, -1.0], A_ub=rows, b_ub=rhs, bounds=[(None, None)] * 3 + [(None, cap)], method="highs")
    if res.status != 0:  # infeasible cannot happen (t is free below); anything else: report no overlap
        return 0.0
    return max(0.0, 2.0 * float(res.x[3]))


def overlap_depths(items: Sequence[tuple[Polytope, np.ndarray, Polytope, np.ndarray]]) -> np.ndarray:
    """``(N,)``: :func:`overlap_depth` of each posed pair ``(a, Ta, b, Tb)`` of ``items``, the linear programmes of up to
    :data:`LP_BATCH` pairs solved as one.

    The fast path of the capsule draft and of :meth:`GeometryCollision.depths`, tested equal to :func:`overlap_depth`:
    the pairs' programmes side by side (block-diagonal rows, each pair its own ``(x, t)``) with the sum of the ``t`` as
    the objective, whose optimum is each pair's own optimum since no row links two pairs. scipy's ``linprog`` spends
    most of a small programme's time before and after HiGHS runs (about 1.7 of 2.1 ms for two 45-face hulls); shared by
    16 pairs, a pair's programme costs about a third (``benchmarks/robot_init.py`` times the drafts: docs/RESULTS.md,
    "Drafting a spec")."""
    from scipy import sparse
    from scipy.optimize import linprog

    out = np.zeros(len(items))
    todo = [k for k, (a, Ta, b, Tb) in enumerate(items) if not _face_separated(a, Ta, b, Tb)]
    for start in range(0, len(todo), LP_BATCH):
        chunk = todo[start:start + LP_BATCH]
        programmes = [_ball_programme(*items[k]) for k in chunk]
        res = linprog(c=np.tile([0.0, 0.0, 0.0, -1.0], len(chunk)), A_ub=sparse.block_diag([p[0] for p in programmes], format="csr"),
                      b_ub=np.concatenate([p[1] for p in programmes]),
                      bounds=[bound for p in programmes for bound in [(None, None)] * 3 + [(None, p[2])]], method="highs")
        if res.status != 0:  # as overlap_depth would say, pair by pair
            out[chunk] = [overlap_depth(*items[k]) for k in chunk]
        else:
            out[chunk] = np.maximum(0.0, 2.0 * res.x[3::4])
    return out


def overlaps(a: Polytope, Ta: np.ndarray, b: Polytope, Tb: np.ndarray) -> bool:
    """Do two posed polytopes overlap deeper than :data:`DEPTH_TOLERANCE` (:func:`overlap_depth`)?"""
    return overlap_depth(a, Ta, b, Tb) > DEPTH_TOLERANCE


def _beyond_a_face(normals: np.ndarray, offsets: np.ndarray, points: np.ndarray, centre: np.ndarray, radius: float,
                   pose: tuple[np.ndarray, np.ndarray] | None = None, slack: float = PREFILTER_SLACK) -> bool:
    """Do all of ``points`` (``(k, 3)``; posed by ``pose = (R, t)`` into the planes' frame, if given) lie beyond one of
    the face planes ``normals (m, 3)`` (unit), ``offsets (m,)`` less :data:`DEPTH_TOLERANCE` (and ``slack``)?
    The posed points lie within ``radius`` of ``centre`` (in the planes' frame), which bounds each plane's least ``x·n``
    within ``centre·n ± radius``: a plane whose bound clears the threshold answers at once, one whose bound stays below
    it cannot; the points are posed and measured only against the planes in between (the same answer as measuring
    every plane, to round-off).

    A few corners (:data:`WITNESSES`, spread through the list) are measured first: a plane one of them lies short of
    cannot have all corners beyond it, so only the planes they all clear are measured with every corner (the same
    answer; through Talos's draft a call had 245 open planes on average and the witnesses left 22 of them)."""
    threshold = offsets - DEPTH_TOLERANCE + slack
    at_centre = normals @ centre
    if (at_centre - radius - BOUND_GUARD >= threshold).any():
        return True
    open_ = np.nonzero(at_centre + radius + BOUND_GUARD >= threshold)[0]
    if len(open_) == 0:
        return False
    def posed(p: np.ndarray) -> np.ndarray:
        return p if pose is None else p @ pose[0].T + pose[1]

    witnesses = posed(points[:: max(1, len(points) // WITNESSES)])
    open_ = open_[(witnesses @ normals[open_].T).min(0) >= threshold[open_]]
    if len(open_) == 0:
        return False
    points = posed(points)
    return bool(((points @ normals[open_].T).min(0) >= threshold[open_]).any())

def overlap_prefilter(a: Polytope, Ta: np.ndarray, b: Polytope, Tb: np.ndarray) -> np.ndarray:
    """What :func:`overlaps` says for many poses at once where a cheap test settles it: ``(S,)`` int8, -1 where the two
    polytopes posed by ``Ta (S, 4, 4)`` and ``Tb (S, 4, 4)`` surely do not overlap deeper than
    :data:`DEPTH_TOLERANCE`, +1 where they surely do, 0 where only :func:`overlap_depth`'s linear programme can tell.

    The fast path of the capsule draft (a linear programme per pose costs milliseconds; this costs microseconds), true
    by construction and tested equal to :func:`overlaps`, each test :data:`PREFILTER_SLACK` on the safe side:

    * -1: the bounding spheres are apart, or all of one polytope's corners lie beyond a face plane of the other less
      :data:`DEPTH_TOLERANCE` (the shared part then fits in a slab that thin: :func:`overlap_depth` returns 0 there,
      or at most that slab);
    * +1: a point on the segment between the two corner means (each inside its convex polytope) lies deeper than half
      the tolerance inside both (the ball the linear programme maximises is at least that big).
    """
    Ta, Tb = np.asarray(Ta, dtype=np.float64), np.asarray(Tb, dtype=np.float64)
    out = np.zeros(len(Ta), dtype=np.int8)
    if len(Ta) == 0:
        return out
    Ra_T = np.swapaxes(Ta[:, :3, :3], 1, 2)  # rigid poses: the inverse rotation is the transpose (np.linalg.inv was 60 % of a draft)
    R = Ra_T @ Tb[:, :3, :3]  # (S, 3, 3) b's frame in a's: everything below is in a's frame
    t = np.einsum("sij,sj->si", Ra_T, Tb[:, :3, 3] - Ta[:, :3, 3])
    centre_b = R @ b.centre + t
    far = np.linalg.norm(centre_b - a.centre, axis=1) > a.radius + b.radius + PREFILTER_SLACK
    out[far] = -1
    todo = np.nonzero(~far)[0]
    mean_a, mean_b = a.vertices.mean(0), b.vertices.mean(0)
    size = max(1, len(a.vertices) * len(b.normals) + len(b.vertices) * len(a.normals))
    for idx in np.array_split(todo, max(1, len(todo) * size // PREFILTER_CHUNK)):
        if len(idx) == 0:
            continue
        Ri, ti = R[idx], t[idx]
        # matrix products, not numpy's einsum (46 % of Talos's draft): the same values to round-off, far inside PREFILTER_SLACK
        normals_b = np.swapaxes(Ri @ b.normals.T, 1, 2)  # (s, m, 3) b's face planes
        offsets_b = b.offsets + (normals_b @ ti[:, :, None])[..., 0]
        apart = np.array([_beyond_a_face(a.normals, a.offsets, b.vertices, centre_b[idx[k]], b.radius, (Ri[k], ti[k]))
                          or _beyond_a_face(normals_b[k], offsets_b[k], a.vertices, a.centre, a.radius)
                          for k in range(len(idx))], dtype=bool)
        inner_b = Ri @ mean_b + ti
        points = mean_a + PREFILTER_POINTS[:, None] * (inner_b - mean_a)[:, None]  # (s, c, 3) from a's corner mean to b's
        inside_a = (a.offsets - points @ a.normals.T).min(-1)  # (s, c) distance inside a's faces
        inside_b = (offsets_b[:, None] - np.einsum("sci,smi->scm", points, normals_b)).min(-1)
        deep = np.minimum(inside_a, inside_b).max(1) > DEPTH_TOLERANCE / 2 + PREFILTER_SLACK
        out[idx[apart]] = -1
        out[idx[deep & ~apart]] = 1
    return out


class GeometryCollision:
    """The self-collision check of a robot by its URDF's geometry.

    Args:
        robot: a loaded ``nlo_lab.robot.Robot``.
        role: ``"collision"`` (default) or ``"visual"`` elements.
        disabled: link pairs not to check (default: those of the spec's SRDF, if it names one, and its
            ``shape_contacts``: collision elements that meet where the parts do not).

    Attributes:
        pieces: one :class:`Polytope` per element.
        pairs: ``(P, 2)`` indices into ``pieces`` of the element pairs checked.
        skipped: ``[(link, reason)]`` elements left out (a mesh file missing or unreadable).
    """

    def __init__(self, robot: Robot, role: str = "collision", disabled: set | None = None):
        self.robot = robot
        if disabled is None:
            srdf = getattr(robot.spec, "srdf", None)
            disabled = disabled_pairs(srdf) if srdf is not None else set()
            disabled |= {frozenset(p) for p in getattr(robot.spec, "shape_contacts", ())}
        self.disabled = disabled
        self.pieces: list[Polytope] = []
        self.skipped: list[tuple[str, str]] = []
        for shape in link_shapes(robot.model, role):
            try:
                self.pieces.append(polytope(shape.link, shape_mesh(shape)))
            except (OSError, ValueError) as exc:  # a missing or unreadable mesh: left out, and said so
                self.skipped.append((shape.link, str(exc)))
                warnings.warn(f"{robot.name}: {role} geometry of link {shape.link!r} left out of the check ({exc})", stacklevel=2)
        tree = robot.tree
        body = {n: tree.link_body[i] for i, n in enumerate(tree.link_names)}  # 0 = root body, k + 1 = moving joint k
        parent = {0: -1, **{k + 1: p + 1 for k, p in enumerate(tree.moving_parent)}}
        candidates = []
        for i, a in enumerate(self.pieces):
            for j in range(i + 1, len(self.pieces)):
                ba, bb = body[a.link], body[self.pieces[j].link]
                if ba != bb and parent[ba] != bb and parent[bb] != ba and frozenset((a.link, self.pieces[j].link)) not in disabled:
                    candidates.append((i, j))
        rest = self.depths(robot.neutral_q.detach().double().cpu().numpy()[None], np.array(candidates).reshape(-1, 2))[0]
        touching = {frozenset((self.pieces[i].link, self.pieces[j].link)) for (i, j), d in zip(candidates, rest, strict=True) if d > 0}
        self.rest_contacts = sorted(tuple(sorted(p)) for p in touching)
        self.pairs = np.array(
            [(i, j) for i, j in candidates if frozenset((self.pieces[i].link, self.pieces[j].link)) not in touching], dtype=np.int64
        ).reshape(-1, 2)

    def _poses(self, q: np.ndarray) -> np.ndarray:
        """``(T, L, 4, 4)`` float64 link poses of ``q (T, n)``."""
        with torch.no_grad():
            return self.robot.forward_kinematics_tensor(torch.as_tensor(q, dtype=torch.float64)).numpy()

    def depths(self, angles, pairs: np.ndarray | None = None) -> np.ndarray:
        """``(T, P)`` overlap depth [m] of each checked pair (or of ``pairs``) for ``(T, n)`` angles."""
        q = self.robot.check_angles(angles)
        pairs = self.pairs if pairs is None else pairs
        out = np.zeros((len(q), len(pairs)))
        if len(pairs) == 0:
            return out
        T = self._poses(q)
        index = [self.robot.link_index(p.link) for p in self.pieces]
        centres = np.stack([T[:, index[k], :3, :3] @ p.centre + T[:, index[k], :3, 3] for k, p in enumerate(self.pieces)], 1)
        radii = np.array([p.radius for p in self.pieces])
        gap = np.linalg.norm(centres[:, pairs[:, 0]] - centres[:, pairs[:, 1]], axis=-1) - radii[pairs].sum(1)  # (T, P)
        near = np.nonzero(gap < 0)
        out[near] = overlap_depths([(self.pieces[pairs[k, 0]], T[t, index[pairs[k, 0]]], self.pieces[pairs[k, 1]], T[t, index[pairs[k, 1]]])
                                    for t, k in zip(*near, strict=True)])
        return out

    def report(self, angles) -> dict:
        """``frames`` in collision (depth > :data:`DEPTH_TOLERANCE`), the ``max_depth_m`` and the ``worst`` link pair."""
        d = self.depths(angles)
        hit = d > DEPTH_TOLERANCE
        if not hit.any():
            return {"frames": 0, "max_depth_m": 0.0, "worst": None}
        t, k = np.unravel_index(np.argmax(d), d.shape)
        i, j = self.pairs[k]
        return {"frames": int(hit.any(1).sum()), "max_depth_m": float(d[t, k]), "worst": (self.pieces[i].link, self.pieces[j].link, int(t))}

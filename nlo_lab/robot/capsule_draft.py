"""A robot's collision capsules and checked pairs, drafted from its URDF's geometry.

**Capsules.** Each link's ``<collision>`` elements, else its ``<visual>`` ones, get capsules that
hold their convex hulls (:func:`~nlo_lab.robot.capsule_fit.fit_link_capsules`): every point of the
geometry lies inside a capsule, so capsules apart means geometry apart. A link fixed to a moving
body (a wrist's camera, a hand's palm) keeps its own capsules, seated on the body's first link
(the one FK poses), so that each pair of links is checked or left out on its own. A hand's
fingers also get an **envelope**: capsules on the wrist link that hold the fingers in every
pose of a random sample of finger poses; the rest of the robot meets the envelope, the
fingers meet only each other and their palm (a pair count of tens instead of hundreds per hand).

**Checked pairs.** Capsules on two different rigid bodies (an actuated joint between them)
whose bodies are not adjacent (one hanging from the other by one joint). A finger meets the other
fingers of its hand, and its palm where their geometry overlaps in one of :data:`PALM_SAMPLES` random
finger poses (YuMi's thumb closed 3 mm into the hand base while that pair was left out; its other
fingers never reach the palm, and a palm's fat capsule would only keep them from closing); the rest
of the robot meets the hand's envelope. Of those:

* pairs that never come within :data:`REACH` (or their summed radii, if smaller) of each other
  in :data:`REACH_SAMPLES` random poses within the joint limits are left out (as MoveIt's
  "never in collision");
* pairs whose link *geometry* touches at the rest pose are left out (the self-collision check
  by the URDF's geometry, :mod:`~nlo_lab.robot.geometry_collision`, leaves them out alike);
* pairs closer than their margin at rest though the geometry does not touch (a capsule is fatter
  than a box, overshoots a cylinder's flat end, holds YuMi's joint housings loosely) are tested
  against their geometry in :data:`GEOMETRY_SAMPLES` random poses of the joints between the two
  links (and the corners of those joints' limits; the rest of the robot does not move them
  relative to each other), the test that decides, since a thinned capsule no longer holds all of
  its geometry (TIAGo's fingers closed 1.4 mm into the palm past capsules thinned by 8 mm each):

  - geometry that overlaps in none of those poses: the pair is not checked (never in collision);
  - otherwise the pair is checked with **thinned** copies (named ``CAPSULE~Nmm``, thinner by N mm),
    half each (:func:`_thinning`), at most three quarters of a radius each, thinned together at
    most :func:`_thinning_bound` (less :data:`THIN_SAFETY`): the most that still lets the thinned
    capsules overlap in every sampled pose where their geometry does. Within that, ``thinning="most"``
    (the default) thins as far as it allows (the pair blocks the least motion: Talos's upper arm and
    forearm, thinned just enough to clear the margin at rest, kept its elbow from bending past 40
    degrees), ``"least"`` just enough to clear the margin at rest and :data:`INNER_CLEARANCE` (the
    bundled specs, whose checkpoints were trained with it);
  - a pair that cannot clear the margin at rest within that bound gets a **narrower margin** (what is
    left at rest), or, when it cannot even clear 0, first its capsules cut finer
    (:func:`_refine`, ``"most"`` only); a pair still *blind* after that (its capsules overlap more
    at rest than where the geometry collides: TIAGo's left thumb, whose links' shapes are 0.2 mm
    apart at rest) is thinned to clear the margin at rest as before, and the draft says so; a pair
    that needs more than the radii allow is left unchecked, and the draft says so;
  - a blind pair whose *visual* geometry overlaps in none of those poses is a **shape contact**: the
    URDF's collision elements meet where the parts they stand for do not (TIAGo's left thumb base:
    its collision mesh is mirrored across y, ``scale="1 -1 1"``, where its visual mesh and its joint
    are mirrored across z; the right thumb's same shapes, and the left's visual ones, stay apart in
    the whole range, the left's collision shapes overlap by up to 0.56 mm in 60 % of it). The draft
    names it, and the self-collision check by the geometry leaves it out, as it leaves out an SRDF's
    disabled pairs (spec ``"shape_contacts"``);
* pairs between the two arms (everything from one shoulder down against everything from the
  other) are always checked, even when they touch at rest (YuMi's zero pose crosses the
  forearms: such a robot needs a ``neutral_pose`` in its spec; the draft reports them).
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch
from tqdm.auto import tqdm

from nlo_lab.robot.capsule_fit import Piece, cuts, fit_link_capsules
from nlo_lab.robot.collision import segment_closest_points
from nlo_lab.robot.geometry import link_shapes, shape_mesh
from nlo_lab.robot.geometry_collision import DEPTH_TOLERANCE, LP_BATCH, overlap_depth, overlap_depths, overlap_prefilter, overlaps, polytope
from nlo_lab.robot.spec import CapsuleSpec

__all__ = [
    "REACH",
    "REACH_SAMPLES",
    "GEOMETRY_SAMPLES",
    "ENVELOPE_SAMPLES",
    "Arms",
    "CapsuleDraft",
    "draft_collision",
    "capsule_gaps",
]

REACH_SAMPLES = 4000  # random poses within the limits of the reach test
GEOMETRY_SAMPLES = 512  # random poses of the joints between a thinned pair's links (and their limits' corners)
THIN_SAFETY = 0.0005  # [m] a thinning stops this short of letting the sampled geometry overlap unseen
ROUNDING = 0.0003  # [m] what the radii's rounding to 0.1 mm (up, and down when thinned) may take from a gap, and some
REFINE_CUTS = 6  # a blind pair's capsules are cut in two at most this many times
PREFILTER_BATCH = 64  # poses prefiltered at a time, as a scan reaches them (Talos's meshes: thousands of corners and faces)
BOUNDARY_SEEDS = 4  # overlapping poses (and free neighbours of each) between which a thinning bound is bisected ...
BOUNDARY_STEPS = 8  # ... in this many halvings
REACH = 0.05  # [m] a pair whose capsules never come this close (nor closer than their radii) in those poses is not checked
ENVELOPE_SAMPLES = 64  # random finger poses (and open, closed, rest) a hand's envelope holds
PALM_SAMPLES = 256  # random finger poses (and open, closed) in which a finger may meet its own palm's geometry
INNER_CLEARANCE = 0.0005  # [m] thinned capsules of a pair clear each other at rest by the margin and this ...
INNER_MAX_THIN = 0.75  # ... taking at most this fraction of a radius
THIN_STEP = 0.001  # [m] thinnings are multiples of this, so that pairs share thinned copies
ENVELOPE = "#fingers"  # key suffix of a hand's envelope


@dataclass(frozen=True)
class Arms:
    """The arms as the pair rules need them.

    Attributes:
        links: side -> every link from that shoulder down (arm and hand).
        wrists: side -> the wrist link.
    """

    links: dict[str, set[str]]
    wrists: dict[str, str]


@dataclass(frozen=True)
class CapsuleDraft:
    """What :func:`draft_collision` decided.

    Attributes:
        capsules: the capsules (named ``LINK``, ``LINK_1``, ``LINK_2`` ... on a link with several,
            ``WRIST_fingers`` for a hand's envelope, ``CAPSULE~Nmm`` for copies thinner by N mm).
        pairs: the checked pairs (capsule names).
        touching: link pairs whose geometry touches at the rest pose: not checked.
        arms_touching: capsule pairs between the two arms that touch at rest (checked anyway).
        unchecked: link pairs whose capsules touch at rest though their geometry does not, and whose
            capsules would need thinning by more than half a radius (not checked; a warning says so).
        thinned: pairs checked with thinned copies of their capsules.
        far: capsule pairs left out because they never came within :data:`REACH`.
        apart: capsule pairs near at rest left out because the geometry they hold never overlaps in
            :data:`GEOMETRY_SAMPLES` poses of the joints between them.
        margins: checked pairs whose margin is narrower than the default (thinning that would clear it
            at rest would let their geometry overlap unseen): pair -> its margin d_min [m].
        blind: link pairs thinned to clear the margin at rest although the geometry they hold overlaps in a
            sampled pose where the thinned capsules do not (capsules this loose cannot tell the two apart).
        shape_contacts: blind link pairs whose visual geometry overlaps in none of those poses: their collision
            elements meet where the parts do not (not in ``blind``; the spec's ``"shape_contacts"``).
    """

    capsules: list[CapsuleSpec]
    pairs: list[tuple[str, str]]
    touching: list[tuple[str, str]] = field(default_factory=list)
    arms_touching: list[tuple[str, str]] = field(default_factory=list)
    unchecked: list[tuple[str, str]] = field(default_factory=list)
    thinned: int = 0
    far: int = 0
    apart: int = 0
    margins: dict[tuple[str, str], float] = field(default_factory=dict)
    blind: list[tuple[str, str]] = field(default_factory=list)
    shape_contacts: list[tuple[str, str]] = field(default_factory=list)


def _link_hulls(model) -> dict[str, list]:
    """Link -> the convex hull (link frame) of each geometry element: collision, else visual."""
    found: dict[str, dict[str, list]] = {"collision": {}, "visual": {}}
    for role in ("collision", "visual"):
        for shape in link_shapes(model, role):
            if role == "visual" and shape.link in found["collision"]:
                continue  # the link has collision geometry: its visuals are not used
            try:
                mesh = shape_mesh(shape)
            except FileNotFoundError as exc:
                warnings.warn(f"link {shape.link!r}: {role} mesh {exc.filename} is missing; no capsule from it", stacklevel=3)
                continue
            found[role].setdefault(shape.link, []).append(mesh.convex_hull)
    merged = {**found["visual"], **found["collision"]}
    return {link: merged[link] for link in getattr(model, "model", model).links if link in merged}


def _body_hulls(model, tree) -> tuple[dict[str, list], dict[str, str]]:
    """Link -> the hulls of its geometry in the frame of the link its capsules sit on (the seat), and
    link -> seat: a link fixed to a moving body sits on the body's first link (the child of its moving
    joint: the only link of the body FK poses); the links of the body that does not move (torso, head,
    legs and base) on themselves. Each link keeps its own capsules, so that a pair of links is checked
    or not on its own (TIAGo's hand: a safety box around the fingertips at rest, its palm clear of them)."""
    first = {}
    for i, link in enumerate(tree.link_names):
        if np.allclose(tree.link_const[i], np.eye(4)) and tree.link_body[i] not in first:
            first[tree.link_body[i]] = link
    out: dict[str, list] = {}
    seat: dict[str, str] = {}
    for link, hulls in _link_hulls(model).items():
        i = tree.link_index[link]
        seat[link] = link if tree.link_body[i] == 0 else first[tree.link_body[i]]
        T = tree.link_const[i] if seat[link] != link else np.eye(4)  # T_seat_link, constant
        out[link] = [h.copy().apply_transform(T) for h in hulls]
    return out, seat


def capsule_gaps(capsules, poses: dict[str, np.ndarray], pairs: list[tuple[int, int]]) -> np.ndarray:
    """Surface distance [m] of capsule pairs (indices into ``capsules``: anything with link, p0, p1,
    radius) at link poses ``{link: (4, 4)}``; < 0: overlap."""
    if not pairs:
        return np.zeros(0)
    ends = np.zeros((4, 3, len(pairs)))
    for k, (i, j) in enumerate(pairs):
        for row, c in ((0, capsules[i]), (2, capsules[j])):
            T = poses[c.link]
            ends[row, :, k] = T[:3, :3] @ np.asarray(c.p0) + T[:3, 3]
            ends[row + 1, :, k] = T[:3, :3] @ np.asarray(c.p1) + T[:3, 3]
    dist = segment_closest_points(ends)[3]
    return dist - np.array([capsules[i].radius + capsules[j].radius for i, j in pairs])


def _random_poses(rest_q, lower, upper, count: int, seed: int, joints=None) -> np.ndarray:
    """``(count, n)`` poses: ``joints`` (default all) uniform within the limits, the others at rest."""
    gen = np.random.default_rng(seed)
    q = np.repeat(np.asarray(rest_q, dtype=np.float64)[None], count, 0)
    idx = np.arange(q.shape[1]) if joints is None else np.asarray(joints, dtype=np.int64)
    lo, hi = np.asarray(lower, dtype=np.float64)[idx], np.asarray(upper, dtype=np.float64)[idx]
    q[:, idx] = lo + (hi - lo) * gen.random((count, len(idx)))
    return q


def _hands(tree, arms: Arms) -> dict[str, tuple[str, str]]:
    """Link -> (side, ``"palm"`` or ``"finger"``) for every link at or below a wrist."""
    body = {n: tree.link_body[i] for i, n in enumerate(tree.link_names)}
    parent = {j.child: j.parent for j in tree.model.joints}
    out = {}
    for side, wrist in arms.wrists.items():
        for link in arms.links[side]:
            up = link
            while up is not None and up != wrist:
                up = parent.get(up)
            if up == wrist:
                out[link] = (side, "palm" if body[link] == body[wrist] else "finger")
    return out


def _envelope(tree, hulls: dict, wrist: str, fingers: dict[str, str], rest_q, lower, upper, seed: int) -> list[Piece]:
    """Capsules on the wrist link holding the fingers' geometry in :data:`ENVELOPE_SAMPLES` random finger
    poses, all open, all closed and the rest pose."""
    # lazy: trimesh loads its mesh formats on import: only where meshes are read
    import trimesh

    joints = [i for i, name in enumerate(tree.actuated) if tree.model.joint(name).child in set(fingers.values())]
    q = _random_poses(rest_q, lower, upper, ENVELOPE_SAMPLES + 3, seed, joints)
    q[0] = rest_q
    q[1, joints], q[2, joints] = np.asarray(lower)[joints], np.asarray(upper)[joints]
    with torch.no_grad():
        T = tree.forward(torch.as_tensor(q)).numpy()  # (S, L, 4, 4)
    inv_wrist = np.linalg.inv(T[:, tree.link_index[wrist]])
    points = []
    for link, seat in fingers.items():  # finger link -> the link its hulls are in
        rel = inv_wrist @ T[:, tree.link_index[seat]]  # (S, 4, 4) T_wrist_seat
        for hull in hulls[link]:
            v = np.asarray(hull.vertices)
            points.append((np.einsum("sij,kj->ski", rel[:, :3, :3], v) + rel[:, None, :3, 3]).reshape(-1, 3))
    return fit_link_capsules(wrist, [trimesh.convex.convex_hull(np.concatenate(points))])


def _palm_reached(tree, hulls: dict, keys: dict[str, str], pairs: list[tuple[str, str]], hand: dict, rest_q, lower, upper,
                  seed: int, prefilter: bool = True) -> set[tuple[str, str]]:
    """The finger-palm ``pairs`` (group keys, one hand) whose geometry overlaps in :data:`PALM_SAMPLES` random
    poses of the hands' joints (and all open, all closed): the others never meet. ``prefilter``: as in
    :func:`_thinning_bound`."""
    if not pairs:
        return set()
    joints = [i for i, name in enumerate(tree.actuated) if hand.get(tree.model.joint(name).child, (None, ""))[1] == "finger"]
    q = _random_poses(rest_q, lower, upper, PALM_SAMPLES + 2, seed, joints)
    q[0, joints], q[1, joints] = np.asarray(lower)[joints], np.asarray(upper)[joints]
    with torch.no_grad():
        T = tree.forward(torch.as_tensor(q)).numpy()  # (S, L, 4, 4)
    found = set()
    for a, b in pairs:
        la, lb = keys[a], keys[b]
        ia, ib = tree.link_index[la], tree.link_index[lb]
        shapes = [(polytope(la, u), polytope(lb, v)) for u in hulls.get(a, []) for v in hulls.get(b, [])]
        if any(overlap() for pa, pb in shapes for overlap in _overlapping(pa, ia, pb, ib, prefilter)(T)):
            found.add((a, b))
    return found


def _key_pairs(tree, keys: dict[str, str], hand: dict[str, tuple[str, str]]) -> list[tuple[str, str]]:
    """Pairs of piece groups that may collide (``keys``: group -> the link its capsules sit on)."""
    body = {n: tree.link_body[i] for i, n in enumerate(tree.link_names)}
    parent = {0: -1, **{k + 1: p + 1 for k, p in enumerate(tree.moving_parent)}}

    def role(key: str) -> tuple[str | None, str]:
        return (hand[keys[key]][0], "envelope") if key.endswith(ENVELOPE) else hand.get(key, (None, "other"))

    out = []
    names = list(keys)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            ba, bb = body[keys[a]], body[keys[b]]
            if ba == bb or parent[ba] == bb or parent[bb] == ba:
                continue
            (sa, ra), (sb, rb) = role(a), role(b)
            if "finger" in (ra, rb) and not (sa == sb and {ra, rb} <= {"finger", "palm"}):
                continue  # a finger meets its own hand (fingers, palm); the rest of the robot meets the envelope
            if "envelope" in (ra, rb) and sa == sb:
                continue
            out.append((a, b))
    return out


def _reach(tree, flat: list[Piece], pairs: list[tuple[int, int]], q: np.ndarray) -> np.ndarray:
    """``(P,)`` the smallest capsule gap of each pair over the poses ``q (S, n)`` [m]."""
    index = [tree.link_index[p.link] for p in flat]
    ends = np.array([[p.p0, p.p1] for p in flat])  # (C, 2, 3) in link frames
    radii = np.array([p.radius for p in flat])
    pa = np.array(pairs, dtype=np.int64).reshape(-1, 2)
    best = np.full(len(pa), np.inf)
    for chunk in np.array_split(q, max(1, len(q) // 250)):
        with torch.no_grad():
            T = tree.forward(torch.as_tensor(chunk)).numpy()[:, index]  # (B, C, 4, 4)
        world = np.einsum("bcij,ckj->bcki", T[..., :3, :3], ends) + T[:, :, None, :3, 3]  # (B, C, 2, 3)
        E = np.concatenate([world[:, pa[:, 0]], world[:, pa[:, 1]]], axis=2)  # (B, P, 4, 3)
        dist = segment_closest_points(np.ascontiguousarray(E.reshape(-1, 4, 3).transpose(1, 2, 0)))[3]
        best = np.minimum(best, (dist.reshape(len(chunk), -1) - radii[pa].sum(1)).min(0))
    return best


def _thinning(a: Piece, b: Piece, rest_gap: float, margin: float) -> tuple[float, float] | None:
    """How much to thin each capsule of a pair that sits closer than its margin at rest though the
    geometry does not touch: together just enough to clear each other by the margin and
    :data:`INNER_CLEARANCE` (so the collision term is silent at rest), on the :data:`THIN_STEP`
    grid, half each (a thinned capsule leaves its geometry out by up to its thinning: the least
    thinning, halved, leaves the least out on either side; NAO's torso thinned alone by 12 mm let
    its box's corners 1 mm into the upper arms), at most :data:`INNER_MAX_THIN` of a radius, the other taking what one
    cannot; None when that is not enough."""
    need = max(0.0, margin + INNER_CLEARANCE - rest_gap)
    half = float(np.ceil(need / 2 / THIN_STEP - 1e-9) * THIN_STEP)
    most = {id(c): float(np.floor(INNER_MAX_THIN * c.radius / THIN_STEP) * THIN_STEP) for c in (a, b)}
    first = min(half, most[id(a)])
    second = max(half, float(np.ceil(max(0.0, need - first) / THIN_STEP - 1e-9) * THIN_STEP))
    if second > most[id(b)]:
        first = min(most[id(a)], float(np.ceil(max(0.0, need - most[id(b)]) / THIN_STEP - 1e-9) * THIN_STEP))
        second = most[id(b)]
        if first + second < need - 1e-9:
            return None
    return first, second


def _path_joints(tree, la: str, lb: str) -> tuple[int, ...]:
    """The actuated joints (indices into ``q``) that move link ``lb`` relative to link ``la``: the moving
    joints between their bodies (for a mimic joint, its source)."""

    def up(body: int) -> list[int]:  # the body and its ancestors, the root body (0) left out
        out = []
        while body > 0:
            out.append(body)
            body = tree.moving_parent[body - 1] + 1
        return out

    a, b = up(tree.link_body[tree.link_index[la]]), up(tree.link_body[tree.link_index[lb]])
    common = set(a) & set(b)
    return tuple(sorted({tree.moving_source[k - 1] for k in a + b if k not in common}))


def _path_poses(tree, joints: tuple[int, ...], rest_q, lower, upper, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``(q (S, n), T (S, L, 4, 4))``: :data:`GEOMETRY_SAMPLES` random poses of ``joints`` (the others at rest)
    and every corner of their limits (collisions often sit at a limit: an elbow bent all the way), with the
    link poses."""
    q = _random_poses(rest_q, lower, upper, GEOMETRY_SAMPLES, seed, joints)
    idx = list(joints)
    if len(idx) <= 6:
        corners = np.repeat(np.asarray(rest_q, dtype=np.float64)[None], 2 ** len(idx), 0)
        for c in range(len(corners)):
            corners[c, idx] = [(upper if (c >> k) & 1 else lower)[i] for k, i in enumerate(idx)]
        q = np.concatenate([q, corners])
    with torch.no_grad():
        return q, tree.forward(torch.as_tensor(q)).numpy()


def _pair_gaps(T: np.ndarray, ia: int, a: Piece, ib: int, b: Piece) -> np.ndarray:
    """``(S,)`` surface distance [m] of capsules ``a`` (on link ``ia``) and ``b`` in the link poses ``T (S, L, 4, 4)``."""
    ends = np.stack([np.einsum("sij,kj->ski", T[:, i, :3, :3], np.array([p.p0, p.p1])) + T[:, i, None, :3, 3]
                     for i, p in ((ia, a), (ib, b))], 1).reshape(len(T), 4, 3)  # (S, 4, 3): a's ends, b's ends
    return segment_closest_points(np.ascontiguousarray(ends.transpose(1, 2, 0)))[3] - a.radius - b.radius


def _thinning_bound(tree, sample: tuple[np.ndarray, np.ndarray], a: Piece, b: Piece, prefilter: bool = True,
                    below: float = -np.inf) -> float:
    """The most thinning [m], summed over both capsules, that still lets capsules ``a`` and ``b`` overlap wherever
    the geometry they hold overlaps (deeper than ``DEPTH_TOLERANCE``), in the poses ``sample = (q, T)``
    (:func:`_path_poses`) and on the way out of the overlap from the :data:`BOUNDARY_SEEDS` overlapping
    poses where the capsules overlap least toward their nearest poses without overlap
    (:data:`BOUNDARY_STEPS` halvings: the overlap's edge, where capsules overlap least, falls between
    samples; NAO's torso and upper arm overlapped 1.7 mm past a bound that only the samples set);
    ``inf`` when the geometry overlaps in none. Thinned further, the collision term would let that
    geometry into each other unseen (TIAGo's fingers closed 1.4 mm into the palm past capsules thinned
    by 16 mm). ``prefilter``: settle the poses a cheap test can (:func:`_overlapping`; the same answer). ``below``: the
    caller only needs to know whether the bound is below this: the search stops once it is (the bound only falls as
    it goes on), returning a value below ``below`` that the bound does not exceed."""
    q, T = sample
    ia, ib = tree.link_index[a.link], tree.link_index[b.link]
    overlapping = _overlapping(a.polytope, ia, b.polytope, ib, prefilter)
    gaps = _pair_gaps(T, ia, a, ib, b)
    free = gaps >= 0  # the capsules hold the geometry: apart capsules, apart geometry
    hit: list[int] = []
    order = np.argsort(-gaps)  # the largest capsule gap first: where thinning lets the geometry in first
    order = order[gaps[order] < 0]
    for s, overlap in zip(order, overlapping(T[order]), strict=True):
        if overlap():
            hit.append(int(s))
            if len(hit) == BOUNDARY_SEEDS or -float(gaps[hit[0]]) < below:
                break
        else:
            free[s] = True
    if not hit:
        return float("inf")
    best = float(gaps[hit[0]])  # the largest capsule gap where the geometry overlaps
    known = np.nonzero(free)[0]
    if len(known) and -best >= below:
        span = np.where(np.ptp(q, 0) > 0, np.ptp(q, 0), 1.0)
        inside, outside = [], []  # the ends of each way out: overlapping, free
        for s in hit:
            near = known[np.argsort(np.abs((q[known] - q[s]) / span).sum(1))[:BOUNDARY_SEEDS]]
            inside += [q[s]] * len(near)
            outside += [q[n] for n in near]
        lo, hi = np.array(inside), np.array(outside)
        for _ in range(BOUNDARY_STEPS):
            if -best < below:
                break
            mid = 0.5 * (lo + hi)
            with torch.no_grad():
                Tm = tree.forward(torch.as_tensor(mid)).numpy()
            gm = _pair_gaps(Tm, ia, a, ib, b)
            near = np.nonzero(gm < 0)[0]  # where the capsules are apart, so is the geometry
            out = np.ones(len(mid), dtype=bool)
            for k, overlap in zip(near, overlapping(Tm[near]), strict=True):
                if overlap():
                    lo[k] = mid[k]
                    best = max(best, float(gm[k]))
                    out[k] = False
            hi[out] = mid[out]
    return -best


def _overlapping(pa, ia: int, pb, ib: int, prefilter: bool) -> Callable[[np.ndarray], list[Callable[[], bool]]]:
    """``overlapping(T (S, L, 4, 4))`` -> for each pose, a call that says whether polytopes ``pa`` (on link index ``ia``)
    and ``pb`` overlap deeper than ``DEPTH_TOLERANCE`` (:func:`~nlo_lab.robot.geometry_collision.overlaps`, a linear
    programme), asked lazily (a scan stops at its first hits). With ``prefilter``, the poses a cheap vectorised test settles
    (:func:`~nlo_lab.robot.geometry_collision.overlap_prefilter`, true by construction) skip the programme, and the
    programme of a pose asked is solved with those of the next unsettled poses, up to ``LP_BATCH`` in all, as one
    (:func:`~nlo_lab.robot.geometry_collision.overlap_depths`): the same answers."""

    def overlapping(T: np.ndarray) -> list[Callable[[], bool]]:
        known = np.zeros(len(T), dtype=np.int8)
        done = np.zeros(-(-len(T) // PREFILTER_BATCH), dtype=bool)  # the batches prefiltered so far (a scan stops early)

        def overlap(s: int) -> bool:
            c = s // PREFILTER_BATCH
            if prefilter and not done[c]:
                batch = slice(c * PREFILTER_BATCH, (c + 1) * PREFILTER_BATCH)
                known[batch], done[c] = overlap_prefilter(pa, T[batch, ia], pb, T[batch, ib]), True
            if prefilter and known[s] == 0:  # this pose's programme with those of the next unsettled ones, as one
                ahead = [k for k in range(s, min(len(T), (c + 1) * PREFILTER_BATCH)) if known[k] == 0][:LP_BATCH]
                depths = overlap_depths([(pa, T[k, ia], pb, T[k, ib]) for k in ahead])
                known[ahead] = np.where(depths > DEPTH_TOLERANCE, 1, -1)
            return bool(known[s] > 0) or (known[s] == 0 and overlaps(pa, T[s, ia], pb, T[s, ib]))

        return [(lambda s=s: overlap(s)) for s in range(len(T))]

    return overlapping


def _allowed(bound: float) -> float:
    """The thinning [m] (both capsules together, on the :data:`THIN_STEP` grid) a pair may have given its
    :func:`_thinning_bound`: :data:`THIN_SAFETY` short of it."""
    return float(np.floor((bound - THIN_SAFETY) / THIN_STEP + 1e-9) * THIN_STEP)


def _split(a: Piece, b: Piece, total: float) -> tuple[float, float] | None:
    """``total`` thinning [m] (on the :data:`THIN_STEP` grid) split between capsules ``a`` and ``b``: half each (``a``
    the larger half), at most :data:`INNER_MAX_THIN` of a radius each, the other taking what one cannot; None
    when that is not enough."""
    most = [float(np.floor(INNER_MAX_THIN * c.radius / THIN_STEP) * THIN_STEP) for c in (a, b)]
    first = min(float(np.ceil(total / 2 / THIN_STEP - 1e-9) * THIN_STEP), most[0])
    second = total - first
    if second > most[1] + 1e-9:
        first, second = total - most[1], most[1]
    return (first, second) if first <= most[0] + 1e-9 and min(first, second) >= -1e-9 else None


def _rest_slack(tree, a: Piece, b: Piece, poses: dict, sample: tuple[np.ndarray, np.ndarray], margin: float, prefilter: bool = True,
                bar: float = -np.inf) -> float:
    """For capsules ``a`` and ``b`` near at rest (``poses``): how far apart at rest they stay, less the clearance,
    when thinned as far as the geometry they hold allows in the poses ``sample`` (:func:`_thinning_bound`); < 0 for
    a *blind* pair (the capsules cannot tell the rest pose from a collision); ``inf`` for a pair that is not
    near at rest, touches at rest or never meets. ``bar``: the caller only needs to know whether the slack exceeds it;
    a value at or below ``bar`` may then be returned early (the slack is no more than that)."""
    gap = float(capsule_gaps([a, b], poses, [(0, 1)])[0])
    if gap > margin + INNER_CLEARANCE:
        return float("inf")
    if overlap_depth(a.polytope, poses[a.link], b.polytope, poses[b.link]) > DEPTH_TOLERANCE:
        return float("inf")
    # slack <= bar once _allowed(bound) <= bar - gap + ROUNDING: surely once bound < bar - gap + ROUNDING + THIN_SAFETY
    # (_allowed(x) <= x - THIN_SAFETY, to 1e-12 m), less 1e-9 m for that rounding
    below = bar - gap + ROUNDING + THIN_SAFETY - 1e-9
    return gap + _allowed(_thinning_bound(tree, sample, a, b, prefilter, below)) - ROUNDING


def _rest_slack_cap(tree, a: Piece, b: Piece, poses: dict, sample: tuple[np.ndarray, np.ndarray], margin: float) -> float:
    """An upper bound of :func:`_rest_slack` for the cost of one vectorised test: the sampled poses where the
    prefilter finds the geometry surely overlapping bound the thinning (:func:`_thinning_bound` takes the largest
    capsule gap of an overlapping pose, and only raises it); ``inf`` where that says nothing."""
    gap = float(capsule_gaps([a, b], poses, [(0, 1)])[0])
    if gap > margin + INNER_CLEARANCE:
        return float("inf")
    pa, pb = a.polytope, b.polytope
    ia, ib = tree.link_index[a.link], tree.link_index[b.link]
    at_rest = overlap_prefilter(pa, poses[a.link][None], pb, poses[b.link][None])[0]
    if at_rest > 0 or (at_rest == 0 and overlaps(pa, poses[a.link], pb, poses[b.link])):
        return float("inf")  # touching at rest
    T = sample[1]
    gaps = _pair_gaps(T, ia, a, ib, b)
    near = np.argsort(-gaps)
    near = near[gaps[near] < 0][:PREFILTER_BATCH]  # the poses the scan meets first: enough to bound (any would do)
    deep = near[overlap_prefilter(pa, T[near, ia], pb, T[near, ib]) > 0] if len(near) else near
    return gap + _allowed(-float(gaps[deep].max())) - ROUNDING if len(deep) else float("inf")


def _toward(a: Piece, b: Piece, poses: dict) -> np.ndarray:
    """The direction from capsule ``a``'s middle to ``b``'s at rest, in ``a``'s link frame."""
    Ta, Tb = poses[a.link], poses[b.link]
    mid_b = Tb[:3, :3] @ (0.5 * (np.asarray(b.p0) + np.asarray(b.p1))) + Tb[:3, 3]
    return Ta[:3, :3].T @ (mid_b - Ta[:3, 3]) - 0.5 * (np.asarray(a.p0) + np.asarray(a.p1))


def _counted(items, done: Callable[[], object]):
    """``items`` one by one, calling ``done()`` after each (a progress bar's update: once the item's work is done)."""
    for item in items:
        yield item
        done()


def _refine(tree, pieces: dict[str, list[Piece]], key_pairs, side_of: dict, poses: dict, path_poses, margin: float,
            prefilter: bool = True, done: Callable[[], object] = lambda: None) -> None:
    """Cut in two (:func:`~nlo_lab.robot.capsule_fit.cuts`: across the principal axes, or across the direction to the
    other capsule) the capsules of *blind* pairs, in place: the piece of the pair, or both, with the cut whose
    halves leave the most room at rest, while that helps, up to :data:`REFINE_CUTS` times
    per pair (TIAGo's finger: a 13 mm ball round its first phalanx overlapped the palm's at rest by more than
    the finger can close into the palm; two 9 mm capsules do not). A pair's slack is worked out once (a piece pair
    keeps it while neither is cut); a cut stops being weighed at its first pair no better than the best so far, and
    that pair's search stops as soon as it cannot be better (the same choice as weighing every pair to the end).
    """
    known: dict[tuple[int, int, bool], tuple[Piece, Piece, float, bool]] = {}  # (id, id, cap?) -> the pieces (kept alive),
    # their slack (or an upper bound of it: cap, or a search stopped at a bar) and whether it is the slack itself

    def rest_slack(x: Piece, y: Piece, sample, cap: bool = False, bar: float = -np.inf) -> float:
        """The pair's slack (:func:`_rest_slack`), or a value at or below ``bar`` when the slack is; with ``cap`` an upper
        bound of it (:func:`_rest_slack_cap`)."""
        key = (id(x), id(y), cap)
        if cap and key not in known:
            known[key] = (x, y, _rest_slack_cap(tree, x, y, poses, sample, margin), False)
        elif not cap and (key not in known or (not known[key][3] and known[key][2] > bar)):
            value = _rest_slack(tree, x, y, poses, sample, margin, prefilter, bar if prefilter else -np.inf)
            known[key] = (x, y, value, value > bar or not prefilter)  # above the bar: the search ran to its end
        return known[key][2]

    for ga, gb in _counted(key_pairs, done):
        if ENVELOPE in ga + gb or _between_arms(side_of, ga, gb):
            continue
        sample = None
        for _ in range(REFINE_CUTS):
            worst = None
            for u, pa in enumerate(pieces[ga]):
                for v, pb in enumerate(pieces[gb]):
                    if capsule_gaps([pa, pb], poses, [(0, 1)])[0] > margin + INNER_CLEARANCE:
                        continue
                    sample = path_poses(pa.link, pb.link) if sample is None else sample
                    slack = rest_slack(pa, pb, sample)
                    if slack < 0 and (worst is None or slack < worst[0]):
                        worst = (slack, u, v)
            if worst is None:
                break
            slack, u, v = worst
            best = None
            pa, pb = pieces[ga][u], pieces[gb][v]
            for na, nb in itertools.product([[pa], *cuts(pa, _toward(pa, pb, poses))], [[pb], *cuts(pb, _toward(pb, pa, poses))]):
                if len(na) + len(nb) == 2:
                    continue  # no cut
                bar = slack if best is None else max(slack, best[0])  # what the cut must beat
                if prefilter and any(rest_slack(x, y, sample, cap=True) <= bar for x in na for y in nb):
                    continue  # a pair no better than the bar, by the cheap bound: the same verdict as below
                after = float("inf")  # the least slack of the cut's pairs ...
                for value in (rest_slack(x, y, sample, bar=bar) for x in na for y in nb):
                    after = min(after, value)
                    if after <= bar:
                        break  # ... no better than the bar already: the rest of its pairs need not be weighed
                if after > bar:
                    best = (after, na, nb)
            if best is None:
                break  # cutting does not help: the pair stays blind
            pieces[ga] = pieces[ga][:u] + best[1] + pieces[ga][u + 1:]
            pieces[gb] = pieces[gb][:v] + best[2] + pieces[gb][v + 1:]


def _visual_apart(model, tree, la: str, lb: str, sample: tuple[np.ndarray, np.ndarray], prefilter: bool) -> bool:
    """Does the *visual* geometry of links ``la`` and ``lb`` (each in its own frame) overlap in none of the poses ``sample``
    (:func:`_path_poses`)? False when either link has no visual geometry (nothing to tell by)."""
    T = sample[1]
    shapes: dict[str, list] = {la: [], lb: []}
    for shape in link_shapes(model, "visual"):
        if shape.link in shapes:
            try:
                shapes[shape.link].append(polytope(shape.link, shape_mesh(shape)))
            except FileNotFoundError:
                return False
    if not shapes[la] or not shapes[lb]:
        return False
    ia, ib = tree.link_index[la], tree.link_index[lb]
    return not any(overlap() for pa in shapes[la] for pb in shapes[lb] for overlap in _overlapping(pa, ia, pb, ib, prefilter)(T))


def _between_arms(side_of: dict, a: str, b: str) -> bool:
    """Are groups ``a`` and ``b`` on different arms?"""
    return None not in (side_of.get(a), side_of.get(b)) and side_of[a] != side_of[b]


def _names(pieces: dict[str, list[Piece]]) -> list[CapsuleSpec]:
    out = []
    for key, items in pieces.items():
        stem = key.replace(ENVELOPE, "_fingers")
        for k, p in enumerate(items):
            name = stem if len(items) == 1 else f"{stem}_{k + 1}"
            out.append(CapsuleSpec(name, p.link, tuple(float(x) + 0.0 for x in np.round(p.p0, 5)),
                                   tuple(float(x) + 0.0 for x in np.round(p.p1, 5)), float(np.ceil(p.radius * 1e4) / 1e4)))
    return out


def draft_collision(model, tree, rest_q, lower, upper, arms: Arms, margin: float, samples: int = REACH_SAMPLES, seed: int = 0,
                    disabled: set | frozenset = frozenset(), thinning: str = "most",
                    fit: Callable[[str, str, list], list[Piece]] | None = None, prefilter: bool = True,
                    progress: bool = False) -> CapsuleDraft:
    """Capsules and checked pairs of a robot (see the module docstring).

    Args:
        model: the parsed :class:`~nlo_lab.robot.urdf.URDFModel` (its geometry).
        tree: the robot's :class:`~nlo_lab.robot.kinematics.KinematicTree` (bodies and FK).
        rest_q, lower, upper: ``(n,)`` the rest pose and the joint limits [rad].
        arms: the arms' links and wrists (:class:`Arms`).
        margin: the collision margin d_min [m] the spec will give the pairs.
        samples: random poses of the reach test (0: no reach test); seed: their generator's seed.
        disabled: link pairs an SRDF disables; two groups of capsules are not paired when every
            link pair between them is disabled.
        thinning: ``"most"`` (default): a pair near at rest is thinned as far as its sampled geometry allows
            (it blocks the least motion: Talos's elbow); ``"least"``: just enough to clear the margin at rest
            (the bundled specs, whose checkpoints were trained with it).
        fit: ``fit(link, seat, hulls)`` -> the capsules (on ``seat``) holding a link's geometry
            ``hulls``; default :func:`~nlo_lab.robot.capsule_fit.fit_link_capsules` on every link
            (a bundled robot's generator may fit some links more tightly: ``assets/robots/fit_capsules.py``).
        prefilter: settle by a cheap vectorised test the sampled poses where it can tell whether two links' geometry
            overlaps, and run the linear programme (:func:`~nlo_lab.robot.geometry_collision.overlap_depth`) only on
            the rest (the fast path, on by default: the same draft, tested equal; iCub's draft took 6 minutes without).
        progress: show a tqdm progress bar: the key pairs weighed for cuts (``thinning="most"``), then the capsule
            pairs checked (the two steps that take a large robot's draft its time).
    """
    if thinning not in ("most", "least"):
        raise ValueError(f"thinning must be 'most' or 'least', not {thinning!r}")
    rest_q = np.asarray(rest_q, dtype=np.float64)
    hulls, seat = _body_hulls(model, tree)
    pieces = {link: fit(link, seat[link], items) if fit is not None else fit_link_capsules(seat[link], items)
              for link, items in hulls.items()}
    keys = dict(seat)  # group -> the link its capsules sit on
    hand = _hands(tree, arms)
    for side, wrist in arms.wrists.items():
        fingers = {link: seat[link] for link in hulls if hand.get(link) == (side, "finger")}
        if fingers:
            pieces[wrist + ENVELOPE] = _envelope(tree, hulls, wrist, fingers, rest_q, lower, upper, seed)
            keys[wrist + ENVELOPE] = wrist
    side_of = {link: side for side, links in arms.links.items() for link in links}
    side_of.update({key: side_of.get(link) for key, link in keys.items()})
    members = {key: {keys[key] if key.endswith(ENVELOPE) else key} for key in keys}  # the links whose geometry a group holds
    key_pairs = [(a, b) for a, b in _key_pairs(tree, keys, hand)
                 if not all(frozenset((x, y)) in disabled for x in members[a] for y in members[b])]  # the SRDF says never
    palm = [(a, b) for a, b in key_pairs if {hand.get(a, (None, ""))[1], hand.get(b, (None, ""))[1]} == {"finger", "palm"}]
    reached = _palm_reached(tree, hulls, keys, palm, hand, rest_q, lower, upper, seed, prefilter)
    key_pairs = [p for p in key_pairs if p not in palm or p in reached]
    with torch.no_grad():
        T = tree.forward(torch.as_tensor(rest_q))
    poses = {n: T[i].numpy() for i, n in enumerate(tree.link_names)}
    sampled: dict[tuple[int, ...], tuple[np.ndarray, np.ndarray]] = {}  # path joints -> (q, link poses)

    def path_poses(la: str, lb: str) -> tuple[np.ndarray, np.ndarray]:
        joints = _path_joints(tree, la, lb)
        if joints not in sampled:
            sampled[joints] = _path_poses(tree, joints, rest_q, lower, upper, seed)
        return sampled[joints]

    bar = tqdm(total=len(key_pairs), desc="weighing capsule pairs", unit="pair", disable=not progress, leave=False)
    if thinning == "most":
        _refine(tree, pieces, key_pairs, side_of, poses, path_poses, margin, prefilter, bar.update)
    capsules = _names(pieces)
    flat = [p for key in pieces for p in pieces[key]]
    group = [key for key in pieces for _ in pieces[key]]
    start = {key: group.index(key) for key in pieces}
    pairs = [(start[a] + u, start[b] + v) for a, b in key_pairs for u in range(len(pieces[a])) for v in range(len(pieces[b]))]
    gaps = capsule_gaps(flat, poses, pairs)
    reach = _reach(tree, flat, pairs, _random_poses(rest_q, lower, upper, samples, seed)) if samples else np.full(len(pairs), -np.inf)
    touching = set()  # link pairs whose geometry touches at rest (an envelope counts as touching)
    for (i, j), gap in zip(pairs, gaps, strict=True):
        ga, gb, la, lb = group[i], group[j], flat[i].link, flat[j].link
        if gap <= 0 and (ga, gb) not in touching and not _between_arms(side_of, ga, gb):
            if ENVELOPE in ga + gb or any(
                overlap_depth(polytope(la, u), poses[la], polytope(lb, v), poses[lb]) > DEPTH_TOLERANCE
                for u in hulls.get(ga, []) for v in hulls.get(gb, [])
            ):
                touching.add((ga, gb))
    checked, arms_touching, unchecked, inner = [], [], set(), {}
    far, thinned, apart = 0, 0, 0
    margins: dict[tuple[str, str], float] = {}
    blind: set[tuple[str, str]] = set()
    bar.reset(total=len(pairs))
    bar.set_description("checking capsule pairs")
    for (i, j), gap, near in zip(pairs, gaps, reach, strict=True):
        bar.update()
        a, b = capsules[i], capsules[j]
        arms = _between_arms(side_of, group[i], group[j])
        reach_of = min(REACH, a.radius + b.radius)  # small parts (fingers) need to come closer to count
        if (group[i], group[j]) in touching or near > reach_of:
            far += near > reach_of
            continue
        if arms or gap > margin + INNER_CLEARANCE:
            checked.append((a.name, b.name))
            if gap <= 0:
                arms_touching.append(checked[-1])
            continue
        bound = _thinning_bound(tree, path_poses(flat[i].link, flat[j].link), flat[i], flat[j], prefilter)
        if bound == float("inf"):
            apart += 1  # their geometry overlaps in no pose of the joints between them: never in collision
            continue
        allowed = _allowed(bound)
        need = margin + INNER_CLEARANCE - gap  # clears the margin at rest
        pair_margin = margin
        if need <= allowed and thinning == "least":
            thin = _thinning(flat[i], flat[j], gap, margin)
        elif need <= allowed:  # "most": as far as the geometry allows (and the radii), so the pair blocks the least
            most = sum(float(np.floor(INNER_MAX_THIN * c.radius / THIN_STEP) * THIN_STEP) for c in (flat[i], flat[j]))
            thin = _split(flat[i], flat[j], max(float(np.ceil(need / THIN_STEP - 1e-9) * THIN_STEP), min(allowed, most)))
        elif gap + allowed - ROUNDING >= 0:  # clearing the margin would hide a collision: thin only so far,
            thin = _split(flat[i], flat[j], allowed)  # and narrow the pair's margin to what is left at rest
            if thin is not None:
                pair_margin = max(0.0, float(np.floor((gap + sum(thin) - ROUNDING) * 1e4) / 1e4))
        else:  # not even touching at rest: these capsules cannot tell the rest pose from a collision
            thin = _thinning(flat[i], flat[j], gap, margin)
            if thin is not None:
                blind.add((group[i], group[j]))
        if thin is None:
            unchecked.add((group[i], group[j]))
            continue
        names = []
        for c, t in zip((a, b), thin, strict=True):
            if t < 5e-4:
                names.append(c.name)
                continue
            copy = CapsuleSpec(f"{c.name}~{round(t * 1000)}mm", c.link, c.p0, c.p1, float(np.floor((c.radius - t) * 1e4) / 1e4))
            inner.setdefault(copy.name, copy)
            names.append(copy.name)
        checked.append(tuple(names))
        thinned += 1
        if pair_margin < margin:
            margins[checked[-1]] = pair_margin
    bar.close()
    if unchecked:
        warnings.warn(f"capsules of {len(unchecked)} link pairs touch at the rest pose though their geometry does not; "
                      f"those pairs are not checked: {sorted(unchecked)}", stacklevel=2)
    contacts = {p for p in blind if ENVELOPE not in p[0] + p[1] and _visual_apart(model, tree, *p, path_poses(keys[p[0]], keys[p[1]]), prefilter)}
    return CapsuleDraft(capsules + list(inner.values()), checked, sorted(touching), arms_touching, sorted(unchecked), thinned, far,
                        apart, margins, sorted(blind - contacts), sorted(contacts))

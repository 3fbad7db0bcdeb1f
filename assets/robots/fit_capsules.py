"""Fit a bundled robot's collision capsules and checked pairs to its URDF's collision geometry.

    .venv/bin/python assets/robots/fit_capsules.py [yumi nao pepper]

Rewrites ``capsules``, ``collision_pairs`` and ``collision_margin`` of ``NAME.json`` with
``nlo_lab.robot.capsule_draft.draft_collision`` (what ``nlo-lab robot init`` does for any URDF):
capsules that hold every ``<collision>`` element, pairs that can collide, thinned copies where
fat capsules would block what the geometry allows. The margin's ``default`` is kept. The rest
pose is the spec's ``neutral_pose`` (YuMi's zero pose crosses the forearms).

The fingers of one hand (:func:`one_hand`, YuMi's Inspire hands):

* pairs between two of the four fingers are dropped: each flexes in its own plane, parallel to
  the others', by one actuated joint, so their geometry never meets (the check by the URDF's
  geometry, ``nlo_lab.robot.geometry_collision``: no overlap in 3000 random hand poses; their
  capsules never came within 9 mm) and the pairs only cost time;
* pairs of the thumb with a finger (or with itself) get the margin :data:`THUMB_MARGIN` (1 mm):
  touching is what a pinch is (sign handshapes need it), so the 5 mm default held the thumb off
  the fingers; penetrating must still cost (the geometry can overlap by 15 mm: the thumb closes
  through the index finger), and with margin 0 the optimum of a pinch sat just inside contact
  (-0.1 mm, a self-collision frame by ``nlo_lab.metrics.self_collision_frames``).

The body and the arm links (:func:`tight_capsules`, YuMi's own fit; the hands keep the generic one):

* each geometry element gets its own capsule (an arm link's joint housing and its tube are not
  merged into one capsule around both: that one was 17-22 mm fatter than the tube);
* a box is tiled with capsules along its longest edge, over a grid of cells at most
  :data:`BOX_CELL` wide (one capsule around a box is fat: the shoulder block's reached 60 mm past
  its ends, into the shoulders, the torso's 100 mm above its top; their pairs with the upper arms
  were within their margin in 34 % of a grid of shoulder poses where the geometry overlapped in 3 %,
  and held the arms off the targets of Table I and of the round trip).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from nlo_lab.robot import load_robot
from nlo_lab.robot.capsule_draft import Arms, draft_collision
from nlo_lab.robot.capsule_fit import Piece, fit_link_capsules
from nlo_lab.robot.spec import spec_text

HERE = Path(__file__).resolve().parent
THUMB_MARGIN = 0.001  # [m] d_min of a thumb against the fingers of its own hand (module docstring)
BOX_CELL = 0.09  # [m] a box's capsules each hold a cell of its cross-section at most this wide (module docstring)
YUMI_THINNING = "most"
TIGHT_LINKS = ("yumi_body", "yumi_link_")  # the links :func:`tight_capsules` fits (prefixes): body and arms


def _box(hull) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(centre, axes (3, 3) rows, sizes (3,))`` of a hull that is a box (8 corners, 3 face directions), else None."""
    v = np.asarray(hull.vertices, dtype=np.float64)
    if len(v) != 8:
        return None
    axes: list[np.ndarray] = []
    for n in np.asarray(hull.face_normals, dtype=np.float64):
        if not any(abs(float(n @ a)) > 1 - 1e-9 for a in axes):
            axes.append(n)
    if len(axes) != 3:
        return None
    A = np.array(axes)
    along = v @ A.T  # (8, 3)
    lo, hi = along.min(0), along.max(0)
    return A.T @ (0.5 * (lo + hi)), A, hi - lo


def box_capsules(seat: str, hull, cell: float = BOX_CELL) -> list[Piece]:
    """Capsules along a box's longest edge, one per cell of a grid over its cross-section (cells at most
    ``cell`` wide); each capsule's segment runs from end face to end face, its radius reaches the cell's
    corners, so the capsules hold the box."""
    # lazy: trimesh loads its mesh formats on import: only where meshes are read
    import trimesh

    centre, axes, sizes = _box(hull)
    k = np.argsort(-sizes)  # longest first
    u, (a, b) = axes[k[0]], (axes[k[1]], axes[k[2]])
    n = [int(np.ceil(sizes[k[i]] / cell - 1e-9)) for i in (1, 2)]
    c = [sizes[k[i]] / n[i - 1] for i in (1, 2)]
    radius = 0.5 * float(np.hypot(*c)) * (1.0 + 1e-9)
    out = []
    for i in range(n[0]):
        for j in range(n[1]):
            mid = centre + ((i + 0.5) * c[0] - 0.5 * sizes[k[1]]) * a + ((j + 0.5) * c[1] - 0.5 * sizes[k[2]]) * b
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = np.column_stack([u, a, np.cross(u, a)]), mid
            cell_box = trimesh.creation.box(extents=(sizes[k[0]], c[0], c[1]), transform=T)
            out.append(Piece(seat, cell_box, mid - 0.5 * sizes[k[0]] * u, mid + 0.5 * sizes[k[0]] * u, radius))
    return out


def tight_capsules(link: str, seat: str, hulls: list) -> list[Piece]:
    """YuMi's capsules of one link (the module docstring): for the body and the arm links one capsule per
    geometry element, boxes tiled (:func:`box_capsules`); the hands' links the generic fit."""
    if not link.startswith(TIGHT_LINKS):
        return fit_link_capsules(seat, hulls)
    return [p for hull in hulls for p in (box_capsules(seat, hull) if _box(hull) is not None else [Piece.around(seat, hull)])]


def fit(name: str) -> dict:
    """The new collision fields of robot ``name`` (its spec as it is now gives the arms and the rest pose)."""
    path = HERE / f"{name}.json"
    robot = load_robot(path)
    arms = Arms({s: set(robot.model.subtree(robot.arm(s).shoulder)) for s in ("left", "right")},
                {s: robot.arm(s).wrist for s in ("left", "right")})
    default = json.loads(path.read_text(encoding="utf-8"))["collision_margin"]["default"]
    draft = draft_collision(robot.model, robot.tree, robot.neutral_q.double().numpy(),
                            robot.lower_limits.double().numpy(), robot.upper_limits.double().numpy(), arms, default,
                            thinning="least",  # the shipped checkpoints were trained with the least thinning
                            fit=tight_capsules if name == "yumi" else None)
    print(f"{name}: {len(draft.capsules)} capsules, {len(draft.pairs)} pairs ({draft.thinned} thinned, "
          f"{draft.far} never near, {len(draft.touching)} link pairs touching at rest)")
    capsules = [{"name": c.name, "link": c.link, "p0": list(c.p0), "p1": list(c.p1), "radius": c.radius} for c in draft.capsules]
    pairs, contact = one_hand(robot, capsules, [list(p) for p in draft.pairs])
    used = {n for p in pairs for n in p}
    capsules = [c for c in capsules if "~" not in c["name"] or c["name"] in used]  # thinned copies of dropped pairs
    if contact:
        print(f"{name}: one hand's fingers: {len(draft.pairs) - len(pairs)} finger-finger pairs dropped, {len(contact)} thumb pairs at {THUMB_MARGIN} m")
    return {
        "capsules": capsules,
        "collision_pairs": pairs,
        "collision_margin": {"default": default, **{f"{a}/{b}": m for (a, b), m in draft.margins.items() if [a, b] in pairs},
                             **{f"{a}/{b}": THUMB_MARGIN for a, b in contact}},
    }


def one_hand(robot, capsules: list[dict], pairs: list[list[str]]) -> tuple[list[list[str]], list[list[str]]]:
    """The checked pairs without those between two fingers of one hand, and the thumb's pairs (:data:`THUMB_MARGIN`)."""
    link_of = {c["name"]: c["link"] for c in capsules}
    fingers: dict[str, set] = {}  # link -> the (side, finger)s whose tip hangs below it
    for side in robot.spec.arms:
        for finger, (_, tip) in robot.arm(side).fingers.items():
            for link in robot.model.links:
                if tip in robot.model.subtree(link):
                    fingers.setdefault(link, set()).add((side, finger))
    kept, contact = [], []
    for a, b in pairs:
        fa, fb = fingers.get(link_of[a], set()), fingers.get(link_of[b], set())
        if len(fa) != 1 or len(fb) != 1 or next(iter(fa))[0] != next(iter(fb))[0]:
            kept.append([a, b])  # not two links of one hand's fingers (the palm and the arm hold all five)
        elif ("thumb" in {f for _, f in fa | fb}):
            kept.append([a, b])
            contact.append([a, b])
        # else: two of the four fingers: dropped
    return kept, contact


def update(name: str) -> None:
    path = HERE / f"{name}.json"
    spec = json.loads(path.read_text(encoding="utf-8"))
    spec.update(fit(name))
    path.write_text(spec_text(spec), encoding="utf-8")


if __name__ == "__main__":
    for robot_name in sys.argv[1:] or ["yumi", "nao", "pepper"]:
        update(robot_name)

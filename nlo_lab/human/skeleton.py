"""The human skeleton graph and its per-frame node and edge features (the encoder's input).

Nodes (:data:`NODE_NAMES`, 27): ``torso``, then per side (left, right)
``{side}_shoulder``, ``{side}_elbow``, ``{side}_wrist`` and per finger
(thumb..pinky) ``{side}_{finger}_base``, ``{side}_{finger}_tip``.

Edges (:data:`EDGES`, 26), parent -> child: torso -> shoulder -> elbow -> wrist ->
finger base -> finger tip, per side.

Node features, ``F = 13`` per node (:data:`NODE_FEATURES`):

- ``[0:3]`` position: arm nodes relative to the same-side shoulder, finger nodes
  relative to the same-side wrist; divided by that side's arm length (median
  upper arm + forearm of the demonstration); the torso is 0.
- ``[3:12]`` the wrist orientation ``R_body_wrist`` flattened row-major, on the wrist
  nodes only (zeros elsewhere, and zeros where the orientation is missing: a zero
  matrix is never a rotation, so it is unambiguous).
- ``[12]`` validity: 1 where the node's position is observed (torso always 1).

Masked points contribute zero features with validity 0: this is an encoder input,
where a zero with a flag is fine (the Demonstration itself keeps NaN).
"""

from __future__ import annotations

import numpy as np
import torch

from nlo_lab.errors import DemonstrationError
from nlo_lab.graph import NODE_ARM, NODE_HAND, Graph
from nlo_lab.human.demonstration import ARM_JOINTS, FINGERS, SIDES, Demonstration

__all__ = [
    "NODE_NAMES",
    "EDGES",
    "NODE_FEATURES",
    "NOMINAL_ARM_LENGTH",
    "skeleton_graph",
    "node_features",
    "edge_features",
]

NODE_FEATURES = 13  # position 3 + wrist rotation 9 + validity 1

NODE_NAMES: tuple[str, ...] = ("torso",) + tuple(
    name
    for side in SIDES
    for name in (
        tuple(f"{side}_{j}" for j in ARM_JOINTS)
        + tuple(f"{side}_{f}_{p}" for f in FINGERS for p in ("base", "tip"))
    )
)
_INDEX = {name: i for i, name in enumerate(NODE_NAMES)}


def _edges() -> tuple[tuple[str, str], ...]:
    edges = []
    for side in SIDES:
        edges += [("torso", f"{side}_shoulder"), (f"{side}_shoulder", f"{side}_elbow"), (f"{side}_elbow", f"{side}_wrist")]
        for f in FINGERS:
            edges += [(f"{side}_wrist", f"{side}_{f}_base"), (f"{side}_{f}_base", f"{side}_{f}_tip")]
    return tuple(edges)


EDGES: tuple[tuple[str, str], ...] = _edges()

# Nominal adult at rest (arms hanging, palms facing the thighs), body frame [m].
# Shoulder half-width 0.18, upper arm 0.20, forearm 0.24 (the paper's
# demonstrator, in its data set); hand: metacarpals ~0.09 (thumb 0.05), fingers 0.05-0.09.
NOMINAL_ARM_LENGTH = 0.44  # [m] upper arm + forearm
_REST_FINGERS = {  # finger -> (base offset from the wrist, tip offset from the base) for the left hand
    "thumb": ((0.03, 0.0, -0.04), (0.04, 0.0, -0.03)),
    "index": ((0.02, 0.0, -0.09), (0.0, 0.0, -0.09)),
    "middle": ((0.0, 0.0, -0.09), (0.0, 0.0, -0.10)),
    "ring": ((-0.02, 0.0, -0.085), (0.0, 0.0, -0.09)),
    "pinky": ((-0.035, 0.0, -0.075), (0.0, 0.0, -0.07)),
}


def _rest_offset(parent: str, child: str) -> np.ndarray:
    sign = 1.0 if child.startswith("left") else -1.0  # mirror the right side across the XZ plane
    joint = child.split("_", 1)[1]
    if joint == "shoulder":
        v = (0.0, 0.18, 0.0)
    elif joint == "elbow":
        v = (0.0, 0.0, -0.20)
    elif joint == "wrist":
        v = (0.0, 0.0, -0.24)
    else:
        finger, point = joint.split("_")
        base, tip = _REST_FINGERS[finger]
        v = base if point == "base" else tip
    return np.array([v[0], sign * v[1], v[2]])


def skeleton_graph() -> Graph:
    """The static human skeleton graph.

    Returns:
        :class:`nlo_lab.graph.Graph` with :data:`NODE_NAMES`, ``edge_index`` ``(2, 26)``
        parent -> child, ``node_type`` arm (torso, shoulders, elbows, wrists) / hand
        (finger nodes), ``edge_attr`` ``(26, 3)`` float32: the rest bone offsets of a
        nominal human divided by its arm length (:data:`NOMINAL_ARM_LENGTH`), i.e. on the
        same scale as :func:`edge_features`.
    """
    edge_index = torch.tensor([[_INDEX[p] for p, _ in EDGES], [_INDEX[c] for _, c in EDGES]], dtype=torch.long)
    attr = np.stack([_rest_offset(p, c) for p, c in EDGES]) / NOMINAL_ARM_LENGTH  # (E, 3)
    node_type = torch.tensor(
        [NODE_HAND if any(f"_{f}_" in n for f in FINGERS) else NODE_ARM for n in NODE_NAMES], dtype=torch.long
    )
    return Graph(NODE_NAMES, edge_index, torch.tensor(attr, dtype=torch.float32), node_type)


def _arm_length(demo: Demonstration, side: str) -> float:
    try:
        upper, fore = demo.arm_lengths(side)
    except DemonstrationError:
        return NOMINAL_ARM_LENGTH  # the arm is never observed: all its features are masked anyway
    length = upper + fore
    if not length > 0:
        raise DemonstrationError(f"the {side} arm has zero length", field=f"{side}/arm")
    return length


def _positions(demo: Demonstration) -> tuple[np.ndarray, np.ndarray]:
    """All node positions in the body frame ``(T, N, 3)`` (NaN where masked) and validity ``(T, N)``."""
    T = len(demo)
    pos = np.zeros((T, len(NODE_NAMES), 3))
    valid = np.ones((T, len(NODE_NAMES)), dtype=bool)
    for s, side in enumerate(SIDES):
        for j, joint in enumerate(ARM_JOINTS):
            i = _INDEX[f"{side}_{joint}"]
            pos[:, i], valid[:, i] = demo.arm_positions[:, s, j], demo.arm_mask[:, s, j]
        for f, finger in enumerate(FINGERS):
            for p, point in enumerate(("base", "tip")):
                i = _INDEX[f"{side}_{finger}_{point}"]
                pos[:, i], valid[:, i] = demo.finger_positions[:, s, f, p], demo.finger_mask[:, s, f]
    return pos, valid


def node_features(demo: Demonstration) -> np.ndarray:
    """Per-frame node features of :func:`skeleton_graph` (see the module docstring).

    Args:
        demo: the demonstration.

    Returns:
        ``(T, 27, 13)`` float32.
    """
    pos, valid = _positions(demo)
    T = len(demo)
    feats = np.zeros((T, len(NODE_NAMES), NODE_FEATURES))
    feats[:, _INDEX["torso"], 12] = 1.0
    for s, side in enumerate(SIDES):
        length = _arm_length(demo, side)
        shoulder = _INDEX[f"{side}_shoulder"]
        wrist = _INDEX[f"{side}_wrist"]
        for name, i in _INDEX.items():
            if not name.startswith(side + "_"):
                continue
            ref = wrist if i > wrist else shoulder  # finger nodes follow the wrist in NODE_NAMES
            ok = valid[:, i] & valid[:, ref]
            rel = (pos[:, i] - pos[:, ref]) / length
            feats[:, i, :3] = np.where(ok[:, None], rel, 0.0)
            feats[:, i, 12] = ok
        rot_ok = demo.wrist_mask[:, s]
        feats[:, wrist, 3:12] = np.where(rot_ok[:, None], demo.wrist_rotations[:, s].reshape(T, 9), 0.0)
    return feats.astype(np.float32)


def edge_features(demo: Demonstration) -> np.ndarray:
    """Per-frame bone offsets ``child - parent`` divided by that side's arm length.

    Args:
        demo: the demonstration.

    Returns:
        ``(T, 26, 3)`` float32, 0 where either end of the bone is missing.
    """
    pos, valid = _positions(demo)
    out = np.zeros((len(demo), len(EDGES), 3))
    lengths = {side: _arm_length(demo, side) for side in SIDES}
    for e, (parent, child) in enumerate(EDGES):
        p, c = _INDEX[parent], _INDEX[child]
        ok = valid[:, p] & valid[:, c]
        length = lengths[child.split("_", 1)[0]]
        out[:, e] = np.where(ok[:, None], (pos[:, c] - pos[:, p]) / length, 0.0)
    return out.astype(np.float32)

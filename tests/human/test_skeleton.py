"""The human skeleton graph and its node / edge features."""

from __future__ import annotations

import numpy as np
import torch

from nlo_lab.graph import NODE_ARM, NODE_HAND
from nlo_lab.human import NODE_NAMES, edge_features, node_features, skeleton_graph
from nlo_lab.human.skeleton import EDGES, NODE_FEATURES


def test_graph_structure():
    g = skeleton_graph()
    assert g.num_nodes == len(NODE_NAMES) == 27
    assert g.num_edges == len(EDGES) == 26
    assert NODE_NAMES[0] == "torso"
    names = list(NODE_NAMES)
    # every node but the torso has exactly one parent; the torso none (a tree rooted at the torso)
    children = g.edge_index[1].tolist()
    assert sorted(children) == list(range(1, 27))
    # chain torso -> shoulder -> elbow -> wrist -> base -> tip, per side
    edges = {(names[p], names[c]) for p, c in g.edge_index.t().tolist()}
    for side in ("left", "right"):
        assert ("torso", f"{side}_shoulder") in edges
        assert (f"{side}_shoulder", f"{side}_elbow") in edges
        assert (f"{side}_elbow", f"{side}_wrist") in edges
        assert (f"{side}_wrist", f"{side}_index_base") in edges
        assert (f"{side}_index_base", f"{side}_index_tip") in edges
    types = dict(zip(names, g.node_type.tolist(), strict=True))
    assert types["torso"] == types["left_wrist"] == types["right_elbow"] == NODE_ARM
    assert types["left_thumb_tip"] == types["right_pinky_base"] == NODE_HAND
    assert g.edge_attr.shape == (26, 3) and g.edge_attr.dtype == torch.float32
    # nominal rest pose: left shoulder at +Y, right at -Y, upper arm hanging down, 0.20 / 0.44 long
    attr = dict(zip([(names[p], names[c]) for p, c in g.edge_index.t().tolist()], g.edge_attr.numpy(), strict=True))
    assert attr[("torso", "left_shoulder")][1] > 0 > attr[("torso", "right_shoulder")][1]
    np.testing.assert_allclose(attr[("left_shoulder", "left_elbow")], [0, 0, -0.20 / 0.44], atol=1e-6)


def test_node_features_values(make_demo):
    demo = make_demo()
    f = node_features(demo)
    T = len(demo)
    assert f.shape == (T, 27, NODE_FEATURES) and f.dtype == np.float32
    i = {n: k for k, n in enumerate(NODE_NAMES)}
    for side in ("left", "right"):
        L = sum(demo.arm_lengths(side))
        S = demo.position(side, "shoulder")
        np.testing.assert_allclose(f[:, i[f"{side}_elbow"], :3], (demo.position(side, "elbow") - S) / L, atol=1e-6)
        np.testing.assert_allclose(f[:, i[f"{side}_shoulder"], :3], 0.0)
        W = demo.position(side, "wrist")
        np.testing.assert_allclose(f[:, i[f"{side}_ring_tip"], :3], (demo.fingers(side)[:, 3, 1] - W) / L, atol=1e-6)
        np.testing.assert_allclose(f[:, i[f"{side}_wrist"], 3:12], demo.wrist_rotation(side).reshape(T, 9), atol=1e-6)
        assert np.all(f[:, i[f"{side}_elbow"], 3:12] == 0)
    assert np.all(f[..., 12] == 1)
    np.testing.assert_allclose(f[:, i["torso"], :12], 0.0)


def test_features_of_masked_points_are_zero_with_flag_zero(make_demo):
    demo = make_demo()
    demo.arm_mask[2, 1, 1] = False  # right elbow missing in frame 2
    demo.finger_mask[4, 0, 0] = False  # left thumb missing in frame 4
    demo.wrist_mask[6, 0] = False
    demo.validate()
    f = node_features(demo)
    e = edge_features(demo)
    i = {n: k for k, n in enumerate(NODE_NAMES)}
    assert np.isfinite(f).all() and np.isfinite(e).all()
    assert f[2, i["right_elbow"], 12] == 0 and np.all(f[2, i["right_elbow"], :3] == 0)
    assert f[4, i["left_thumb_tip"], 12] == 0 and f[4, i["left_index_tip"], 12] == 1
    assert np.all(f[6, i["left_wrist"], 3:12] == 0) and f[6, i["left_wrist"], 12] == 1
    edges = {pc: k for k, pc in enumerate(EDGES)}
    assert np.all(e[2, edges[("right_shoulder", "right_elbow")]] == 0)
    assert np.all(e[2, edges[("right_elbow", "right_wrist")]] == 0)
    assert np.any(e[3, edges[("right_elbow", "right_wrist")]] != 0)


def test_edge_features_are_normalised_offsets(make_demo):
    demo = make_demo()
    e = edge_features(demo)
    assert e.shape == (len(demo), 26, 3) and e.dtype == np.float32
    k = EDGES.index(("left_elbow", "left_wrist"))
    L = sum(demo.arm_lengths("left"))
    np.testing.assert_allclose(e[:, k], (demo.position("left", "wrist") - demo.position("left", "elbow")) / L, atol=1e-6)
    k = EDGES.index(("torso", "right_shoulder"))
    np.testing.assert_allclose(e[:, k], demo.position("right", "shoulder") / sum(demo.arm_lengths("right")), atol=1e-6)
    # scale-free: a demonstrator twice as large gives the same features
    big = make_demo()
    big.arm_positions *= 2
    big.finger_positions *= 2
    np.testing.assert_allclose(edge_features(big), e, atol=1e-6)
    np.testing.assert_allclose(node_features(big), node_features(demo), atol=1e-6)

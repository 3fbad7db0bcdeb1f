"""plot_graph draws a graph as a tree, also the robot graphs, whose two arm roots point at each other."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest

from nlo_lab.human import NODE_NAMES, skeleton_graph
from nlo_lab.lab import graph_layout, plot_graph


def _depth_steps(lay) -> set[float]:
    return {float(lay.pos[c, 0] - lay.pos[p, 0]) for p, c in lay.tree}


@pytest.mark.parametrize("name", ["yumi", "nao", "pepper"])
def test_a_robot_graph_is_drawn_as_a_rooted_tree(robots, name):
    robot = robots[name]
    edges = robot.graph.edge_index.numpy()
    lay = graph_layout(robot.graph.num_nodes, edges)
    # the two arm roots: the pair joined both ways, set aside from the tree, below a drawn base
    assert len(lay.both_ways) == 1
    a, b = lay.both_ways[0]
    assert sorted(lay.roots) == sorted((a, b)) and lay.base is not None
    assert 0 in (a, b)  # the first joint of the first arm
    # every other edge is a tree edge one level down; every node has its own place
    assert len(lay.tree) == edges.shape[1] - 2 and lay.other == []
    assert _depth_steps(lay) == {1.0}
    assert len({tuple(p) for p in lay.pos}) == robot.graph.num_nodes


def test_the_human_graph_has_one_root_and_no_base():
    g = skeleton_graph()
    lay = graph_layout(g.num_nodes, g.edge_index.numpy())
    assert lay.roots == [NODE_NAMES.index("torso")] and lay.base is None and lay.both_ways == []
    assert len({tuple(p) for p in lay.pos}) == g.num_nodes


def test_a_cycle_of_one_way_edges_still_gets_a_root():
    edges = np.array([[0, 1, 2, 2], [1, 2, 0, 3]])  # 0 -> 1 -> 2 -> 0, and 2 -> 3
    lay = graph_layout(4, edges)
    assert lay.roots == [0] and lay.other == [(2, 0)]
    assert len({tuple(p) for p in lay.pos}) == 4 and _depth_steps(lay) == {1.0}


def test_the_drawing_puts_each_node_apart_and_names_the_base(robots):
    robot = robots["yumi"]
    fig, ax = plot_graph(robot.graph, robot.joint_names, title="YuMi", base="torso")
    offsets = np.concatenate([c.get_offsets() for c in ax.collections])  # the nodes and the base square
    assert len(offsets) == robot.graph.num_nodes + 1
    assert len({tuple(np.round(o, 6)) for o in offsets}) == len(offsets)
    texts = [t.get_text() for t in ax.texts]
    assert "torso" in texts and "joint_1_l" in texts  # the shared prefix "yumi_" is left out of the labels
    assert any("'yumi_'" in t for t in texts)
    plt.close(fig)

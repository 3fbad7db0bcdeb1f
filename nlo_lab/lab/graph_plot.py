"""A graph drawn as a tree: the robot structure graph and the human skeleton graph (notebooks 01, 02).

:func:`plot_graph` draws with matplotlib; :func:`graph_layout` decides where. The robot graph has no
root: its two arms' first joints are joined by an edge in each direction. The drawing sets such a pair
aside (a dashed bracket) and hangs the roots from a virtual base node; the graph itself is not changed.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["GraphLayout", "graph_layout", "plot_graph"]


@dataclass
class GraphLayout:
    """Where :func:`plot_graph` draws a graph's nodes, and which edges it draws how.

    Attributes:
        pos: ``(n, 2)`` node positions ``(depth, row)``: depth grows from the roots to the leaves, each leaf
            has a row of its own and a parent sits at the mean row of its children.
        tree: ``[(parent, child)]`` edges drawn as the tree (each node has at most one parent).
        both_ways: ``[(a, b)]`` pairs of nodes joined by an edge in each direction (drawn once, dashed).
        other: ``[(source, target)]`` the remaining edges (a second parent, or an edge closing a cycle).
        roots: the nodes nearest the top of the tree.
        base: ``(depth, row)`` of the virtual base node drawn before several roots (not a node of the graph),
            or None.
    """

    pos: np.ndarray
    tree: list[tuple[int, int]]
    both_ways: list[tuple[int, int]]
    other: list[tuple[int, int]]
    roots: list[int]
    base: tuple[float, float] | None


def graph_layout(n: int, edges, base: bool = True) -> GraphLayout:
    """A tree drawing of a directed graph of ``n`` nodes with ``(2, E)`` ``edges`` (source, target).

    A graph need not be a tree: the robot structure graph joins its two arm roots by one edge
    in each direction, so no node lacks a parent. Such pairs are set aside (``both_ways``); each
    remaining node keeps its first parent; a node that no root reaches (a cycle) becomes a root.
    With several roots and ``base``, a virtual base node is placed before them (depth 0).
    """
    pairs = [(int(a), int(b)) for a, b in np.asarray(edges).reshape(2, -1).T]
    present = set(pairs)
    both_ways = sorted({(min(a, b), max(a, b)) for a, b in pairs if a != b and (b, a) in present})
    mutual = {e for pair in both_ways for e in (pair, pair[::-1])}
    parent: dict[int, int] = {}
    tree, other = [], []
    for a, b in pairs:
        if (a, b) in mutual:
            continue
        if b in parent or a == b:
            other.append((a, b))
        else:
            parent[b] = a
            tree.append((a, b))
    children: dict[int, list[int]] = {i: [] for i in range(n)}
    for a, b in tree:
        children[a].append(b)
    roots = [i for i in range(n) if i not in parent]
    reached: set[int] = set()

    def reach(node: int) -> None:
        stack = [node]
        while stack:
            k = stack.pop()
            if k not in reached:
                reached.add(k)
                stack.extend(children[k])

    for r in roots:
        reach(r)
    for i in range(n):  # a cycle of one-way edges: its first node becomes a root
        if i not in reached:
            p = parent.pop(i)
            tree.remove((p, i))
            other.append((p, i))
            children[p].remove(i)
            roots.append(i)
            reach(i)
    first = 1 if (base and len(roots) > 1) else 0
    pos = np.zeros((n, 2))
    next_row = [0.0]

    def place(node: int, depth: int) -> float:
        kids = children[node]
        if kids:
            row = float(np.mean([place(k, depth + 1) for k in kids]))
        else:
            row = next_row[0]
            next_row[0] += 1.0
        pos[node] = (depth, row)
        return row

    for k, r in enumerate(roots):
        next_row[0] += 1.0 if k else 0.0  # a free row between the trees of two roots
        place(r, first)
    base_at = (0.0, float(np.mean(pos[roots, 1]))) if first else None
    return GraphLayout(pos, tree, both_ways, other, roots, base_at)


def _common_prefix(names: Sequence[str]) -> str:
    """The prefix all ``names`` share, cut after its last ``_`` (``yumi_``), or ""."""
    prefix = os.path.commonprefix([str(n) for n in names]) if len(names) > 1 else ""
    return prefix[: prefix.rfind("_") + 1]


def plot_graph(graph, names: Sequence[str] | None = None, ax=None, title: str = "", fontsize: float = 7.0,
               base: str | None = "base"):
    """Draw a :class:`nlo_lab.graph.Graph` as a tree, roots on the left, leaves on the right.

    Solid lines are the parent -> child edges. A pair of nodes joined in both directions (the robot
    graph's two arm roots) is one dashed curve with an arrow at each end. Where the graph has several
    roots, they hang from a grey square labelled ``base``: a drawing aid, not a node of the graph.
    A prefix that every name shares (``yumi_``) is left out of the labels and named in the title.

    Args:
        graph: the robot structure graph (``robot.graph``) or the human skeleton graph.
        names: one label per node (e.g. ``robot.joint_names`` or ``nlo_lab.human.NODE_NAMES``).
        ax: axes to draw into (a new figure of the drawing's size if None).
        title: the title (by default the counts of nodes and edges).
        fontsize: of the node labels [pt].
        base: the label of the virtual base node before several roots; None draws the roots alone.

    Returns:
        ``(fig, ax)``.
    """
    # lazy: pyplot picks a backend on import: only when a figure is drawn
    import matplotlib.pyplot as plt

    edges = np.asarray(graph.edge_index.detach().cpu() if hasattr(graph.edge_index, "detach") else graph.edge_index)
    n = int(graph.num_nodes)
    lay = graph_layout(n, edges, base=base is not None)
    labels = [str(name) for name in names] if names is not None else [""] * n
    prefix = _common_prefix(labels)
    labels = [name[len(prefix):] for name in labels]
    leaf = np.ones(n, bool)
    for p, _ in lay.tree:
        leaf[p] = False
    char = 0.6 * fontsize / 72  # about the width of one character [in]
    # a column is as far from the next as the labels above their nodes need (half of each, centred)
    depth = lay.pos[:, 0].astype(int)
    columns = int(depth.max()) + 1 if n else 1
    above = np.zeros(columns)
    for i in np.flatnonzero(~leaf):
        above[depth[i]] = max(above[depth[i]], len(labels[i]))
    if lay.base is not None:
        above[0] = max(above[0], len(base))
    gaps = [max(0.55, char * ((above[d] + above[d + 1]) / 2 + 2)) for d in range(columns - 1)]
    x_of = np.concatenate([[0.0], np.cumsum(gaps)])
    dy = 0.34  # row spacing [in]
    pos = np.column_stack([x_of[depth], -lay.pos[:, 1] * dy])  # inches: the drawing keeps its shape
    tail = char * max([len(labels[i]) for i in np.flatnonzero(leaf)] + [4]) + 0.2
    left, top = char * above[0] / 2 + 0.1, 0.55
    if ax is None:
        width, height = left + float(x_of[-1]) + tail, top + float(-pos[:, 1].min()) + 0.25
        fig, ax = plt.subplots(figsize=(max(4.0, width), max(1.5, height)))
        fig.subplots_adjust(0, 0, 1, 1)
        ax.set_xlim(-left, fig.get_size_inches()[0] - left)
        ax.set_ylim(top - fig.get_size_inches()[1], top)
    fig = ax.figure
    for p, c in lay.tree:
        ax.plot(pos[[p, c], 0], pos[[p, c], 1], color="0.6", lw=1, zorder=1)
    for p, c in lay.other:
        ax.annotate("", pos[c], pos[p], arrowprops=dict(arrowstyle="->", color="0.6", lw=1, ls=":"), zorder=1)
    for a, b in lay.both_ways:  # a bracket on the left of the two nodes, an arrow into each
        x = min(pos[a, 0], pos[b, 0]) - 0.22
        ax.plot([x, x], [pos[a, 1], pos[b, 1]], color="#4C72B0", lw=1.2, ls="--", zorder=1)
        for k in (a, b):
            ax.annotate("", pos[k], (x, pos[k, 1]), zorder=1,
                        arrowprops=dict(arrowstyle="->", color="#4C72B0", lw=1.2, ls="--", shrinkA=0, shrinkB=4))
    if lay.base is not None:
        bx, by = 0.0, -lay.base[1] * dy
        for r in lay.roots:
            ax.plot([bx, pos[r, 0]], [by, pos[r, 1]], color="0.75", lw=1, ls=":", zorder=0)
        ax.scatter([bx], [by], marker="s", s=60, color="0.75", zorder=2)
        ax.annotate(str(base), (bx, by), xytext=(0, 6), textcoords="offset points", ha="center", va="bottom",
                    fontsize=fontsize, color="0.35", style="italic")
    types = np.asarray(graph.node_type.detach().cpu() if hasattr(graph.node_type, "detach") else graph.node_type)
    palette = {0: "#E8731A", 1: "#2CA02C"}  # arm, hand (as in the 3-D viewer)
    ax.scatter(pos[:, 0], pos[:, 1], c=[palette.get(int(t), "#4C72B0") for t in types], s=30, zorder=2)
    for i, label in enumerate(labels):
        if leaf[i]:  # after the last node of its branch
            ax.annotate(label, pos[i], xytext=(6, 0), textcoords="offset points", ha="left", va="center", fontsize=fontsize)
        else:  # above the node, between its edges
            ax.annotate(label, pos[i], xytext=(0, 5), textcoords="offset points", ha="center", va="bottom", fontsize=fontsize)
    name = title or f"{n} nodes, {edges.shape[1]} edges"
    ax.text(0.5, 0.99, name + (f" (names without the prefix {prefix!r})" if prefix else ""), transform=ax.transAxes,
            ha="center", va="top", fontsize=fontsize + 2)
    ax.axis("off")
    return fig, ax

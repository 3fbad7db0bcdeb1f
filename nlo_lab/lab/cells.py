"""Helpers that keep the notebooks' cells thin (see ``notebooks/README.md``).

* :data:`TEST_MODE` / :func:`budget`: shorter loops under CI (``NLO_LAB_TEST_MODE=1``);
* :func:`setup`: seeds and a one-line report of the mode and the viewer;
* :func:`show_robot`, :func:`show_view`, :func:`show_human`: a new 3-D scene each, a
  widget running meshcat's viewer in the notebook (:class:`nlo_lab.viz.SceneWidget`);
* :func:`joint_table`, :func:`plot_graph`, :func:`recording_path`: small things
  several notebooks need.
"""

from __future__ import annotations

import html
import os
import random
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from nlo_lab.errors import NloLabError
from nlo_lab.paths import RECORDINGS_DIR

__all__ = [
    "TEST_ENV",
    "TEST_MODE",
    "is_test_mode",
    "budget",
    "setup",
    "show_robot",
    "show_view",
    "show_human",
    "joint_table",
    "plot_graph",
    "RECORDINGS_DIR",
    "recording_path",
]

TEST_ENV = "NLO_LAB_TEST_MODE"  # set to 1 (CI, ``make test``) for short loops


def is_test_mode() -> bool:
    """True when the environment asks for test mode (``NLO_LAB_TEST_MODE=1``)."""
    return os.environ.get(TEST_ENV, "").strip().lower() in ("1", "true", "yes", "on")


TEST_MODE: bool = is_test_mode()  # read once at import: a notebook's budgets stay fixed while it runs


def budget(full, test):
    """``test`` in test mode, else ``full`` (iterations, frames, sequences, seeds ...)."""
    return test if is_test_mode() else full


def setup(seed: int = 0, quiet: bool = False) -> None:
    """Seed torch, numpy and random, use one torch thread; print the mode.

    Args:
        seed: the seed of every generator.
        quiet: print nothing.
    """
    import torch

    from nlo_lab.threads import default_threads

    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)
    torch.set_num_threads(default_threads())  # small problems: see nlo_lab.threads
    if not quiet:
        print(f"nlo_lab: test mode {'on' if is_test_mode() else 'off'}; 3-D views: meshcat widgets in the notebook")


# ------------------------------------------------------------------ the 3-D views
def _robot(robot):
    if isinstance(robot, str):
        from nlo_lab.robot import load_robot

        return load_robot(robot)
    return robot


def _angles(robot, q) -> np.ndarray:
    if q is None:
        q = getattr(robot, "neutral_q", None)
        q = robot.reference_q if q is None else q
    return robot.check_angles(q)  # (T, n) float64


def _failed(widget, exc: Exception):
    """The view with the reason it cannot draw, instead of a silent blank canvas."""
    widget.show_message(f"Cannot show this view: {exc}")
    return widget


def show_view(robot, angles=None, demo=None, *, layout: str = "side", height: int = 400):
    """An animated 3-D view of ``robot`` (and the human ``demo`` beside it) to display: a new scene.

    The view is a widget (:class:`nlo_lab.viz.SceneWidget`, meshcat's viewer in the notebook
    output) that talks to the kernel over the notebook's own connection: no server, no port.
    The animation plays in the browser; the viewer's Open Controls panel pauses and scrubs it.

    Args:
        robot: a loaded ``nlo_lab.robot.Robot`` or its name.
        angles: ``(T, n)`` or ``(n,)`` joint angles [rad]; the robot's neutral pose if None.
        demo: optional ``Demonstration`` with the same number of frames.
        layout: ``"side"`` or ``"overlay"``.
        height: view height [px].

    Returns:
        A :class:`nlo_lab.viz.SceneWidget`. Bad input (an unknown robot, non-finite angles, frames
        that do not match) gives the widget with the reason shown in it.
    """
    from nlo_lab.viz import RetargetScene, SceneWidget

    widget = SceneWidget(height=height)
    try:
        robot = _robot(robot)
        q = _angles(robot, angles)
        with widget.hold():
            scene = RetargetScene(widget.vis, robot, q, demo=demo, layout=layout)
            if len(scene) > 1:
                scene.animate(play=True, repetitions=0)
    except NloLabError as exc:
        return _failed(widget, exc)
    widget.scene = scene
    return widget


def show_robot(robot, q=None, *, height: int = 400):
    """One pose of ``robot`` (``(n,)`` [rad], neutral if None) as a new scene; see :func:`show_view`."""
    from nlo_lab.viz import SceneWidget

    try:
        robot = _robot(robot)
        q = _angles(robot, q)
        if q.shape[0] != 1:
            raise NloLabError(f"show_robot shows one pose; got {q.shape[0]} frames (use show_view)")
    except NloLabError as exc:
        return _failed(SceneWidget(height=height), exc)
    return show_view(robot, q, height=height)


def show_human(demo, *, height: int = 400):
    """An animated 3-D view of a human ``Demonstration`` alone (skeleton and fingers) as a new scene; see :func:`show_view`."""
    from meshcat.animation import Animation

    from nlo_lab.viz import HumanScene, SceneWidget, frame_points, style_viewer

    widget = SceneWidget(height=height)
    try:
        with widget.hold():
            scene = HumanScene(widget.vis, demo).draw()
            style_viewer(widget.vis, camera=frame_points(scene.extent_points()))
            if len(demo) > 1:
                anim = Animation(default_framerate=float(demo.fps))
                scene.add_to(anim)
                widget.vis.set_animation(anim, play=True, repetitions=0)
    except NloLabError as exc:
        return _failed(widget, exc)
    widget.scene = scene
    return widget


# ------------------------------------------------------------------ small things
def joint_table(robot):
    """An HTML table of the robot's actuated joints and limits ([rad] and [deg])."""
    from IPython.display import HTML

    rows = []
    for i, (name, lo, hi) in enumerate(zip(robot.joint_names, robot.lower_limits.tolist(), robot.upper_limits.tolist(), strict=True)):
        rows.append(
            f"<tr><td>{i}</td><td><code>{html.escape(name)}</code></td><td>{lo:+.3f}</td><td>{hi:+.3f}</td>"
            f"<td>{np.degrees(lo):+.1f}</td><td>{np.degrees(hi):+.1f}</td></tr>"
        )
    head = "<tr><th>#</th><th>joint</th><th>lower [rad]</th><th>upper [rad]</th><th>lower [°]</th><th>upper [°]</th></tr>"
    return HTML(f"<p><b>{html.escape(robot.name)}</b>: {robot.n_joints} actuated joints</p><table>{head}{''.join(rows)}</table>")


def _tree_layout(n: int, edges: np.ndarray) -> np.ndarray:
    """``(n, 2)`` positions of a forest: depth downwards, leaves spread left to right."""
    children: dict[int, list[int]] = {i: [] for i in range(n)}
    has_parent = np.zeros(n, bool)
    for p, c in edges.T:
        children[int(p)].append(int(c))
        has_parent[int(c)] = True
    pos = np.zeros((n, 2))
    cursor = [0.0]

    def place(node: int, depth: int) -> float:
        kids = children[node]
        if not kids:
            x = cursor[0]
            cursor[0] += 1.0
        else:
            x = float(np.mean([place(k, depth + 1) for k in kids]))
        pos[node] = (x, -depth)
        return x

    for root in np.flatnonzero(~has_parent):
        place(int(root), 0)
    return pos


def plot_graph(graph, names: Sequence[str] | None = None, ax=None, title: str = "", fontsize: float = 6.0):
    """Draw a :class:`nlo_lab.graph.Graph` as a tree (parent above child), nodes coloured by type.

    Args:
        graph: the robot structure graph (``robot.graph``) or the human skeleton graph.
        names: one label per node (e.g. ``robot.joint_names`` or ``nlo_lab.human.NODE_NAMES``).
        ax: axes to draw into (a new figure if None).

    Returns:
        ``(fig, ax)``.
    """
    import matplotlib.pyplot as plt

    edges = np.asarray(graph.edge_index.detach().cpu() if hasattr(graph.edge_index, "detach") else graph.edge_index)
    n = int(graph.num_nodes)
    pos = _tree_layout(n, edges)
    if ax is None:
        fig, ax = plt.subplots(figsize=(max(6.0, 0.35 * n), 3.5))
    fig = ax.figure
    for p, c in edges.T:
        ax.plot(pos[[p, c], 0], pos[[p, c], 1], color="0.6", lw=1, zorder=1)
    types = np.asarray(graph.node_type.detach().cpu() if hasattr(graph.node_type, "detach") else graph.node_type)
    palette = {0: "#E8731A", 1: "#2CA02C"}  # arm, hand (as in the 3-D viewer)
    ax.scatter(pos[:, 0], pos[:, 1], c=[palette.get(int(t), "#4C72B0") for t in types], s=40, zorder=2)
    if names is not None:
        for i, name in enumerate(names):
            ax.annotate(str(name), pos[i], xytext=(0, -7), textcoords="offset points", ha="center", va="top", fontsize=fontsize, rotation=60)
    ax.set_title(title or f"{n} nodes, {edges.shape[1]} edges (orange: arm, green: hand)")
    ax.axis("off")
    return fig, ax


def recording_path(name: str = "holistic_both_hands_47f.pose") -> Path:
    """A real recording shipped in ``assets/recordings/`` (see its README for the licence)."""
    path = RECORDINGS_DIR / name
    if not path.is_file():
        have = sorted(p.name for p in RECORDINGS_DIR.glob("*")) if RECORDINGS_DIR.is_dir() else []
        raise NloLabError(f"no shipped recording {name!r} in {RECORDINGS_DIR} (have: {', '.join(have) or 'none'})")
    return path

"""Helpers that keep the notebooks' cells thin (see ``notebooks/README.md``).

* :data:`TEST_MODE` / :func:`budget`: shorter loops under CI (``NLO_LAB_TEST_MODE=1``);
* :func:`setup`: seeds and a one-line report of the mode and the viewer;
* :func:`viewer`, :func:`show_robot`, :func:`show_view`: the live meshcat viewer
  when one can be started and reached, else the static page inline;
* :func:`joint_table`, :func:`plot_graph`, :func:`recording_path`: small things
  several notebooks need.
"""

from __future__ import annotations

import html
import os
import random
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from nlo_lab.errors import NloLabError
from nlo_lab.paths import ASSETS

__all__ = [
    "TEST_ENV",
    "TEST_MODE",
    "is_test_mode",
    "budget",
    "setup",
    "viewer",
    "close_viewer",
    "show_robot",
    "show_view",
    "show_human",
    "view_html",
    "joint_table",
    "plot_graph",
    "RECORDINGS_DIR",
    "recording_path",
]

TEST_ENV = "NLO_LAB_TEST_MODE"  # set to 1 (CI, ``make test``) for short loops
RECORDINGS_DIR = ASSETS / "recordings"


def is_test_mode() -> bool:
    """True when the environment asks for test mode (``NLO_LAB_TEST_MODE=1``)."""
    return os.environ.get(TEST_ENV, "").strip().lower() in ("1", "true", "yes", "on")


TEST_MODE: bool = is_test_mode()  # read once at import: a notebook's budgets stay fixed while it runs


def budget(full, test):
    """``test`` in test mode, else ``full`` (iterations, frames, sequences, seeds ...)."""
    return test if is_test_mode() else full


def setup(seed: int = 0, quiet: bool = False) -> None:
    """Seed torch, numpy and random, use one torch thread; print the mode and the viewer used.

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
        from nlo_lab.viz import static_viewer_requested

        view = "static (NLO_LAB_STATIC_VIEWER=1)" if static_viewer_requested() else "live if it can start, else static"
        print(f"nlo_lab: test mode {'on' if is_test_mode() else 'off'}; 3-D viewer: {view}")


# ------------------------------------------------------------------ the viewer
_VIEWER: dict[str, Any] = {"viewer": None, "tried": False}


def viewer(start: bool = True):
    """The notebook's one shared live :class:`nlo_lab.viz.Viewer`, or None.

    The first call tries to start it (unless ``NLO_LAB_STATIC_VIEWER=1``); a
    failed start is remembered, so later cells fall back to the static view at
    once. The server listens on 127.0.0.1 and dies with the kernel.

    Args:
        start: try to start a server if none is running.
    """
    from nlo_lab.viz import live_viewer, static_viewer_requested

    v = _VIEWER["viewer"]
    if v is not None and v.alive:
        return v
    _VIEWER["viewer"] = None
    if not start or static_viewer_requested() or _VIEWER["tried"]:
        return None
    _VIEWER["tried"] = True
    _VIEWER["viewer"] = live_viewer()
    return _VIEWER["viewer"]


def close_viewer() -> None:
    """Stop the shared live viewer (it also stops by itself when the kernel ends)."""
    v = _VIEWER["viewer"]
    if v is not None:
        v.close()
    _VIEWER.update(viewer=None, tried=False)


def _angles(robot, q) -> np.ndarray:
    if q is None:
        q = getattr(robot, "neutral_q", None)
        q = robot.reference_q if q is None else q
    if hasattr(q, "detach"):
        q = q.detach().cpu().numpy()
    a = np.asarray(q, dtype=np.float64)
    if a.ndim == 1:
        a = a[None]
    if a.ndim != 2 or a.shape[1] != robot.n_joints:
        raise NloLabError(f"angles for robot {robot.name!r} must be ({robot.n_joints},) or (T, {robot.n_joints}), got shape {a.shape}")
    return a


def show_view(robot, angles=None, demo=None, *, layout: str = "side", height: int = 400, live: bool | None = None):
    """An animated 3-D view of ``robot`` (and the human ``demo`` beside it) to display.

    Uses the live viewer when one can be started and reached, else the static
    self-contained page in an iframe (``srcdoc``): the cell's output works in
    CI, on Binder and in an exported notebook.

    Args:
        robot: a loaded ``nlo_lab.robots.Robot``.
        angles: ``(T, n)`` or ``(n,)`` joint angles [rad]; the robot's neutral pose if None.
        demo: optional ``Demonstration`` with the same number of frames.
        layout: ``"side"`` or ``"overlay"``.
        height: view height [px].
        live: force (True) or forbid (False) the live viewer; None = automatic.

    Returns:
        An ``IPython.display.HTML`` object.
    """
    from nlo_lab.viz import RetargetScene, iframe_html, static_html

    q = _angles(robot, angles)
    v = viewer() if live is not False else None
    if v is not None:
        v.vis.delete()
        scene = RetargetScene(v.vis, robot, q, demo=demo, layout=layout)
        if len(scene) > 1:
            scene.animate(play=True, repetitions=0)
        return v.jupyter_cell(height=height)
    if live:
        raise NloLabError("no live viewer could be started (static view requested, or the server did not start)")
    return iframe_html(static_html(robot, q, demo=demo, layout=layout), height=height)


def show_robot(robot, q=None, *, height: int = 400, live: bool | None = None):
    """One pose of ``robot`` (``(n,)`` [rad], neutral if None) to display; see :func:`show_view`."""
    q = _angles(robot, q)
    if q.shape[0] != 1:
        raise NloLabError(f"show_robot shows one pose; got {q.shape[0]} frames (use show_view)")
    return show_view(robot, q, height=height, live=live)


def show_human(demo, *, height: int = 400, live: bool | None = None):
    """An animated 3-D view of a human ``Demonstration`` alone (skeleton and fingers); see :func:`show_view`."""
    from meshcat.animation import Animation

    from nlo_lab.viz import HumanScene, frame_points, iframe_html, recording_visualizer, style_viewer

    v = viewer() if live is not False else None
    if v is None and live:
        raise NloLabError("no live viewer could be started (static view requested, or the server did not start)")
    vis = v.vis if v is not None else recording_visualizer()
    vis.delete()
    scene = HumanScene(vis, demo).draw()
    style_viewer(vis, camera=frame_points(scene.extent_points()))
    if len(demo) > 1:
        anim = Animation(default_framerate=float(demo.fps))
        scene.add_to(anim)
        vis.set_animation(anim, play=True, repetitions=0)
    return v.jupyter_cell(height=height) if v is not None else iframe_html(vis.static_html(), height=height)


def view_html(page: str, height: int = 400) -> str:
    """The HTML of an iframe showing a static page inline (for an ``ipywidgets.HTML``)."""
    return (
        f'<iframe srcdoc="{html.escape(page, quote=True)}" '
        f'style="width: 100%; height: {int(height)}px; border: none"></iframe>'
    )


# ------------------------------------------------------------------ small things
def joint_table(robot):
    """An HTML table of the robot's actuated joints and limits ([rad] and [deg])."""
    from IPython.display import HTML

    rows = []
    for i, (name, lo, hi) in enumerate(zip(robot.joint_names, robot.lower_limits.tolist(), robot.upper_limits.tolist())):
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

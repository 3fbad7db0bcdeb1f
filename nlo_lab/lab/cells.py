"""Helpers that keep the notebooks' cells thin (see ``notebooks/README.md``).

* :data:`TEST_MODE` / :func:`budget`: shorter loops under CI (``NLO_LAB_TEST_MODE=1``);
* :func:`setup`: seeds and a one-line report of the mode and the viewer;
* :func:`show_robot`, :func:`show_view`, :func:`show_human`: a new 3-D scene each, a
  widget running meshcat's viewer in the notebook (:class:`nlo_lab.viz.SceneWidget`);
* :func:`joint_table`, :func:`recording_path`: small things several notebooks need;
* :func:`time_bar`: a progress bar for work whose budget is a time (training for N seconds);
* :func:`work_folder`: where a notebook writes (exports, uploads), never into the package or a
  clone's tracked files.
"""

from __future__ import annotations

import contextlib
import html
import os
import random
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch
from tqdm.auto import tqdm

from nlo_lab.errors import NloLabError, OutputError, SettingsError
from nlo_lab.paths import RECORDINGS_DIR
from nlo_lab.robot import load_robot
from nlo_lab.threads import default_threads
from nlo_lab.viz.tracks import LOOP

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

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
    "RECORDINGS_DIR",
    "recording_path",
    "WORK_ENV",
    "work_folder",
    "time_bar",
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
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)
    torch.set_num_threads(default_threads())  # small problems: see nlo_lab.threads
    if not quiet:
        print(f"nlo_lab: test mode {'on' if is_test_mode() else 'off'}; 3-D views: meshcat widgets in the notebook")


# ------------------------------------------------------------------ the 3-D views
def _robot(robot):
    if isinstance(robot, str):
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


def show_view(robot: Robot | str, angles=None, demo=None, *, layout: str = "side", height: int = 400):
    """An animated 3-D view of ``robot`` (and the human ``demo`` beside it) to display: a new scene.

    The view is a widget (:class:`nlo_lab.viz.SceneWidget`, meshcat's viewer in the notebook
    output) that talks to the kernel over the notebook's own connection: no server, no port.
    The animation plays in the browser and loops; the button at the view's lower left pauses and plays it,
    the viewer's Open Controls panel also scrubs it.

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
    # lazy: anywidget and ipywidgets: only when a view is drawn in a kernel
    from nlo_lab.viz import RetargetScene, SceneWidget

    widget = SceneWidget(height=height)
    try:
        robot = _robot(robot)
        q = _angles(robot, angles)
        with widget.hold():
            scene = RetargetScene(widget.vis, robot, q, demo=demo, layout=layout)
            if len(scene) > 1:
                scene.animate(play=True, repetitions=LOOP)
    except NloLabError as exc:
        return _failed(widget, exc)
    widget.scene = scene
    return widget


def show_robot(robot: Robot | str, q=None, *, height: int = 400, capsules: bool = False):
    """One pose of ``robot`` (``(n,)`` [rad], neutral if None) as a new scene; see :func:`show_view`.
    ``capsules=True`` draws the spec's collision capsules over it (:func:`nlo_lab.viz.capsules.draw_capsules`)."""
    # lazy: anywidget and ipywidgets: only when a view is drawn in a kernel
    from nlo_lab.viz import SceneWidget

    try:
        robot = _robot(robot)
        q = _angles(robot, q)
        if q.shape[0] != 1:
            raise SettingsError(f"show_robot shows one pose; got {q.shape[0]} frames (use show_view)")
    except NloLabError as exc:
        return _failed(SceneWidget(height=height), exc)
    widget = show_view(robot, q, height=height)
    if capsules and getattr(widget, "scene", None) is not None:
        from nlo_lab.viz.capsules import draw_capsules

        with widget.hold():
            draw_capsules(widget.vis, robot, path=widget.scene.robot_scene.path)
    return widget


def show_human(demo, *, height: int = 400):
    """An animated (looping) 3-D view of a human ``Demonstration`` alone (skeleton and fingers) as a new scene; see :func:`show_view`."""
    # lazy: meshcat's scene classes: only when a view is drawn
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
                widget.vis.set_animation(anim, play=True, repetitions=LOOP)
    except NloLabError as exc:
        return _failed(widget, exc)
    widget.scene = scene
    return widget


# ------------------------------------------------------------------ small things
def joint_table(robot: Robot):
    """An HTML table of the robot's actuated joints and limits ([rad] and [deg])."""
    # lazy: a kernel's display: only in a notebook
    from IPython.display import HTML

    rows = []
    for i, (name, lo, hi) in enumerate(zip(robot.joint_names, robot.lower_limits.tolist(), robot.upper_limits.tolist(), strict=True)):
        rows.append(
            f"<tr><td>{i}</td><td><code>{html.escape(name)}</code></td><td>{lo:+.3f}</td><td>{hi:+.3f}</td>"
            f"<td>{np.degrees(lo):+.1f}</td><td>{np.degrees(hi):+.1f}</td></tr>"
        )
    head = "<tr><th>#</th><th>joint</th><th>lower [rad]</th><th>upper [rad]</th><th>lower [°]</th><th>upper [°]</th></tr>"
    return HTML(f"<p><b>{html.escape(robot.name)}</b>: {robot.n_joints} actuated joints</p><table>{head}{''.join(rows)}</table>")


def recording_path(name: str = "holistic_both_hands_47f.pose") -> Path:
    """A real recording shipped in ``assets/recordings/`` (see its README for the licence)."""
    path = RECORDINGS_DIR / name
    if not path.is_file():
        have = sorted(p.name for p in RECORDINGS_DIR.glob("*")) if RECORDINGS_DIR.is_dir() else []
        raise SettingsError(f"no shipped recording {name!r} in {RECORDINGS_DIR} (have: {', '.join(have) or 'none'})")
    return path


WORK_ENV = "NLO_LAB_WORK"  # where the notebooks write; default ./nlo_lab_work


def work_folder(name: str = "") -> Path:
    """The folder a notebook writes into (exports, uploaded videos), created if missing.

    ``$NLO_LAB_WORK/name`` if that variable is set, else ``nlo_lab_work/name`` in the current folder (the
    notebook's own: beside your copy of the notebooks, where Jupyter's file browser shows it). In a clone
    of the repository ``nlo_lab_work/`` is ignored by git (``.gitignore``), so running the notebooks there
    leaves ``git status`` clean.

    Args:
        name: a sub-folder (one plain name, e.g. ``"retargeted"``); "" for the work folder itself.

    Raises:
        NloLabError: ``name`` is not one plain folder name, or the folder cannot be created.
    """
    if name and (Path(name).name != name or name in (".", "..")):
        raise SettingsError(f"work_folder takes one plain folder name, got {name!r}")
    root = Path(os.environ.get(WORK_ENV) or "nlo_lab_work").expanduser()
    folder = root / name if name else root
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create the work folder {folder}: {exc.strerror or exc}") from None
    return folder


@contextlib.contextmanager
def time_bar(seconds: float, desc: str = ""):
    """A progress bar (tqdm: a widget in a notebook, text elsewhere) that fills with the wall-clock time
    spent inside the block, out of ``seconds``: for work whose budget is a time, such as training for
    N seconds (``train_variant``), where the time spent is the progress made.

    Args:
        seconds: the budget [s] (the bar's total).
        desc: the bar's label.

    Yields:
        The tqdm bar (``bar.set_postfix_str(...)`` says what runs now).
    """
    total = max(1, round(float(seconds)))
    bar = tqdm(total=total, desc=desc, unit="s", bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} s{postfix}")
    start, stop = time.monotonic(), threading.Event()

    def tick() -> None:  # another thread: the block itself runs undisturbed
        while not stop.wait(0.5):
            bar.n = min(total, int(time.monotonic() - start))
            bar.refresh()

    ticker = threading.Thread(target=tick, name="nlo_lab-time-bar", daemon=True)
    ticker.start()
    try:
        yield bar
    finally:
        stop.set()
        ticker.join()
        bar.n = min(total, round(time.monotonic() - start))
        bar.refresh()
        bar.close()

"""Self-contained static HTML of a meshcat scene, made without any server.

:class:`RecordingWindow` stands in for meshcat's ZMQ window: it keeps the scene
tree in process exactly as meshcat's server does, and its ``get_scene`` packs
the viewer's JavaScript and every drawing command (as ``data:`` URLs) into one
HTML page, so ``Visualizer.static_html()`` works offline, from ``file://``, in
CI and on Binder. Nothing in the page is fetched from the network.
"""

from __future__ import annotations

import html
import os
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import umsgpack
from meshcat import Visualizer
from meshcat.servers.tree import SceneTree, find_node, walk
from meshcat.servers.zmqserver import VIEWER_ROOT, create_command

from nlo_lab.atomic_files import atomic_path
from nlo_lab.errors import OutputError, SettingsError
from nlo_lab.viz._packing import packb_single
from nlo_lab.viz.scene import RetargetScene
from nlo_lab.viz.tracks import LOOP, set_key_times

__all__ = [
    "VIEWER_MAX_FRAMES",
    "RecordingWindow",
    "recording_visualizer",
    "scene_commands",
    "scene_html",
    "decimate",
    "export_html",
    "static_html",
]

# Most animation frames a page stores (YuMi and a human: about 10 kB each in single
# precision, 14 kB in double): a longer recording keeps every k-th frame (see
# :func:`decimate`), so a 10,000-frame recording gives a page of about 20 MB instead of 140.
VIEWER_MAX_FRAMES = 2000


@lru_cache(maxsize=1)
def viewer_js() -> str:
    """meshcat's three.js viewer bundle (``viewer/dist/main.min.js`` of the meshcat package)."""
    return (Path(VIEWER_ROOT) / "main.min.js").read_text(encoding="utf-8")


def scene_commands(tree) -> list[bytes]:
    """Every command of ``tree`` (msgpack bytes, as meshcat's server relays them), parents before children."""
    out = []
    for node in walk(tree):
        out.extend(payload for payload in (node.object, *node.properties, node.transform, node.animation) if payload is not None)
    return out


def scene_html(tree, title: str = "nlo_lab viewer") -> str:
    """One HTML page holding meshcat's viewer script and every command of ``tree``."""
    commands = [create_command(payload) for payload in scene_commands(tree)]
    js = viewer_js().replace("</script", "<\\/script")  # keep the inline script closed only where we close it
    return (
        "<!DOCTYPE html>\n<html>\n<head><meta charset=\"utf-8\"><title>" + html.escape(title) + "</title>\n"
        "<style>body { margin: 0; } #meshcat-pane { width: 100vw; height: 100vh; overflow: hidden; }</style>\n"
        "</head>\n<body>\n<div id=\"meshcat-pane\"></div>\n"
        "<script>\n" + js + "\n</script>\n"
        "<script>\nvar viewer = new MeshCat.Viewer(document.getElementById(\"meshcat-pane\"));\n"
        + "".join(commands) + "\n</script>\n</body>\n</html>\n"
    )


class RecordingWindow:
    """An in-process stand-in for meshcat's ``ViewerWindow`` that records the scene tree."""

    web_url = None
    server_proc = None

    def __init__(self, single_precision: bool = False) -> None:
        self.tree = SceneTree()
        self.single_precision = single_precision  # animation keys as float32 (half the bytes; three.js computes in float32)
        self.last_payload = b""  # the bytes of the last command (what a live view is sent)

    def send(self, command) -> None:
        data = command.lower()
        cmd = data["type"]
        path = [p for p in data["path"].split("/") if p]
        payload = packb_single(data) if cmd == "set_animation" and self.single_precision else umsgpack.packb(data)
        self.last_payload = payload
        if cmd == "set_object":
            node = find_node(self.tree, path)
            node.object, node.properties = payload, []
        elif cmd == "set_transform":
            find_node(self.tree, path).transform = payload
        elif cmd == "set_property":
            find_node(self.tree, path).properties.append(payload)
        elif cmd == "set_animation":
            find_node(self.tree, path).animation = payload
        elif cmd == "delete":
            if path:
                parent = find_node(self.tree, path[:-1])
                parent.pop(path[-1], None)
            else:
                self.tree = SceneTree()
        else:
            raise SettingsError(f"the static viewer cannot record meshcat command {cmd!r}")

    def get_scene(self) -> str:
        return scene_html(self.tree)

    def close(self) -> None:
        pass


def recording_visualizer(single_precision: bool = False) -> Visualizer:
    """A meshcat ``Visualizer`` that needs no server; ``.static_html()`` gives the page.

    ``single_precision``: store animation keys as float32 (the page's animation half as large).
    """
    return Visualizer(window=RecordingWindow(single_precision))


def _decimation_step(q, max_frames: int) -> int:
    """k of :func:`decimate`: keep every k-th frame so at most ``max_frames`` remain."""
    return -(-len(q) // max_frames) if q.ndim == 2 else 1


def decimate(angles: Any, demo: Any = None, fps: float | None = None, max_frames: int | None = None):
    """Every k-th frame of ``angles`` (and ``demo``) so at most ``max_frames`` remain, and the rate that keeps the duration.

    The page stores one animation key per frame and track; three.js interpolates
    between keys (linearly, quaternions by slerp), so a long recording plays at its
    own speed with fewer keys. ``k = ceil(T / max_frames)``; nothing changes when
    ``T <= max_frames`` (default :data:`VIEWER_MAX_FRAMES`).

    Returns:
        ``(angles, demo, fps)``, decimated.
    """
    max_frames = VIEWER_MAX_FRAMES if max_frames is None else int(max_frames)
    q = np.asarray(angles)
    rate = float(fps if fps is not None else (demo.fps if demo is not None else 30.0))
    step = _decimation_step(q, max_frames)
    if step <= 1:
        return angles, demo, fps
    keep = np.arange(0, len(q), step)
    if demo is not None:
        fields = ("arm_positions", "arm_mask", "wrist_rotations", "wrist_mask", "finger_positions", "finger_mask")
        demo = type(demo).from_arrays(demo.fps, *(getattr(demo, f)[keep] for f in fields), name=demo.name, meta=demo.meta)
    return q[keep], demo, rate / step


def static_html(
    robot: Any,
    angles: Any,
    demo: Any = None,
    fps: float | None = None,
    layout: str = "side",
    offset: float | Sequence[float] | None = None,
    play: bool = True,
    human_scale: str = "robot",
    single_precision: bool = False,
    times: Any = None,
) -> str:
    """The animated robot (and human) scene as one self-contained HTML page (works offline from ``file://``).

    Args:
        robot: a ``nlo_lab.robot.Robot``.
        angles: ``(T, n)`` joint angles [rad].
        demo: optional ``Demonstration`` (same ``T``) shown beside or over the robot.
        fps: animation rate; defaults to the demonstration's, else 30.
        layout: ``"side"`` or ``"overlay"``.
        offset: side-by-side shift of the human [m] (float along -Y, or (x, y, z)); None: just beside the robot.
        play: start playing (looping) when opened; the viewer's Animations panel plays, pauses and scrubs.
        human_scale: ``"robot"`` (the human mapped into the robot's frame and size, as the metric does)
            or ``"human"`` (as recorded; side layout only).
        single_precision: animation keys as float32 (see below).
        times: optional ``(T,)`` per-frame times [s] (a trajectory's ``times``, retimed where the
            robot must go slower than the human): frame ``i`` plays at ``times[i]``, human and
            robot alike, so the page shows the motion as the robot would play it. None: frames
            ``1/fps`` apart, as recorded.

    The camera is framed on the robot and human over the whole trajectory, from the front-side.
    The page stays small: a recording longer than :data:`VIEWER_MAX_FRAMES` frames keeps
    every k-th frame at ``fps / k`` (:func:`decimate`; same duration, three.js interpolates
    between the keys), and ``single_precision=True`` (what ``nlo-lab retarget --out`` uses)
    stores the animation keys as float32, the precision three.js computes in (about 30 %
    smaller; the default keeps float64 for callers that read the numbers back).

    Returns:
        The page's HTML.
    """
    if times is not None:
        times = np.asarray(times, dtype=np.float64)
        if times.shape != (len(np.asarray(angles)),):
            raise SettingsError(f"times must be ({len(np.asarray(angles))},) to match the angles, got shape {times.shape}")
    if times is not None:
        times = times[::_decimation_step(np.asarray(angles), VIEWER_MAX_FRAMES)]  # the frames decimate keeps
    angles, demo, fps = decimate(angles, demo, fps)
    vis = recording_visualizer(single_precision)
    scene = RetargetScene(vis, robot, angles, demo=demo, layout=layout, offset=offset, fps=fps, human_scale=human_scale)
    if len(scene) > 1:
        anim = scene.animation()
        if times is not None:
            try:
                set_key_times(anim, times)  # the trajectory's own time base (retimed): what the robot would play
            except ValueError as exc:
                raise SettingsError(f"times: {exc}") from None
        vis.set_animation(anim, play=play, repetitions=LOOP if play else 1)
    return vis.static_html()


def export_html(path: str | os.PathLike, robot: Any, angles: Any, *args: Any, **options: Any) -> Path:
    """Write :func:`static_html` (same arguments after ``path``) to a file, atomically.

    Args:
        path: the ``.html`` file to write (atomically, :mod:`nlo_lab.atomic_files`; mode from the umask).
        robot, angles, *args, **options: as :func:`static_html`.

    Returns:
        The written path.
    """
    page = static_html(robot, angles, *args, **options)
    target = Path(path)
    if not target.parent.is_dir():
        raise OutputError(f"{target}: folder {target.parent} does not exist")
    with atomic_path(target) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return target

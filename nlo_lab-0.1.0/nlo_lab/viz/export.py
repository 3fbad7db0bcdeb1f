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
from functools import lru_cache
from pathlib import Path
from typing import Any, Sequence

import umsgpack
from meshcat import Visualizer
from meshcat.servers.tree import SceneTree, find_node, walk
from meshcat.servers.zmqserver import VIEWER_ROOT, create_command

from nlo_lab._atomic import atomic_path
from nlo_lab.errors import NloLabError

__all__ = ["RecordingWindow", "recording_visualizer", "scene_html", "export_html", "static_html", "iframe_html"]


@lru_cache(maxsize=1)
def _viewer_js() -> str:
    return (Path(VIEWER_ROOT) / "main.min.js").read_text(encoding="utf-8")


def scene_html(tree, title: str = "nlo_lab viewer") -> str:
    """One HTML page holding meshcat's viewer script and every command of ``tree``."""
    commands = []
    for node in walk(tree):
        if node.object is not None:
            commands.append(create_command(node.object))
        for prop in node.properties:
            commands.append(create_command(prop))
        if node.transform is not None:
            commands.append(create_command(node.transform))
        if node.animation is not None:
            commands.append(create_command(node.animation))
    js = _viewer_js().replace("</script", "<\\/script")  # keep the inline script closed only where we close it
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

    def __init__(self) -> None:
        self.tree = SceneTree()

    def send(self, command) -> None:
        data = command.lower()
        cmd = data["type"]
        path = [p for p in data["path"].split("/") if p]
        payload = umsgpack.packb(data)
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
            raise NloLabError(f"the static viewer cannot record meshcat command {cmd!r}")

    def get_scene(self) -> str:
        return scene_html(self.tree)

    def close(self) -> None:
        pass


def recording_visualizer() -> Visualizer:
    """A meshcat ``Visualizer`` that needs no server; ``.static_html()`` gives the page."""
    return Visualizer(window=RecordingWindow())


def static_html(
    robot: Any,
    angles: Any,
    demo: Any = None,
    fps: float | None = None,
    layout: str = "side",
    offset: float | Sequence[float] | None = None,
    play: bool = True,
    human_scale: str = "robot",
) -> str:
    """The animated robot (and human) scene as one self-contained HTML string.

    Args as :func:`export_html`.
    """
    from nlo_lab.viz.scene import RetargetScene

    vis = recording_visualizer()
    scene = RetargetScene(vis, robot, angles, demo=demo, layout=layout, offset=offset, fps=fps, human_scale=human_scale)
    if len(scene) > 1:
        scene.animate(play=play, repetitions=0 if play else 1)
    return vis.static_html()


def export_html(
    path: str | os.PathLike,
    robot: Any,
    angles: Any,
    demo: Any = None,
    fps: float | None = None,
    layout: str = "side",
    offset: float | Sequence[float] | None = None,
    play: bool = True,
    human_scale: str = "robot",
) -> Path:
    """Write a self-contained animated 3-D view (works offline from ``file://``).

    Args:
        path: the ``.html`` file to write (atomically, :mod:`nlo_lab._atomic`; mode from the umask).
        robot: a ``nlo_lab.robots.Robot``.
        angles: ``(T, n)`` joint angles [rad].
        demo: optional ``Demonstration`` (same ``T``) shown beside or over the robot.
        fps: animation rate; defaults to the demonstration's, else 30.
        layout: ``"side"`` or ``"overlay"``.
        offset: side-by-side shift of the human [m] (float along -Y, or (x, y, z)); None: just beside the robot.
        play: start playing (looping) when opened; the viewer's Animations panel plays, pauses and scrubs.
        human_scale: ``"robot"`` (the human mapped into the robot's frame and size, as the metric does)
            or ``"human"`` (as recorded; side layout only).

    The camera is framed on the robot and human over the whole trajectory, from the front-side.

    Returns:
        The written path.
    """
    page = static_html(robot, angles, demo=demo, fps=fps, layout=layout, offset=offset, play=play, human_scale=human_scale)
    target = Path(path)
    if not target.parent.is_dir():
        raise NloLabError(f"{target}: folder {target.parent} does not exist")
    with atomic_path(target) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return target


def iframe_html(page: str, height: int = 400):
    """An ``IPython.display.HTML`` iframe showing ``page`` inline (``srcdoc``): no server needed."""
    from IPython.display import HTML

    return HTML(
        f'<div style="height: {int(height)}px; width: 100%; overflow: hidden; resize: both">'
        f'<iframe srcdoc="{html.escape(page, quote=True)}" style="width: 100%; height: 100%; border: none"></iframe></div>'
    )

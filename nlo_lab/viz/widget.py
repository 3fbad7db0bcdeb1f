"""The live 3-D view: meshcat's own three.js viewer inside a Jupyter widget (anywidget).

No server and no port: the kernel speaks to the page over the widget's own comm
channel, which every Jupyter front end with ipywidgets provides (JupyterLab,
Notebook 7, VS Code, Binder, JupyterHub, a remote server).

* :class:`SceneWidget` is one scene. ``widget.vis`` is a meshcat ``Visualizer``
  whose window (:class:`WidgetWindow`) keeps the scene tree in the kernel, as
  meshcat's server does, and forwards each command (the same msgpack bytes
  meshcat's server relays) to the page, where ``viewer.handle_command_bytearray``
  runs it. ``with widget.hold(): ...`` sends the commands of one update as one
  message.
* The page draws with meshcat's bundle ``viewer/dist/main.min.js``. It travels
  once per page: every view refers to one :class:`MeshcatBundle` widget per kernel
  and the page evaluates it once.
* A view that is (re-)displayed, or a page that is reloaded, asks for the whole
  current scene ("ready", repeated until the kernel answers: a kernel busy with the
  next cells answers late, never not). The scene is also kept in the widget's state
  (``_scene``): at display, and after every cell that changed it, whatever contains
  the widget (a panel, a ``VBox``), so a view draws it even while the kernel is busy,
  and a notebook saved with widget state shows it without a kernel.
* The camera is the learner's: updates carry transforms, never the camera, unless
  a scene is rebuilt.
"""

from __future__ import annotations

import contextlib
import struct
import weakref
from collections.abc import Iterator
from pathlib import Path

import anywidget
import ipywidgets
import traitlets
import umsgpack
from meshcat import Visualizer

from nlo_lab.errors import SettingsError
from nlo_lab.viz.export import RecordingWindow, scene_commands, viewer_js
from nlo_lab.viz.tracks import DETAILS

__all__ = ["SceneWidget", "WidgetWindow", "MeshcatBundle", "meshcat_bundle", "pack_commands", "unpack_commands"]

_ESM = Path(__file__).with_name("scene_widget.js")


def pack_commands(commands: list[bytes]) -> bytes:
    """Commands framed as (uint32 little-endian length, msgpack bytes)... for one binary buffer."""
    return b"".join(struct.pack("<I", len(c)) + c for c in commands)


def unpack_commands(data: bytes) -> list[dict]:
    """The commands of a :func:`pack_commands` buffer (a message, a widget's saved ``_scene``) as meshcat dicts."""
    commands, at = [], 0
    while at + 4 <= len(data):
        (n,) = struct.unpack_from("<I", data, at)
        if at + 4 + n > len(data):
            raise SettingsError(f"a framed command runs past the end of the buffer (at byte {at}, length {n})")
        commands.append(umsgpack.unpackb(bytes(data[at + 4:at + 4 + n])))
        at += 4 + n
    return commands


class MeshcatBundle(ipywidgets.Widget):
    """Holds meshcat's viewer bundle; one per kernel, shared by every :class:`SceneWidget`."""

    code = traitlets.Unicode("").tag(sync=True)


_BUNDLE: list[MeshcatBundle] = []
_LIVE: weakref.WeakSet[SceneWidget] = weakref.WeakSet()  # every scene widget of this kernel
_HOOKED: list[object] = []  # the IPython shell whose post_run_cell syncs them (once per kernel)


def sync_all(*_args) -> None:
    """Store the current scene of every open :class:`SceneWidget` that changed since its last sync.

    Runs after every cell (an IPython ``post_run_cell`` hook): a widget shown inside a
    container (a panel, a ``VBox``) was never displayed itself, yet its views need the
    saved scene while the kernel is busy with the next cell and cannot answer them.
    """
    for widget in list(_LIVE):
        if widget.comm is not None:
            widget.sync()


def _hook_cells() -> None:
    """Register :func:`sync_all` after every cell of the running IPython kernel (nothing outside IPython)."""
    try:
        # lazy: a kernel's display: only in a notebook
        from IPython import get_ipython
    except ImportError:
        return
    shell = get_ipython()
    if shell is None or any(s is shell for s in _HOOKED):
        return
    shell.events.register("post_run_cell", sync_all)
    _HOOKED.append(shell)


def meshcat_bundle() -> MeshcatBundle:
    """The kernel's one :class:`MeshcatBundle` (created on first use, again if it was closed)."""
    if not _BUNDLE or _BUNDLE[0].comm is None:
        _BUNDLE[:] = [MeshcatBundle(code=viewer_js())]
    return _BUNDLE[0]


class WidgetWindow(RecordingWindow):
    """A meshcat window that records the scene tree and forwards every command to a :class:`SceneWidget`."""

    def __init__(self, widget: SceneWidget) -> None:
        super().__init__()
        self.widget = widget
        self.force = False  # send unchanged transforms too (see SceneWidget.resend)

    @property
    def detail(self) -> str:
        """The tessellation the scenes draw into this window with (the widget's ``detail``)."""
        return self.widget.detail

    def send(self, command) -> None:
        before = self._transform_of(command)
        super().send(command)  # the tree: the whole scene for a view that (re)connects
        if self.force or before is None or before != self.last_payload:  # a transform that did not change is not sent
            self.widget._forward(self.last_payload)

    def _transform_of(self, command) -> bytes | None:
        """The recorded transform bytes of the node a ``set_transform`` command targets (None otherwise)."""
        # lazy: meshcat's scene classes: only when a view is drawn
        from meshcat.commands import SetTransform
        from meshcat.servers.tree import find_node

        if not isinstance(command, SetTransform):
            return None
        return find_node(self.tree, [p for p in command.path.lower().split("/") if p]).transform


class SceneWidget(anywidget.AnyWidget):
    """One 3-D scene in a notebook output (meshcat's viewer; see the module doc).

    Args:
        height: view height [px].
        message: text shown over the view (an error or a hint); empty for none.
        detail: ``"light"`` (spheres and cylinders with about 5x fewer triangles: a browser without a GPU
            draws the scene faster) or ``"full"`` (meshcat's own tessellation, as in ``viewer.html``);
            None: :attr:`default_detail`. It applies to scenes drawn after it is set.
        antialias: multisampled (smooth) edges: True or False; None: :attr:`default_antialias`, which is None:
            on where the browser draws WebGL with a GPU, off where it draws on the CPU (SwiftShader, llvmpipe:
            there multisampling costs about a third of the frame rate). It applies to views displayed after it is set.

    Attributes:
        vis: the meshcat ``Visualizer`` drawing into this scene.
        messages_sent: comm messages sent to the page so far (for benchmarks).
        bytes_sent: their binary payload so far [bytes].
    """

    _esm = _ESM
    _bundle = traitlets.Instance(MeshcatBundle).tag(sync=True, **ipywidgets.widget_serialization)
    _scene = traitlets.Bytes(b"").tag(sync=True)  # the whole scene as last displayed (pack_commands)
    _scene_version = traitlets.Int(0).tag(sync=True)
    height = traitlets.Int(400).tag(sync=True)
    message = traitlets.Unicode("").tag(sync=True)
    detail = traitlets.Enum(DETAILS, default_value="light").tag(sync=True)
    antialias = traitlets.Bool(None, allow_none=True).tag(sync=True)
    default_detail = "light"  # of every new view (the panels' and show_*'s too): set to "full" for meshcat's own
    default_antialias: bool | None = None  # of every new view: None decides in the browser (GPU: on; CPU: off)

    def __init__(self, height: int = 400, message: str = "", detail: str | None = None, antialias: bool | None = None,
                 **kwargs) -> None:
        kwargs.setdefault("layout", ipywidgets.Layout(width="100%"))
        detail = type(self).default_detail if detail is None else detail
        if detail not in DETAILS:
            raise SettingsError(f"detail must be one of {DETAILS}, got {detail!r}")
        antialias = type(self).default_antialias if antialias is None else antialias
        if antialias is not None and not isinstance(antialias, bool):
            raise SettingsError(f"antialias must be True, False or None, got {antialias!r}")
        super().__init__(_bundle=meshcat_bundle(), height=int(height), message=message, detail=detail,
                         antialias=antialias, **kwargs)
        self.vis = Visualizer(window=WidgetWindow(self))
        self._version = 0  # commands issued so far; the page's views count the same way
        self._held: list[bytes] | None = None
        self._held_depth = 0
        self.messages_sent = 0
        self.bytes_sent = 0
        self._answered: set[str] = set()  # views sent the whole scene (their later "ready" repeats were sent before it)
        self.on_msg(self._on_page_message)
        _LIVE.add(self)
        _hook_cells()

    # ---------------------------------------------------------------- kernel -> page
    def _forward(self, payload: bytes) -> None:
        self._version += 1
        if self._held is not None:
            self._held.append(payload)
        else:
            self._send_commands([payload])

    def _send_commands(self, commands: list[bytes]) -> None:
        if not commands or self.comm is None:
            return
        data = pack_commands(commands)
        self.send({"type": "commands", "version": self._version, "count": len(commands)}, buffers=[data])
        self.messages_sent += 1
        self.bytes_sent += len(data)

    @contextlib.contextmanager
    def hold(self) -> Iterator[SceneWidget]:
        """Collect the commands issued inside the block and send them as one message at its end."""
        if self._held_depth == 0:
            self._held = []
        self._held_depth += 1
        try:
            yield self
        finally:
            self._held_depth -= 1
            if self._held_depth == 0:
                held, self._held = self._held, None
                self._send_commands(held)

    @contextlib.contextmanager
    def resend(self) -> Iterator[SceneWidget]:
        """Send every transform set inside the block, changed or not (after an animation in the page moved things)."""
        window = self.vis.window
        window.force = True
        try:
            yield self
        finally:
            window.force = False

    def snapshot(self) -> bytes:
        """The whole current scene: a delete of meshcat's root, then every command of the tree."""
        # lazy: meshcat's scene classes: only when a view is drawn
        from meshcat.commands import Delete
        from meshcat.path import Path as MeshcatPath

        reset = umsgpack.packb(Delete(MeshcatPath(("meshcat",))).lower())
        return pack_commands([reset] + scene_commands(self.vis.window.tree))

    def sync(self) -> None:
        """Store the current scene in the widget's state (what a new view or a saved notebook starts from)."""
        if self._scene_version != self._version or not self._scene:
            with self.hold_sync():
                self._scene = self.snapshot()
                self._scene_version = self._version

    def _on_page_message(self, _widget, content, buffers) -> None:
        if not isinstance(content, dict) or content.get("type") != "ready":
            return
        view = str(content.get("view"))
        # A view repeats "ready" until answered: the repeats that waited behind a busy kernel were sent before
        # the answer, and the commands after it keep that view current: a short answer is enough.
        if content.get("version") == self._version or view in self._answered:
            self.send({"type": "current", "view": view, "version": self._version})
        else:
            self.send({"type": "scene", "view": view, "version": self._version}, buffers=[self.snapshot()])
            self._answered.add(view)

    def show_message(self, text: str) -> None:
        """Show ``text`` over the view (empty: none)."""
        self.message = str(text)

    def _repr_mimebundle_(self, **kwargs):
        self.sync()
        return super()._repr_mimebundle_(**kwargs)


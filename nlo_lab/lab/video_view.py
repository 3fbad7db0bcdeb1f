"""A video's frames beside the 3-D view of the human skeleton and the robot, played in sync.

:class:`VideoView` holds an image of the current video frame and a 3-D scene
(:class:`nlo_lab.viz.RetargetScene`: the human skeleton from the video beside the
robot); one ``Play`` button and one frame slider drive both, so frame ``t`` of the
video, of the skeleton and of the robot are always shown together. Moving the
slider (or setting ``view.frame``) works headless too, which is what the tests do.

The frames are encoded to JPEG once, when the view is built, so that playing only
swaps bytes. The 3-D view is the panels' (:class:`nlo_lab.lab.View`, as
:class:`nlo_lab.lab.RetargetPanel`): a scene widget of its own, meshcat's viewer over the notebook's connection.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from nlo_lab.atomic_files import atomic_write_bytes
from nlo_lab.errors import DemonstrationError, SettingsError
from nlo_lab.human import VIDEO_SUFFIXES
from nlo_lab.lab.views import View
from nlo_lab.viz import RetargetScene

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["VideoView", "jpeg_bytes", "save_upload"]


def jpeg_bytes(image: np.ndarray, quality: int = 80) -> bytes:
    """One RGB ``uint8`` image ``(H, W, 3)`` as JPEG bytes (for an ``ipywidgets.Image``)."""
    # lazy: Pillow: only when a frame is encoded
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image)).save(buffer, format="JPEG", quality=quality)
    return buffer.getvalue()


def save_upload(upload, folder) -> Path | None:
    """Write the file a learner chose in an ``ipywidgets.FileUpload`` into ``folder``.

    Args:
        upload: the ``FileUpload`` widget (ipywidgets 8: ``value`` is a tuple of
            ``{"name", "content", ...}``), or its ``value``.
        folder: where to write it (created if missing).

    Returns:
        The written file (its name is the uploaded file's name without any folder
        part), or None when nothing was uploaded.

    Raises:
        NloLabError: the upload's name has no video extension.
    """
    value = getattr(upload, "value", upload) or ()
    if not value:
        return None
    item = value[-1]
    name = Path(str(item["name"])).name  # never a folder part from the browser
    if Path(name).suffix.lower() not in VIDEO_SUFFIXES:
        raise DemonstrationError(f"uploaded file {name!r} is not a video; expected one of {', '.join(VIDEO_SUFFIXES)}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return atomic_write_bytes(folder / name, bytes(item["content"]))


class VideoView:
    """Video frames, human skeleton and robot, one frame at a time, driven by one slider.

    Args:
        frames: ``(T, H, W, 3)`` RGB ``uint8`` video frames
            (:func:`nlo_lab.human.read_video_frames`).
        robot: a loaded ``nlo_lab.robot.Robot``.
        angles: ``(T, n)`` the robot's joint angles [rad].
        demo: the ``Demonstration`` read from the video (``T`` frames), drawn beside the robot.
        fps: playing rate; the demonstration's by default.
        view: ``"auto"`` (a scene widget of its own), a meshcat ``Visualizer``, or None (no 3-D view).
        height: height of the image and the 3-D view [px].

    Attributes:
        image: the ``ipywidgets.Image`` of the current video frame.
        slider: the frame slider; ``play``: the ``Play`` widget linked to it.
        scene: the :class:`~nlo_lab.viz.RetargetScene` (None without a 3-D view).
        widget: the whole view (displayed as the cell's value).
    """

    def __init__(self, frames: np.ndarray, robot: Robot, angles, demo, *, fps: float | None = None,
                 view: Any = "auto", height: int = 360):
        # lazy: a kernel's widgets: only when a panel is built
        import ipywidgets as W

        frames = np.asarray(frames)
        q = np.asarray(angles, dtype=np.float64)
        if frames.ndim != 4 or frames.shape[-1] != 3 or frames.dtype != np.uint8:
            raise SettingsError(f"frames must be (T, H, W, 3) uint8 RGB images, got {frames.shape} {frames.dtype}")
        if not len(frames) == len(q) == len(demo):
            raise SettingsError(f"frames ({len(frames)}), angles ({len(q)}) and the demonstration ({len(demo)}) "
                              "must have the same number of frames")
        fps = float(fps if fps is not None else demo.fps)
        if not np.isfinite(fps) or fps <= 0:
            raise SettingsError(f"fps must be > 0, got {fps!r}")
        self.fps = fps
        self._jpegs = [jpeg_bytes(f) for f in frames]
        h, w = frames.shape[1:3]
        self.image = W.Image(value=self._jpegs[0], format="jpeg",
                             layout=W.Layout(height=f"{height}px", width=f"{round(height * w / h)}px"))
        last = len(frames) - 1
        self.slider = W.IntSlider(value=0, min=0, max=last, description="frame", continuous_update=True)
        self.play = W.Play(value=0, min=0, max=last, interval=max(1, round(1000 / fps)), description="play")
        W.link((self.play, "value"), (self.slider, "value"))  # kernel-side link: works headless too
        self.time = W.HTML()
        self._view = View(view, height)
        self.scene = None
        if self._view.vis is not None:
            with self._view.hold():
                self.scene = RetargetScene(self._view.vis, robot, q, demo=demo, fps=fps)
        self.slider.observe(lambda change: self._show(change["new"]), names="value")
        self._show(0)
        parts = [self.image] + ([self._view.widget] if self._view.widget is not None else [])
        self.widget = W.VBox([W.HBox([self.play, self.slider, self.time]),
                              W.HBox(parts, layout=W.Layout(flex_flow="row wrap"))])

    def __len__(self) -> int:
        return len(self._jpegs)

    @property
    def frame(self) -> int:
        """The frame shown; setting it moves the slider (and so the image and the 3-D view)."""
        return int(self.slider.value)

    @frame.setter
    def frame(self, t: int) -> None:
        if not 0 <= int(t) < len(self):
            raise SettingsError(f"frame {t} is outside 0..{len(self) - 1}")
        self.slider.value = int(t)

    def _show(self, t: int) -> None:
        self.image.value = self._jpegs[t]
        self.time.value = f"{t / self.fps:.2f} s"
        if self.scene is not None:
            with self._view.hold():  # one message: the transforms that changed
                self.scene.set_frame(t)

    def _repr_mimebundle_(self, **kwargs):
        self._view.sync()
        return self.widget._repr_mimebundle_(**kwargs)

"""The camera in the learner's browser driving the robot in the kernel: a widget, over the notebook's own connection.

:class:`CameraView` shows a "Start" button, the camera's picture and, beside it, the robot's 3-D view
(:class:`nlo_lab.viz.SceneWidget`). Start asks the browser for the camera (``getUserMedia``); the page
then sends camera frames to the kernel over the widget's comm, each shrunk so that its longer side is
at most ``frame_size`` pixels (480) and encoded as JPEG at ``jpeg_quality`` (0.8): 20-40 kB a frame.
**At most one frame is in flight**: the page sends the next frame only when the kernel has answered the
last one, so a slow kernel makes the page drop camera frames, never queue them, and the robot shows
the present, late by one frame's processing at most. The kernel runs each frame through
:class:`~nlo_lab.live.LiveRetargeter` and updates the robot's view (only the transforms that
changed). Nothing listens on a port and the page loads nothing from anywhere: it works wherever
ipywidgets work (JupyterLab, Notebook 7, VS Code, a hub) as long as the page is a secure context
(https, or http on localhost), which browsers require for a camera; the view says so otherwise,
and when there is no camera or the learner refuses it.

Read-only traits, synced to the page: ``frames_received`` (frame messages from the page),
``frames_processed`` (retargeted), ``fps`` (processed frames per second over the last
:data:`WINDOW_SECONDS`), ``latency_ms`` (median over the same window of the kernel's time from a
frame's arrival to the robot's view update: JPEG decoding, MediaPipe, the filter, the optimisation,
the view), ``latency_split`` (the medians of those parts), ``found`` (a person in the last frame),
``error`` (the last frame the kernel could not use, in one line; the stream goes on),
``recording``. The page sets ``camera`` (``"off"``, ``"starting"``, ``"on"``, ``"failed"``) and
``camera_message`` (why it failed).

Nothing is stored unless the learner asks: frames are decoded, retargeted and dropped.
:meth:`CameraView.record` starts keeping each processed frame's landmarks and robot angles (never the
images), :meth:`CameraView.stop` ends it and returns a :class:`~nlo_lab.live.LiveRecording` (a
``.pose`` file and a :class:`~nlo_lab.inference.RobotTrajectory`, written if a folder was given).
:meth:`CameraView.play_video` feeds a video's frames through the same path as the page's (JPEG and
all): the notebook's view without a camera, and the tests' and benchmarks' stream.
"""

from __future__ import annotations

import html
import statistics
import time
from collections import deque
from pathlib import Path

import anywidget
import ipywidgets
import numpy as np
import traitlets
from tqdm.auto import tqdm

from nlo_lab.errors import NloLabError, SettingsError
from nlo_lab.live.frame_message import FrameMessageError, decode_frame_message, encode_frame
from nlo_lab.live.recording import LiveRecording
from nlo_lab.live.retargeter import TIMINGS, LiveFrame, LiveRetargeter
from nlo_lab.settings import check_bool, check_int, check_range

__all__ = ["CameraView", "WINDOW_SECONDS", "SPLIT", "FRAME_SIZE", "JPEG_QUALITY"]

WINDOW_SECONDS = 3.0  # [s] fps and latency are over the frames processed in this window
FRAME_SIZE = 480  # [px] the longer side of the frames the page sends (a 640x480 camera: 480x360)
JPEG_QUALITY = 0.8  # their JPEG quality (0..1)
SPLIT = ("decode", *TIMINGS, "view")  # the parts of the kernel's latency per frame
_ESM = Path(__file__).with_name("camera_view.js")
# image landmarks drawn over the camera picture: shoulders, elbows, wrists (MediaPipe's numbers)
_ARM_POINTS = (11, 12, 13, 14, 15, 16)


class CameraView(anywidget.AnyWidget):
    """A camera in the browser driving a robot (see the module docstring).

    Args:
        robot: a robot name or :class:`~nlo_lab.robot.Robot` (for a new :class:`LiveRetargeter`), or a
            :class:`LiveRetargeter` to use.
        height: height of the camera picture and of the 3-D view [px].
        frame_size: the longer side [px] of the frames the page sends (120..1920).
        jpeg_quality: their JPEG quality (0.3..0.95).
        mirror: show the camera picture as a mirror (the frames sent are the camera's own).
        **options: for a new :class:`LiveRetargeter` (``iterations``, ``weights``, ``filter``, ...).

    Attributes:
        retargeter: the :class:`LiveRetargeter` (change its weights and filter while it runs).
        scene: the robot's :class:`~nlo_lab.viz.SceneWidget`; ``widget``: camera and robot side by side (what is shown).
        last_frame: the last :class:`LiveFrame`; ``history``: recent frames' ``{"t", "latency_ms", SPLIT...}``.
    """

    _esm = _ESM
    height = traitlets.Int(360).tag(sync=True)
    frame_size = traitlets.Int(FRAME_SIZE).tag(sync=True)
    jpeg_quality = traitlets.Float(JPEG_QUALITY).tag(sync=True)
    mirror = traitlets.Bool(True).tag(sync=True)
    camera = traitlets.Unicode("off").tag(sync=True)  # set by the page
    camera_message = traitlets.Unicode("").tag(sync=True)  # set by the page
    frames_received = traitlets.Int(0, read_only=True).tag(sync=True)
    frames_processed = traitlets.Int(0, read_only=True).tag(sync=True)
    frames_rejected = traitlets.Int(0, read_only=True).tag(sync=True)
    fps = traitlets.Float(0.0, read_only=True).tag(sync=True)
    latency_ms = traitlets.Float(0.0, read_only=True).tag(sync=True)
    latency_split = traitlets.Dict(read_only=True).tag(sync=True)
    found = traitlets.Bool(False, read_only=True).tag(sync=True)
    error = traitlets.Unicode("", read_only=True).tag(sync=True)
    recording = traitlets.Bool(False, read_only=True).tag(sync=True)

    def __init__(self, robot="yumi", *, height: int = 360, frame_size: int = FRAME_SIZE, jpeg_quality: float = JPEG_QUALITY,
                 mirror: bool = True, **options):
        # lazy: meshcat's scene classes: only when the view is built
        from nlo_lab.viz import RobotScene, SceneWidget, frame_points, style_viewer

        check_int("height", height, 120, 2000)
        check_int("frame_size", frame_size, 120, 1920)
        check_range("jpeg_quality", jpeg_quality, 0.3, 0.95)
        check_bool("mirror", mirror)
        self.retargeter = robot if isinstance(robot, LiveRetargeter) else LiveRetargeter(robot, **options)
        if isinstance(robot, LiveRetargeter) and options:
            raise SettingsError(f"options {sorted(options)} are for a new LiveRetargeter; this one is given")
        super().__init__(height=height, frame_size=frame_size, jpeg_quality=jpeg_quality, mirror=mirror)
        self.scene = SceneWidget(height=height)
        live = self.retargeter
        with self.scene.hold():
            self._robot_scene = RobotScene(self.scene.vis, live.robot).draw()
            poses = np.stack([live.rest, live.limits.lower, live.limits.upper])
            style_viewer(self.scene.vis, camera=frame_points(self._robot_scene.extent_points(poses)))
            self._robot_scene.set_pose(live.rest)
        self.widget = ipywidgets.HBox([self, ipywidgets.Box([self.scene], layout=ipywidgets.Layout(flex="1 1 360px", min_width="320px"))],
                                      layout=ipywidgets.Layout(flex_flow="row wrap", width="100%", align_items="flex-start"))
        self.last_frame: LiveFrame | None = None
        self.history: deque[dict] = deque(maxlen=2000)
        self._recent: deque[dict] = deque()
        self._recording: LiveRecording | None = None
        self._record_to: tuple[Path, str] | None = None
        self._page_t: float | None = None  # the page's time of the last frame, and what it maps to on the stream's clock
        self._stream_t: float | None = None
        self._stream_wall: float | None = None
        self.on_msg(self._on_page_message)

    # ---------------------------------------------------------------- page -> kernel
    def _on_page_message(self, _widget, content, buffers) -> None:
        kind = content.get("type") if isinstance(content, dict) else None
        if kind == "frame":
            self._receive(content, buffers)
        elif kind == "started":
            self._page_t = None  # a new camera session: its clock is re-based on the stream's (see _stream_time)

    def _stream_time(self, page_t: float) -> float:
        """The stream's time of a frame taken at ``page_t`` on the page's clock.

        Within one camera session the page's own clock (the capture times: velocities follow them);
        a new session, or a page whose clock went back (a reload), continues after the last frame by the
        wall time that passed in the kernel.
        """
        now = time.perf_counter()
        if self._stream_t is None or self._stream_wall is None:
            t = page_t
        elif self._page_t is None or page_t <= self._page_t:
            t = self._stream_t + max(now - self._stream_wall, 1e-3)
        else:
            t = self._stream_t + (page_t - self._page_t)
        self._page_t, self._stream_t, self._stream_wall = page_t, t, now
        return t

    def _receive(self, content, buffers, answer_page: bool = True) -> None:
        """One frame message: decoded, retargeted, the robot moved; always answered (the page waits for it) unless
        ``answer_page`` is False (the kernel's own frames: :meth:`play_video`)."""
        arrived = time.perf_counter()
        received = self.frames_received + 1
        answer: dict = {"type": "done", "seq": content.get("seq") if isinstance(content, dict) else None}
        try:
            message = decode_frame_message(content, buffers)
            decoded = time.perf_counter()
            frame = self.retargeter.step(message.image, self._stream_time(message.t))
            viewed = time.perf_counter()
            with self.scene.hold():  # one message: the transforms that changed
                self._robot_scene.set_pose(frame.angles)
            done = time.perf_counter()
            self._processed(frame, arrived, {"decode": 1000 * (decoded - arrived), **frame.timings, "view": 1000 * (done - viewed)},
                            received)
            answer.update(found=frame.found, points=_overlay_points(frame))
        except NloLabError as err:  # a malformed frame (FrameMessageError) or one the retargeter refuses: said, the stream goes on
            text = str(err) if isinstance(err, FrameMessageError) else f"frame {answer['seq']}: {err}"
            with self.hold_sync():
                self.set_trait("frames_received", received)
                self.set_trait("frames_rejected", self.frames_rejected + 1)
                self.set_trait("error", text.splitlines()[0] if text else type(err).__name__)
            answer["error"] = self.error
        finally:
            if self.frames_received < received:  # an unexpected fault: counted, and the page is answered all the same
                self.set_trait("frames_received", received)
            if answer_page:
                self.send(answer)

    def _processed(self, frame: LiveFrame, arrived: float, split: dict[str, float], received: int) -> None:
        now = time.perf_counter()
        row = {"t": frame.t, "latency_ms": 1000 * (now - arrived), **{k: split.get(k, 0.0) for k in SPLIT}, "found": frame.found}
        self.last_frame = frame
        self.history.append(row)
        self._recent.append({**row, "wall": now})
        while self._recent and self._recent[0]["wall"] < now - WINDOW_SECONDS:
            self._recent.popleft()
        span = self._recent[-1]["wall"] - self._recent[0]["wall"]
        fps = (len(self._recent) - 1) / span if len(self._recent) > 1 and span > 0 else 0.0
        if self._recording is not None and frame.landmarks is not None:
            self._recording.add(frame.t, frame.landmarks, frame.angles)
        with self.hold_sync():  # one message for all of them
            self.set_trait("frames_received", received)
            self.set_trait("frames_processed", self.frames_processed + 1)
            self.set_trait("fps", round(fps, 2))
            self.set_trait("latency_ms", round(statistics.median(r["latency_ms"] for r in self._recent), 1))
            self.set_trait("latency_split", {k: round(statistics.median(r[k] for r in self._recent), 1) for k in SPLIT})
            self.set_trait("found", bool(frame.found))

    # ---------------------------------------------------------------- the kernel's own frames
    def play_video(self, source, *, frames: int | None = None, realtime: bool = False, progress: bool = False) -> dict:
        """Feed a video's frames through the page's path (JPEG of ``frame_size`` at ``jpeg_quality``, decoded, retargeted, viewed).

        Args:
            source: a video file, or ``(T, H, W, 3)`` RGB frames with their times as ``(frames, times)``.
            frames: at most this many frames (from the start).
            realtime: wait for each frame's time (a camera's pace: frames that come while the kernel is busy are
                dropped, as the page drops them); False: every frame, one after the other.
            progress: a progress bar.

        Returns:
            ``{"frames": offered, "processed": retargeted, "dropped": skipped to keep the pace}``.
        """
        images, times = _video_frames(source, frames)
        bar = None
        if progress:
            bar = tqdm(total=len(images), desc="live stream", unit="frame", leave=False)
        processed = dropped = 0
        start = time.perf_counter()
        self._page_t = None  # the video's clock starts a new session (_stream_time)
        i = 0
        while i < len(images):
            skipped = 0
            if realtime:  # the newest frame the camera has by now; the ones before it were dropped
                elapsed = time.perf_counter() - start
                newest = int(np.searchsorted(times, elapsed, side="right")) - 1
                if newest < i:
                    time.sleep(min(times[i] - elapsed, 0.05))
                    continue
                skipped, i = newest - i, newest
            jpeg = encode_frame(images[i], self.frame_size, self.jpeg_quality)
            self._receive({"type": "frame", "seq": self.frames_received + 1, "t": float(times[i])}, [jpeg], answer_page=False)
            processed, dropped = processed + 1, dropped + skipped
            if bar is not None:
                bar.update(1 + skipped)
            i += 1
        if bar is not None:
            bar.close()
        return {"frames": len(images), "processed": processed, "dropped": dropped}

    # ---------------------------------------------------------------- recording
    def record(self, folder=None, name: str = "live") -> None:
        """Start keeping each processed frame's landmarks and robot angles (never the images).

        Args:
            folder: where :meth:`stop` writes ``NAME.pose``, ``NAME.npz`` and ``NAME.csv``; None: nothing is written
                (the recording is returned by :meth:`stop`, call its ``save``).
            name: the files' name.
        """
        self._recording = LiveRecording(self.retargeter.robot.name, self.retargeter.joint_names)
        self._record_to = None if folder is None else (Path(folder), str(name))
        self.set_trait("recording", True)

    def stop(self) -> LiveRecording:
        """End the recording started by :meth:`record`: the :class:`~nlo_lab.live.LiveRecording` (saved if a folder was given).

        Raises:
            SettingsError: no recording was started, or no frame was processed since.
        """
        if self._recording is None:
            raise SettingsError("no recording to stop: call record() first")
        recording, to = self._recording, self._record_to
        self._recording, self._record_to = None, None
        self.set_trait("recording", False)
        if to is not None:
            recording.save(*to)
        else:
            recording.trajectory()  # the same error as save() when nothing was recorded
        return recording

    # ---------------------------------------------------------------- display
    def summary(self) -> str:
        """The stream's figures as one HTML line (frames, fps, latency and its parts)."""
        split = ", ".join(f"{k} {v:.0f} ms" for k, v in (self.latency_split or {}).items())
        return html.escape(f"{self.frames_processed} of {self.frames_received} frames processed, {self.fps:.1f} fps, "
                           f"latency {self.latency_ms:.0f} ms ({split})")

    def _repr_mimebundle_(self, **kwargs):
        self.scene.sync()
        return self.widget._repr_mimebundle_(**kwargs)


def _overlay_points(frame: LiveFrame) -> list[list[float]]:
    """The frame's arm and hand landmarks in image fractions (0..1), for the page to draw over the camera picture."""
    lm = frame.landmarks
    if lm is None or lm.pose is None:
        return []
    scale = np.array([1.0 / lm.width, 1.0 / lm.height])
    parts = [lm.pose[list(_ARM_POINTS), :2]] + [h[:, :2] for h in (lm.hands or {}).values()]
    return np.round(np.concatenate(parts) * scale, 4).tolist()


def _video_frames(source, limit: int | None) -> tuple[np.ndarray, np.ndarray]:
    """``(frames (T, H, W, 3), times (T,))`` of a video file or a given pair."""
    if isinstance(source, tuple):
        images, times = np.asarray(source[0]), np.asarray(source[1], dtype=np.float64)
        if images.ndim != 4 or images.shape[-1] != 3 or images.dtype != np.uint8 or times.shape != images.shape[:1]:
            raise SettingsError("source must be a video file or (frames (T, H, W, 3) uint8, times (T,))")
    else:
        # lazy: opencv (the video extra): only for a video file
        from nlo_lab.human import read_video_frames, video_info

        info = video_info(source)
        images = read_video_frames(source, max_side=FRAME_SIZE * 2)
        times = np.arange(len(images)) / float(info["fps"])
    if limit is not None:
        images, times = images[: int(limit)], times[: int(limit)]
    return images, times

"""A robot's joints on sliders, its 3-D view and the forward kinematics of a chosen link.

:class:`JointPanel` is a plain object that tests drive headlessly: set
``panel.sliders[name].value`` and read ``panel.q``, ``panel.position``
(observers fire as in the browser). The layout wraps: the view goes below the
sliders when the notebook is too narrow for both side by side.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.lab.views import View, guarded
from nlo_lab.viz import RobotScene, frame_points, style_viewer

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["JointPanel"]


class JointPanel:
    """One slider per actuated joint (within its limits) driving the robot, and FK of a link.

    Args:
        robot: a loaded ``nlo_lab.robot.Robot``.
        q: start angles ``(n,)`` [rad]; the neutral pose if None.
        link: the link whose pose is printed (default: the left wrist).
        view: ``"auto"``, None or a meshcat ``Visualizer`` (see the module doc).
        height: 3-D view height [px].

    Attributes:
        sliders: ``{joint name: FloatSlider}``.
        link: Dropdown of links.
        q: current angles ``(n,)`` [rad].
        position: the chosen link's position ``(3,)`` [m] in the robot frame.
        error: the last callback error shown in the panel ("" when the last update worked).
    """

    def __init__(self, robot: Robot, q=None, link: str | None = None, view: Any = "auto", height: int = 360):
        # lazy: a kernel's widgets: only when a panel is built
        import ipywidgets as W

        self.robot = robot
        q0 = robot.neutral_q if q is None else torch.as_tensor(q, dtype=robot.lower_limits.dtype)
        if q0.shape != (robot.n_joints,):
            raise SettingsError(f"q must be ({robot.n_joints},) for robot {robot.name!r}, got {tuple(q0.shape)}")
        lo, hi = robot.lower_limits.tolist(), robot.upper_limits.tolist()
        style = {"description_width": "initial"}
        layout = W.Layout(width="420px")
        self.sliders = {
            name: W.FloatSlider(value=float(v), min=a, max=b, step=0.01, description=name, style=style, layout=layout, continuous_update=True)
            for name, v, a, b in zip(robot.joint_names, q0.tolist(), lo, hi, strict=True)
        }
        links = sorted(robot.forward_kinematics(q0[None]).keys())
        default = link or robot.arm("left").wrist
        if default not in links:
            raise SettingsError(f"robot {robot.name!r} has no link {default!r}")
        self.link = W.Dropdown(options=links, value=default, description="link")
        self.readout = W.HTML()
        self.status = W.HTML()
        self.error = ""
        self._view = View(view, height)
        self.scene = None
        if self._view.vis is not None:
            with self._view.hold():
                self._view.vis.delete()
                self.scene = RobotScene(self._view.vis, robot).draw()
                # Frame on the rest pose and both limit extremes, so slider moves mostly stay in view.
                poses = torch.stack([robot.neutral_q, robot.lower_limits, robot.upper_limits])
                style_viewer(self._view.vis, camera=frame_points(self.scene.extent_points(poses.numpy())))
        update = guarded(self, self._update)
        for s in self.sliders.values():
            s.observe(update, names="value")
        self.link.observe(update, names="value")
        self._update()
        sliders = W.VBox(list(self.sliders.values()), layout=W.Layout(max_height=f"{height}px", overflow="auto", flex="0 0 440px"))
        parts = [sliders]
        if self._view.widget is not None:
            parts.append(W.Box([self._view.widget], layout=W.Layout(flex="1 1 360px", min_width="320px")))
        self.widget = W.VBox([W.HBox(parts, layout=W.Layout(flex_flow="row wrap", width="100%")), W.HBox([self.link, self.readout]), self.status])

    @property
    def q(self) -> np.ndarray:
        """Current joint angles ``(n,)`` [rad]."""
        return np.array([s.value for s in self.sliders.values()], dtype=np.float64)

    def _update(self, change=None) -> None:
        q = torch.as_tensor(self.q, dtype=self.robot.lower_limits.dtype)[None]
        with torch.no_grad():
            T = self.robot.forward_kinematics(q)[self.link.value][0].cpu().double().numpy()  # (4, 4) T_world_link
        self.pose = T
        self.position = T[:3, 3].copy()
        x, y, z = self.position
        self.readout.value = f"<code>{self.link.value}</code>: position [m] x={x:+.3f} y={y:+.3f} z={z:+.3f}"
        if self.scene is not None:
            with self._view.hold():
                self.scene.set_pose(self.q)

    def _repr_mimebundle_(self, **kwargs):
        self._view.sync()
        return self.widget._repr_mimebundle_(**kwargs)

"""The hand weights on sliders and one handshape in close-up (notebook 12).

:class:`HandPanel` retargets one frame of a demonstration (a fingerspelled letter) with the
weights the sliders show, then draws the robot in a 3-D view framed on one hand, the human
hand's landmarks (at the robot hand's size, in the robot's wrist frame) beside it, and the
frame's hand measures (:mod:`nlo_lab.evaluation.hands`). A plain object that tests drive
headlessly: set ``panel.controls[name].value`` and read ``panel.q``, ``panel.measures``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.evaluation.hands import hand_scores
from nlo_lab.human import FINGERS
from nlo_lab.inference import HANDSHAPE_SEARCH, OptimizeSettings
from nlo_lab.lab.views import View, guarded
from nlo_lab.model import load_pretrained
from nlo_lab.objective import HAND_TERMS, LossWeights, point_plan, targets_from_demonstration
from nlo_lab.pipeline import RetargetConfig, hand_search
from nlo_lab.viz import RobotScene, frame_points, style_viewer
from nlo_lab.viz.tracks import translation

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.model import RetargetModel
    from nlo_lab.robot import Robot

__all__ = ["HandPanel", "HAND_SLIDERS"]

HAND_SLIDERS = ("finger", *HAND_TERMS)  # the weights on the panel: finger base -> tip and the hand terms


class HandPanel:
    """Sliders for the hand weights, the fingers the hand stage searches, a frame (letter) chooser, and a
    close-up of one robot hand.

    Args:
        demo: a :class:`~nlo_lab.human.Demonstration` (its ``meta["letters"]`` name the frames, if present).
        robot: a loaded robot with fingers (YuMi).
        model: its trained model (default: the shipped checkpoint).
        weights: the start weights (default ``LossWeights()``; ``smooth`` is set to 0: one frame).
        frame: the frame shown first.
        side: ``"right"`` or ``"left"``: the hand in close-up.
        iterations: latent optimisation steps per update.
        search: the fingers the hand stage searches first (default None: the pipeline's, those of ``HAND_SEARCH``
            the robot's hands move alone; ``HANDSHAPE_SEARCH`` with ``LossWeights.handshape()`` is the handshape preset).
        view: ``"auto"`` (a 3-D widget), None (no view: tests) or a meshcat ``Visualizer``.
        height: 3-D view height [px].

    Attributes:
        controls: widgets: a slider per weight of ``HAND_SLIDERS``, ``"search"`` (the fingers whose motor the hand
            stage searches first: :attr:`OptimizeSettings.hand_search <nlo_lab.inference.OptimizeSettings.hand_search>`)
            and ``"frame"``.
        preset: a button that sets the handshape preset (:meth:`LossWeights.handshape
            <nlo_lab.objective.LossWeights.handshape>` and :data:`~nlo_lab.inference.HANDSHAPE_SEARCH`), one update;
            :meth:`use_weights` does the same for any weights and fingers.
        q: ``(n,)`` the robot's angles for the shown frame [rad]; measures: its hand measures (dict).
        error: the last callback error shown in the panel's status line ("" when the last update worked).
    """

    def __init__(self, demo, robot: Robot, model: RetargetModel | None = None, weights: LossWeights | None = None, frame: int = 0, side: str = "right",
                 iterations: int = 60, view: Any = "auto", height: int = 380, search: Sequence[str] | None = None):
        # lazy: a kernel's widgets: only when a panel is built
        import ipywidgets as W

        if not robot.has_fingers:
            raise SettingsError(f"{robot.name} has no fingers: the hand panel needs a robot with hands (yumi)")
        if side not in ("left", "right"):
            raise SettingsError(f"side must be 'left' or 'right', got {side!r}")
        if not 0 <= frame < len(demo):
            raise SettingsError(f"frame {frame} is outside 0..{len(demo) - 1}")
        if search is None:
            search = hand_search(robot, OptimizeSettings())
        search = OptimizeSettings(hand_search=tuple(search)).hand_search  # a finger unknown or named twice: refused here
        if model is None:
            model = load_pretrained(robot)
        self.demo, self.robot, self.model, self.side = demo, robot, model, side
        self.iterations = int(iterations)
        self.base_weights = weights or LossWeights()
        style = {"description_width": "60px"}
        self.controls: dict[str, Any] = {
            name: W.FloatLogSlider(value=max(getattr(self.base_weights, name), 0.1), base=10, min=-1, max=4, step=0.05,
                                   description=name, style=style, continuous_update=False)
            for name in HAND_SLIDERS
        }
        self.controls["search"] = W.SelectMultiple(options=list(FINGERS), value=search, rows=len(FINGERS), description="search",
                                                   style=style, layout=W.Layout(width="180px"))
        labels = demo.meta.get("letters") or [str(t) for t in range(len(demo))]
        self.controls["frame"] = W.Dropdown(options=[(str(label), t) for t, label in enumerate(labels)], value=frame,
                                            description="frame", style=style)
        self.readout = W.HTML()
        self.status = W.HTML()  # an update's error (lab.views.guarded writes it)
        self.preset = W.Button(description="handshape preset", tooltip="LossWeights.handshape() and the search of HANDSHAPE_SEARCH")
        self.error = ""
        self._holding = False  # use_weights: several controls set, one update
        self.q = np.zeros(robot.n_joints)
        self.measures: dict[str, float] = {}
        self._view = View(view, height)
        self._camera = None
        update = guarded(self, self.update)
        for control in self.controls.values():
            control.observe(lambda change: None if self._holding else update(change), names="value")
        use_weights = guarded(self, self.use_weights)
        self.preset.on_click(lambda _: use_weights(LossWeights.handshape(), HANDSHAPE_SEARCH))
        self.update()
        left = W.VBox([*self.controls.values(), self.preset, self.readout, self.status], layout=W.Layout(flex="0 0 300px"))
        parts = [left] + ([W.Box([self._view.widget], layout=W.Layout(flex="1 1 380px"))] if self._view.widget is not None else [])
        self.widget = W.HBox(parts, layout=W.Layout(flex_flow="row wrap", width="100%"))

    @property
    def frame(self) -> int:
        return int(self.controls["frame"].value)

    @property
    def weights(self) -> LossWeights:
        """The base weights with the sliders' hand weights (smoothness 0: one frame has no neighbours)."""
        values = self.base_weights.as_dict() | {n: float(self.controls[n].value) for n in HAND_SLIDERS}
        return LossWeights(**(values | {"smooth": 0.0}))

    @property
    def settings(self) -> OptimizeSettings:
        """The optimisation's settings: the panel's iterations and the fingers the hand stage searches."""
        return OptimizeSettings(iterations=self.iterations, hand_search=tuple(self.controls["search"].value))

    def use_weights(self, weights: LossWeights, search: tuple[str, ...] = ()) -> None:
        """Set the sliders to ``weights``' hand weights (each within its slider's range) and the searched fingers to
        ``search``, then retarget once (not once per control). A finger unknown or named twice is refused before
        any control is set, as by the constructor."""
        search = OptimizeSettings(hand_search=tuple(search)).hand_search
        self._holding = True
        try:
            for name in HAND_SLIDERS:
                self.controls[name].value = getattr(weights, name)
            self.controls["search"].value = tuple(search)
        finally:
            self._holding = False
        self.update()

    def update(self, change=None) -> None:
        """Retarget the chosen frame with the sliders' weights; show the robot, the human hand and the measures."""
        t = self.frame
        one = self.demo.slice(t, t + 1)
        config = RetargetConfig(self.robot, settings=self.settings, weights=self.weights,
                                model=self.model, retime=False)
        self.q = np.array(config.build()(one).trajectory.angles[0], dtype=np.float64)  # a copy: the trajectory's is read-only
        scores = hand_scores(self.robot, self.q[None], one)
        s = 1 if self.side == "right" else 0
        pick = scores.side == s
        self.measures = {"tip_deg": float(scores.tip[pick].mean()) if pick.any() else float("nan"),
                         "thumb_deg": float(scores.thumb[pick].mean()) if pick.any() else float("nan"),
                         "finger_deg": float(scores.finger[pick].mean()) if pick.any() else float("nan"),
                         "pinch_human": float(scores.pinch_human[pick].mean()) if pick.any() else float("nan"),
                         "pinch_robot": float(scores.pinch_robot[pick].mean()) if pick.any() else float("nan")}
        m = self.measures
        self.readout.value = (f"<b>{self.side} hand</b>: wrist→tip {m['tip_deg']:.1f}°, thumb→tips {m['thumb_deg']:.1f}°, "
                              f"base→tip {m['finger_deg']:.1f}°<br>thumb–index distance: human {m['pinch_human']:.2f}, "
                              f"robot {m['pinch_robot']:.2f} hand lengths")
        self._draw(one)

    def human_hand(self, one) -> np.ndarray:
        """``(6, 3)`` the human's wrist and fingertips of the chosen frame, in the robot's world, at the
        robot hand's size: where the robot hand would put them."""
        s = 1 if self.side == "right" else 0
        plan = point_plan(self.robot, self.robot.lower_limits.dtype)
        scale = float(plan.hand_length[s]) / float(targets_from_demonstration(one).hand_length[0, s])
        wrist, rot = one.arm_positions[0, s, 2], one.wrist_rotations[0, s]
        local = (np.concatenate([wrist[None], one.finger_positions[0, s, :, 1]]) - wrist) @ rot * scale  # human wrist frame
        arm = self.robot.arm(self.side)
        with torch.no_grad():
            poses = self.robot.forward_kinematics(torch.as_tensor(self.q[None], dtype=self.robot.lower_limits.dtype))
        T = poses[arm.wrist][0].double().numpy()
        R = T[:3, :3] @ arm.wrist_alignment.double().numpy()  # the robot's wrist frame
        return T[:3, 3] + local @ R.T

    def _draw(self, one) -> None:
        vis = self._view.vis
        if vis is None:
            return
        # lazy: meshcat's scene classes: only when a view is drawn
        import meshcat.geometry as g

        with self._view.hold():
            if self._camera is None:
                vis.delete()
                self.scene = RobotScene(vis, self.robot).draw()
            self.scene.set_pose(self.q)
            human = self.human_hand(one)
            offset = np.array([0.0, 0.0, 0.22])  # the human hand above the robot's, to compare
            for i, p in enumerate(human):
                node = vis["human_hand"][f"p{i}"]
                node.set_object(g.Sphere(0.006 if i else 0.01), g.MeshLambertMaterial(color=0xD62728))
                node.set_transform(translation(p + offset))
            if self._camera is None:
                pts = np.concatenate([human, human + offset])
                self._camera = frame_points(pts, fill=0.5)
                style_viewer(vis, camera=self._camera)

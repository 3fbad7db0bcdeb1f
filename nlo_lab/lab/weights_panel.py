"""The loss weights on sliders, for one frame: the pose they give and their terms, drawn.

:class:`WeightsPanel` (notebook 03) has one log slider per term of the objective. Releasing a
slider optimises the frame again in joint space (:func:`nlo_lab.inference.optimize_joints`,
the same start and budget every time) with the new weights: the 3-D view shows the new pose
beside the human, a bar chart the weighted terms at that pose. A plain object that tests
drive headlessly: set ``panel.sliders[name].value`` and read ``panel.q``, ``panel.terms``,
``panel.total`` (observers fire as in the browser); ``panel.chart.value`` is the chart (PNG).
"""

from __future__ import annotations

import dataclasses
import html
import io
from typing import TYPE_CHECKING, Any

import torch

from nlo_lab.errors import SettingsError
from nlo_lab.inference import JointOptimizeSettings, optimize_joints
from nlo_lab.lab.views import View, guarded
from nlo_lab.objective import TERMS, LossWeights, objective
from nlo_lab.viz import RetargetScene, plot_loss_terms

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["WeightsPanel"]


class WeightsPanel:
    """One frame optimised in joint space again whenever a loss weight moves; its pose and terms drawn.

    Args:
        robot: a loaded ``nlo_lab.robot.Robot``.
        targets: the ``Targets`` of one frame (``targets.index(slice(t, t + 1))``).
        demo: that frame of the human ``Demonstration``, shown beside the robot (optional).
        weights: the start weights (``LossWeights``; the paper's by default).
        iterations: Adam steps of each optimisation (from the robot's neutral pose).
        view: ``"auto"``, None or a meshcat ``Visualizer``.
        height: 3-D view height [px].

    Attributes:
        sliders: ``{term: FloatLogSlider}`` (0.1 to 10,000; updates when released).
        chart: ``Image`` widget: the weighted terms at the current pose (PNG).
        q: ``(n,)`` the current pose [rad]; ``terms``: ``{term: unweighted value}`` there; ``total``: the weighted total.
        history: the loss history of the last optimisation.
        error: the last callback error shown in the panel ("" when the last update worked).
    """

    def __init__(self, robot: Robot, targets, demo=None, *, weights=None, iterations: int = 100, view: Any = "auto",
                 height: int = 360):
        # lazy: a kernel's widgets: only when a panel is built
        import ipywidgets as W

        if len(targets) != 1:
            raise SettingsError(f"WeightsPanel optimises one frame; got targets of {len(targets)} frames")
        if demo is not None and len(demo) != 1:
            raise SettingsError(f"demo must be the one frame of the targets; got {len(demo)} frames")
        if int(iterations) < 1:
            raise SettingsError(f"iterations must be >= 1, got {iterations!r}")
        self.robot, self.targets, self.iterations = robot, targets, int(iterations)
        start = weights if weights is not None else LossWeights()
        self.sliders = {
            name: W.FloatLogSlider(value=float(getattr(start, name)), base=10, min=-1, max=4, step=0.1, description=name,
                                   continuous_update=False, readout_format=".3g")
            for name in TERMS
        }
        self._base = start
        self.chart = W.Image(format="png", layout=W.Layout(width="420px"))
        self.status = W.HTML()
        self.error = ""
        self._view = View(view, height)
        self.scene = None
        self._optimise()
        if self._view.vis is not None:
            with self._view.hold():
                self._view.vis.delete()
                self.scene = RetargetScene(self._view.vis, robot, self.q[None], demo=demo)
        update = guarded(self, self._update)
        for slider in self.sliders.values():
            slider.observe(update, names="value")
        self._draw()
        parts = [W.VBox([*self.sliders.values(), self.chart], layout=W.Layout(flex="0 0 440px"))]
        if self._view.widget is not None:
            parts.append(W.Box([self._view.widget], layout=W.Layout(flex="1 1 360px", min_width="320px")))
        self.widget = W.VBox([W.HBox(parts, layout=W.Layout(flex_flow="row wrap", width="100%")), self.status])

    @property
    def weights(self):
        """The ``LossWeights`` the sliders hold (the other weights as given)."""
        return dataclasses.replace(self._base, **{name: float(s.value) for name, s in self.sliders.items()})

    def _optimise(self) -> None:
        weights = self.weights
        settings = JointOptimizeSettings(iterations=self.iterations, patience=self.iterations)
        result = optimize_joints(self.robot, self.targets, settings, weights=weights, fast=True)  # a slider answers quickly
        q = result.q.detach()
        with torch.no_grad():
            total, terms = objective(self.robot, q, self.targets, weights)
        self.q = q[0].cpu().double().numpy()
        self.history = list(result.history)
        self.total = float(total.sum())
        self.terms = {name: float(value.sum()) for name, value in terms.items()}

    def _draw(self) -> None:
        # lazy: matplotlib: only when a figure is drawn
        from matplotlib.figure import Figure

        weights = self.weights.as_dict()
        fig = Figure(figsize=(4.4, 2.6), dpi=100)
        plot_loss_terms(self.terms, ax=fig.add_subplot(), weights=weights, title=f"weighted terms at this pose (total {self.total:.3g})")
        fig.tight_layout()
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png")
        self.chart.value = buffer.getvalue()
        shares = "  ".join(f"{name} {weights[name] * v / self.total:.0%}" for name, v in self.terms.items()) if self.total > 0 else ""
        self.status.value = f"<code>{html.escape(shares)}</code>"

    def _update(self, change=None) -> None:
        self._optimise()
        if self.scene is not None:
            with self._view.hold():
                self.scene.set_angles(self.q, 0)
        self._draw()

    def _repr_mimebundle_(self, **kwargs):
        self._view.sync()
        return self.widget._repr_mimebundle_(**kwargs)

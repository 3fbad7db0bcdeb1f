"""The retargeting panel: the method's controls and its result, live.

:class:`RetargetPanel`: loss weights (log sliders), initialisation strategy,
  iteration budget, robot, a frame scrubber with play, a convergence plot and
  a 3-D view. Moving a control re-optimises the *current* frame (one frame,
  at most ``frame_iterations`` steps, warm-started from its latent; a new
  initialisation or budget restarts the frame from that initialisation); the
  button re-optimises the whole sequence.

State for tests and notebooks: ``panel.q`` (current joint angles), ``panel.history``
(the loss history shown), ``panel.weights``, ``panel.angles``; set a control with
``panel.controls[name].value = ...`` (observers fire as in the browser).

The 3-D view is optional and injectable: ``view="auto"`` gives the panel its own
scene (:class:`nlo_lab.viz.SceneWidget`, meshcat's viewer over the notebook's
connection; a move sends only the transforms that changed), ``None`` none, or
pass a meshcat ``Visualizer``. An error in a control's callback is shown in the
panel (``panel.error``, the status line, the view) and raised.

The panel lays out as a wrapping row: the controls keep their width and the view
goes below them when the notebook is too narrow for both side by side.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.inference import INITS, OptimizeResult, OptimizeSettings, RetargetInputs, retime_times
from nlo_lab.lab.views import View, guarded, svg_convergence
from nlo_lab.model import load_pretrained
from nlo_lab.objective import TERMS, LossWeights, Targets
from nlo_lab.paths import BUNDLED_ROBOTS
from nlo_lab.pipeline import RetargetConfig, Retargeter
from nlo_lab.robot import load_robot
from nlo_lab.settings import LATENT_ITERATIONS
from nlo_lab.threads import single_thread
from nlo_lab.viz import RetargetScene
from nlo_lab.viz.tracks import set_key_times, tick_ms

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.model import RetargetModel

__all__ = ["RetargetPanel"]


class RetargetPanel:
    """Interactive latent optimisation of a demonstration on a robot.

    Args:
        demo: the human ``Demonstration``.
        robot: ``"yumi"``, ``"nao"``, ``"pepper"`` (or a loaded ``Robot``).
        model: the model for ``robot``; by default ``model_loader(robot)``.
        model_loader: ``robot -> model`` used on a robot change (default: the shipped checkpoints,
            ``nlo_lab.model.load_pretrained``).
        weights: start loss weights (the paper's by default).
        init: start initialisation strategy (one of ``nlo_lab.inference.INITS``).
        iterations: iteration budget of a cold start (the init/budget controls) and of the sequence button.
        frame_iterations: at most this many steps when a control re-optimises the current frame warm-started.
        frame: the start frame.
        view: ``"auto"``, None or a meshcat ``Visualizer``.
        height: 3-D view height [px].
        max_curves: earlier convergence curves kept (faded) in the plot for comparison.

    Attributes:
        controls: ``{"ee", "ori", "elbow", "finger", "collision", "init", "iterations", "robot", "frame"}`` widgets.
        play: the ``Play`` widget linked to the frame slider. With a view, playing runs in the browser:
            the clip as optimised so far becomes a meshcat animation (no kernel round trip per frame) on
            the time base the robot would play it: the recording's rate, slowed where a joint would
            exceed its velocity limit (:meth:`play_times`, as ``retarget`` retimes); stopping shows the
            slider's frame again. Play ticks at that time base's mean frame period (the slider ends with the
            animation); without a view it shows the frames as optimised (no re-optimisation) at that rate.
        button: re-optimises the whole sequence.
        plot: ``HTML`` widget with the convergence plot (SVG; ``plot_data`` holds its curves).
        angles: ``(T, n)`` current joint angles of every frame [rad].
        latents: ``(T, N_r, k)`` current latents.
        history: the loss history of the last optimisation (shown in the plot).
        curves: ``[(label, history)]`` shown in the plot (the last one is ``history``).
        last: the last :class:`OptimizeResult`.
        last_seconds: wall time of the last optimisation [s].
        error: the last callback error shown in the panel ("" when the last update worked).
    """

    def __init__(
        self,
        demo,
        robot: Any = "yumi",
        *,
        model: RetargetModel | None = None,
        model_loader: Callable[[Any], Any] | None = None,
        weights: LossWeights | None = None,
        init: str = "encoder",
        iterations: int = LATENT_ITERATIONS,
        frame_iterations: int = 30,
        frame: int = 0,
        view: Any = "auto",
        height: int = 360,
        max_curves: int = 5,
    ):
        # lazy: a kernel's widgets: only when a panel is built
        import ipywidgets as W

        if init not in INITS:
            raise SettingsError(f"unknown init {init!r}; expected one of {', '.join(INITS)}")
        if len(demo) == 0:
            raise SettingsError("the demonstration has no frames")
        if not 0 <= frame < len(demo):
            raise SettingsError(f"frame {frame} is outside 0..{len(demo) - 1}")
        if model_loader is None:
            model_loader = load_pretrained
        self.demo = demo
        self.model_loader = model_loader
        self.frame_iterations = int(frame_iterations)
        self.max_curves = int(max_curves)
        self._models: dict[str, tuple[Any, Any]] = {}
        robot_obj = self._robot(robot)
        if model is not None:
            self._models[robot_obj.name] = (robot_obj, model)
        weights = weights or LossWeights()
        style = {"description_width": "80px"}
        self.controls: dict[str, Any] = {
            name: W.FloatLogSlider(value=max(getattr(weights, name), 0.1), base=10, min=-1, max=4.5, step=0.05, description=name, style=style, continuous_update=False)
            for name in TERMS
        }
        self._latent_weight = weights.latent
        # smoothness over consecutive frames: acts in "re-optimise the whole sequence" (one frame has no neighbours)
        self.controls["smooth"] = W.FloatSlider(value=weights.smooth, min=0.0, max=100.0, step=1.0, description="smooth", style=style, continuous_update=False)
        names = list(BUNDLED_ROBOTS) + ([robot_obj.name] if robot_obj.name not in BUNDLED_ROBOTS else [])
        self.controls["init"] = W.Dropdown(options=list(INITS), value=init, description="init", style=style)
        self.controls["iterations"] = W.IntSlider(value=iterations, min=0, max=300, step=5, description="iterations", style=style, continuous_update=False)
        self.controls["robot"] = W.Dropdown(options=names, value=robot_obj.name, description="robot", style=style)
        self.controls["frame"] = W.IntSlider(value=frame, min=0, max=len(demo) - 1, description="frame", style=style)
        self.play = W.Play(value=frame, min=0, max=len(demo) - 1, interval=50, description="play")
        W.link((self.play, "value"), (self.controls["frame"], "value"))  # kernel-side link: works headless too
        self.button = W.Button(description="re-optimise the whole sequence", layout=W.Layout(width="260px"))
        self.plot = W.HTML()
        self.status = W.HTML()
        self.error = ""
        self._view = View(view, height)
        self.scene = None
        self._shown_frame = -1
        self.curves: list[tuple[str, list[float]]] = []
        self.history: list[float] = []
        self.last: OptimizeResult | None = None
        self.last_seconds = 0.0
        self._busy = False
        self._set_robot(robot_obj.name)

        warm = guarded(self, lambda ch: self.reoptimise_frame(warm=True))
        cold = guarded(self, lambda ch: self.reoptimise_frame(warm=False))
        for name in TERMS:
            self.controls[name].observe(warm, names="value")
        self.controls["init"].observe(cold, names="value")
        self.controls["iterations"].observe(cold, names="value")
        self.controls["frame"].observe(guarded(self, self._frame_changed), names="value")
        self.play.observe(guarded(self, self._playing_changed), names="playing")
        self.controls["robot"].observe(guarded(self, lambda ch: self._set_robot(ch["new"])), names="value")
        self.button.on_click(guarded(self, lambda b: self.optimise_sequence()))

        weights_box = W.VBox([self.controls[n] for n in (*TERMS, "smooth")], layout=W.Layout(flex="0 0 auto"))
        setup_box = W.VBox([self.controls[n] for n in ("robot", "init", "iterations")] + [self.button], layout=W.Layout(flex="0 0 auto"))
        frames = W.HBox([self.play, self.controls["frame"]])
        left = W.VBox([W.HBox([weights_box, setup_box], layout=W.Layout(flex_flow="row wrap")), frames, self.status, self.plot], layout=W.Layout(flex="0 1 auto"))
        parts = [left]
        if self._view.widget is not None:
            parts.append(W.Box([self._view.widget], layout=W.Layout(flex="1 1 420px", min_width="320px")))
        self.widget = W.HBox(parts, layout=W.Layout(flex_flow="row wrap", width="100%"))

    # ----------------------------------------------------------- state
    @property
    def robot(self):
        return self._models[self.controls["robot"].value][0]

    @property
    def model(self):
        return self._models[self.controls["robot"].value][1]

    @property
    def frame(self) -> int:
        return int(self.controls["frame"].value)

    @property
    def weights(self) -> LossWeights:
        """The weights the sliders show (``latent`` as given at construction)."""
        return LossWeights(**{n: float(self.controls[n].value) for n in TERMS}, latent=self._latent_weight,
                           smooth=float(self.controls["smooth"].value))

    def settings(self, iterations: int | None = None) -> OptimizeSettings:
        """Optimisation settings from the controls."""
        its = int(self.controls["iterations"].value) if iterations is None else int(iterations)
        return OptimizeSettings(init=self.controls["init"].value, iterations=its)

    def retargeter(self, iterations: int | None = None) -> Retargeter:
        """The retargeting pipeline with the controls' settings and weights (the whole sequence as one batch)."""
        config = RetargetConfig(self.robot, self.settings(iterations), self.weights, model=self.model, chunk_frames=None)
        return config.build()

    @property
    def targets(self) -> Targets:
        """The demonstration as the objective compares it, in the robot's dtype."""
        return self.inputs.targets

    @property
    def q(self) -> np.ndarray:
        """Joint angles ``(n,)`` of the current frame [rad]."""
        return self.angles[self.frame].copy()

    # ----------------------------------------------------------- actions
    def _robot(self, robot):
        if not isinstance(robot, str):
            self._models.setdefault(robot.name, (robot, None))
            return robot
        if robot in self._models:
            return self._models[robot][0]

        r = load_robot(robot)
        self._models[r.name] = (r, None)
        return r

    def _set_robot(self, name: str) -> None:
        robot = self._robot(name)
        if self._models[name][1] is None:
            self._models[name] = (robot, self.model_loader(robot))
        retargeter = self.retargeter()
        self.inputs: RetargetInputs = retargeter.inputs(self.demo)
        with torch.no_grad():
            self.latents = retargeter.start(self.inputs).clone()
            self.angles = self.model.decode(self.latents).to(robot.lower_limits.dtype).cpu().double().numpy()  # (T, n)
        self.curves = []
        if self._view.vis is not None:
            with self._view.hold():
                self._view.vis.delete()
                self.scene = RetargetScene(self._view.vis, robot, self.angles, demo=self.demo)
                self._shown_frame = 0
        self.reoptimise_frame(warm=True)

    def _frame_changed(self, change=None) -> None:
        """A new frame: re-optimise it; while Play plays, the page animates (or, without a widget view, show the frame)."""
        if not self.play.playing:
            self.reoptimise_frame(warm=True)
        elif self._view.widget is None:
            self._show_frame(self.frame)

    def _playing_changed(self, change) -> None:
        """Play starts: the clip plays as a meshcat animation in the page. Play stops: back to the slider's frame."""
        # lazy: meshcat's scene classes: only when a view is drawn
        from meshcat.animation import Animation

        times = self.play_times()  # what the robot would play, not the recording's rate
        self.play.interval = tick_ms(times)  # one time base: the slider ends with the page's animation
        if self.scene is None or self._view.widget is None:
            return
        with self._view.hold():
            if change["new"]:
                anim = self.scene.animation()
                set_key_times(anim, times)
                self._view.vis.set_animation(anim, play=True, repetitions=0)
            else:
                self._view.vis.set_animation(Animation(), play=False)  # stops the page's animation
                with self._view.widget.resend():
                    self.scene.set_frame(self.frame)
                self._shown_frame = self.frame

    def play_times(self) -> np.ndarray:
        """``(T,)`` times [s] at which Play shows the frames: the current angles retimed to the robot's
        velocity limits (:func:`nlo_lab.inference.retime_times`, as :func:`nlo_lab.pipeline.retarget` does)."""
        return retime_times(self.angles, self.demo.fps, self.robot.velocity_limits.double().numpy())

    def reoptimise_frame(self, warm: bool = True) -> OptimizeResult:
        """Re-optimise the current frame and update the plot and the view.

        Args:
            warm: start from the frame's current latent with at most
                ``frame_iterations`` steps; else start from the chosen
                initialisation with the full iteration budget.
        """
        t = self.frame
        budget = int(self.controls["iterations"].value)
        iterations, z0 = (min(self.frame_iterations, budget), self.latents[t : t + 1]) if warm else (budget, None)
        retargeter = self.retargeter(iterations)
        settings = retargeter.settings
        with single_thread():
            start = time.perf_counter()
            result = retargeter.optimize_frame(self.inputs, t, z0)
            self.last_seconds = time.perf_counter() - start
        self.latents[t] = result.z[0].detach()
        self.angles[t] = result.q[0].detach().cpu().double().numpy()
        label = f"frame {t}: {'warm' if warm else settings.init}, {result.iterations} it"
        self._show(result, label)
        return result

    def optimise_sequence(self) -> OptimizeResult:
        """Optimise every frame from the chosen initialisation with the full budget (the button)."""
        retargeter = self.retargeter()
        settings = retargeter.settings
        live_every = 10

        def progress(it: int, loss: float) -> None:  # a live curve while the sequence runs
            if it % live_every == 0 and it > 0:
                self._draw(self.curves + [("sequence (running)", running + [loss])])
            running.append(loss)

        running: list[float] = []
        start = time.perf_counter()
        result = retargeter.optimize(self.inputs, callback=progress)
        self.last_seconds = time.perf_counter() - start
        self.latents = result.z.detach().clone()
        self.angles = result.q.detach().cpu().double().numpy()
        if self.scene is not None:
            self.scene.angles[:] = self.angles
        self._show(result, f"sequence: {settings.init}, {result.iterations} it")
        return result

    # ----------------------------------------------------------- display
    def _show(self, result: OptimizeResult, label: str) -> None:
        self.last = result
        self.history = list(result.history)
        self.curves = (self.curves + [(label, self.history)])[-self.max_curves :]
        t = self.frame
        terms = ", ".join(f"{k} {float(v.mean()):.3g}" for k, v in result.terms.items())
        self.status.value = (
            f"<b>{label}</b>: loss {self.history[0]:.4g} → {min(self.history):.4g} in "
            f"{self.last_seconds * 1000:.0f} ms<br><small>terms: {terms}</small>"
        )
        self._draw(self.curves)
        self._show_frame(t)

    def _show_frame(self, t: int) -> None:
        """Frame ``t`` in the view: the robot's new pose, and the human only when the frame changed."""
        if self.scene is None:
            return
        with self._view.hold():
            self.scene.angles[t] = self.angles[t]
            if t == self._shown_frame:
                self.scene.set_angles(self.angles[t])
            else:
                self.scene.set_frame(t)
                self._shown_frame = t

    def _draw(self, curves) -> None:
        self.plot_data = [(label, list(h)) for label, h in curves]
        self.plot.value = svg_convergence(self.plot_data)

    def _repr_mimebundle_(self, **kwargs):
        self._view.sync()
        return self.widget._repr_mimebundle_(**kwargs)

"""ipywidgets panels of the notebooks, plain objects that tests drive headlessly.

* :class:`JointPanel`: one slider per joint drives the robot; the pose of a chosen link (FK).
* :class:`RetargetPanel`: loss weights (log sliders), initialisation strategy,
  iteration budget, robot, a frame scrubber with play, a convergence plot and
  a 3-D view. Moving a control re-optimises the *current* frame (one frame,
  at most ``frame_iterations`` steps, warm-started from its latent; a new
  initialisation or budget restarts the frame from that initialisation); the
  button re-optimises the whole sequence.

State for tests and notebooks: ``panel.q`` (current joint angles), ``panel.history``
(the loss history shown), ``panel.weights``, ``panel.angles``; set a control with
``panel.controls[name].value = ...`` (observers fire as in the browser).

The 3-D view is optional and injectable: ``view="auto"`` uses the notebook's
live viewer (:func:`nlo_lab.notebook.viewer`) or the static page, ``"static"``
only the static page, ``None`` none, or pass a meshcat ``Visualizer``.
"""

from __future__ import annotations

import html
import time
from typing import Any, Callable

import numpy as np
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.losses import TERMS, LossWeights, Targets, targets_from_demonstration
from nlo_lab.optimize import INITS, OptimizeResult, OptimizeSettings, initial_latent, optimize_latent
from nlo_lab.threads import single_thread

__all__ = ["ROBOTS", "JointPanel", "RetargetPanel", "single_thread", "svg_convergence"]

ROBOTS = ("yumi", "nao", "pepper")


_PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b")


def svg_convergence(curves, width: int = 480, height: int = 220, log: bool = True) -> str:
    """A small SVG line plot of loss histories (cheap enough to redraw on every slider move).

    Args:
        curves: ``[(label, (iterations,) losses)]``; the last one is drawn bold.
        width, height: size [px].
        log: logarithmic loss axis when every value is > 0.

    Returns:
        The ``<svg>`` markup (for an ``ipywidgets.HTML``).
    """
    left, right, top, bottom = 58, 10, 10, 34
    w, h = width - left - right, height - top - bottom
    ys = [np.asarray(c, dtype=np.float64).reshape(-1) for _, c in curves]
    ys = [y[np.isfinite(y)] for y in ys]
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" font-size="10">',
             f'<rect x="{left}" y="{top}" width="{w}" height="{h}" fill="white" stroke="#999"/>']
    if any(y.size for y in ys):
        allv = np.concatenate([y for y in ys if y.size])
        use_log = log and bool((allv > 0).all())
        f = np.log10 if use_log else (lambda v: v)
        lo, hi = float(f(allv.min())), float(f(allv.max()))
        if hi - lo < 1e-12:
            lo, hi = lo - 0.5, hi + 0.5
        n = max(max(y.size for y in ys) - 1, 1)
        for k, (label, _) in enumerate(curves):
            y = ys[k]
            if not y.size:
                continue
            px = left + w * np.arange(y.size) / n
            py = top + h * (1 - (f(y) - lo) / (hi - lo))
            pts = " ".join(f"{a:.1f},{b:.1f}" for a, b in zip(px, py))
            last = k == len(curves) - 1
            colour = _PALETTE[k % len(_PALETTE)]
            parts.append(f'<polyline points="{pts}" fill="none" stroke="{colour}" stroke-width="{2.2 if last else 1.2}" opacity="{1 if last else 0.5}"/>')
            if y.size == 1:
                parts.append(f'<circle cx="{px[0]:.1f}" cy="{py[0]:.1f}" r="3" fill="{colour}"/>')
            parts.append(f'<text x="{left + w - 4}" y="{top + 12 + 12 * k}" text-anchor="end" fill="{colour}">{html.escape(str(label))}</text>')
        for v, yy in ((hi, top), (lo, top + h)):
            text = f"{10 ** v:.3g}" if use_log else f"{v:.3g}"
            parts.append(f'<text x="{left - 4}" y="{yy + 4}" text-anchor="end">{text}</text>')
        parts.append(f'<text x="{left}" y="{height - 18}">0</text><text x="{left + w}" y="{height - 18}" text-anchor="end">{n}</text>')
    parts.append(f'<text x="{left + w / 2}" y="{height - 4}" text-anchor="middle">iteration</text>')
    parts.append(f'<text x="12" y="{top + h / 2}" text-anchor="middle" transform="rotate(-90 12 {top + h / 2})">loss{" (log)" if ys and any(y.size for y in ys) and use_log else ""}</text>')
    parts.append("</svg>")
    return "".join(parts)


class _View:
    """A 3-D view for a panel: a meshcat ``Visualizer`` plus, when shown in the notebook, an HTML widget."""

    def __init__(self, view: Any, height: int):
        import ipywidgets as W

        self.height = height
        self.static = False
        self.widget = None
        self.vis = None
        if view is None or view is False:
            return
        if view in ("auto", "static"):
            from nlo_lab.notebook import viewer

            live = viewer() if view == "auto" else None
            if live is not None:
                self.vis = live.vis
                self.widget = W.HTML(live.jupyter_cell(height=height).data)
            else:
                from nlo_lab.viz import recording_visualizer

                self.vis = recording_visualizer()
                self.static = True
                self.widget = W.HTML()
        elif hasattr(view, "__getitem__") and hasattr(view, "delete"):
            self.vis = view  # an injected meshcat Visualizer (live or recording)
        else:
            raise SettingsError(f"view must be 'auto', 'static', None or a meshcat Visualizer, got {view!r}")

    def refresh(self) -> None:
        """Re-render the static page (the live viewer updates by itself)."""
        if self.static and self.widget is not None:
            from nlo_lab.notebook import view_html

            self.widget.value = view_html(self.vis.static_html(), self.height)


class JointPanel:
    """One slider per actuated joint (within its limits) driving the robot, and FK of a link.

    Args:
        robot: a loaded ``nlo_lab.robots.Robot``.
        q: start angles ``(n,)`` [rad]; the neutral pose if None.
        link: the link whose pose is printed (default: the left wrist).
        view: ``"auto"``, ``"static"``, None or a meshcat ``Visualizer`` (see the module doc).
        height: 3-D view height [px].

    Attributes:
        sliders: ``{joint name: FloatSlider}``.
        link: Dropdown of links.
        q: current angles ``(n,)`` [rad].
        position: the chosen link's position ``(3,)`` [m] in the robot frame.
    """

    def __init__(self, robot, q=None, link: str | None = None, view: Any = "auto", height: int = 360):
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
            for name, v, a, b in zip(robot.joint_names, q0.tolist(), lo, hi)
        }
        links = sorted(robot.forward_kinematics(q0[None]).keys())
        default = link or robot.arm("left").wrist
        if default not in links:
            raise SettingsError(f"robot {robot.name!r} has no link {default!r}")
        self.link = W.Dropdown(options=links, value=default, description="link")
        self.readout = W.HTML()
        self._view = _View(view, height)
        self.scene = None
        if self._view.vis is not None:
            from nlo_lab.viz import RobotScene, frame_points, style_viewer

            self._view.vis.delete()
            self.scene = RobotScene(self._view.vis, robot).draw()
            # Frame on the rest pose and both limit extremes, so slider moves mostly stay in view.
            poses = torch.stack([robot.neutral_q, robot.lower_limits, robot.upper_limits])
            style_viewer(self._view.vis, camera=frame_points(self.scene.extent_points(poses.numpy())))
        for s in self.sliders.values():
            s.observe(self._update, names="value")
        self.link.observe(self._update, names="value")
        self._update()
        sliders = W.VBox(list(self.sliders.values()), layout=W.Layout(max_height=f"{height}px", overflow="auto"))
        right = [self._view.widget] if self._view.widget is not None else []
        self.widget = W.VBox([W.HBox([sliders, W.VBox(right, layout=W.Layout(width="100%"))]), W.HBox([self.link, self.readout])])

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
            self.scene.set_pose(self.q)
            self._view.refresh()

    def _repr_mimebundle_(self, **kwargs):
        return self.widget._repr_mimebundle_(**kwargs)


class RetargetPanel:
    """Interactive latent optimisation of a demonstration on a robot.

    Args:
        demo: the human ``Demonstration``.
        robot: ``"yumi"``, ``"nao"``, ``"pepper"`` (or a loaded ``Robot``).
        model: the model for ``robot``; by default ``model_loader(robot)``.
        model_loader: ``robot -> model`` used on a robot change (default: the shipped checkpoints,
            ``nlo_lab.train.load_pretrained``).
        weights: start loss weights (the paper's by default).
        init: start initialisation strategy (one of ``nlo_lab.optimize.INITS``).
        iterations: iteration budget of a cold start (the init/budget controls) and of the sequence button.
        frame_iterations: at most this many steps when a control re-optimises the current frame warm-started.
        frame: the start frame.
        view: ``"auto"``, ``"static"``, None or a meshcat ``Visualizer``.
        height: 3-D view height [px].
        max_curves: earlier convergence curves kept (faded) in the plot for comparison.

    Attributes:
        controls: ``{"ee", "ori", "elbow", "finger", "collision", "init", "iterations", "robot", "frame"}`` widgets.
        play: the ``Play`` widget linked to the frame slider.
        button: re-optimises the whole sequence.
        plot: ``HTML`` widget with the convergence plot (SVG; ``plot_data`` holds its curves).
        angles: ``(T, n)`` current joint angles of every frame [rad].
        latents: ``(T, N_r, k)`` current latents.
        history: the loss history of the last optimisation (shown in the plot).
        curves: ``[(label, history)]`` shown in the plot (the last one is ``history``).
        last: the last :class:`OptimizeResult`.
        last_seconds: wall time of the last optimisation [s].
    """

    def __init__(
        self,
        demo,
        robot: Any = "yumi",
        *,
        model=None,
        model_loader: Callable[[Any], Any] | None = None,
        weights: LossWeights | None = None,
        init: str = "encoder",
        iterations: int = 100,
        frame_iterations: int = 30,
        frame: int = 0,
        view: Any = "auto",
        height: int = 360,
        max_curves: int = 5,
    ):
        import ipywidgets as W

        if init not in INITS:
            raise SettingsError(f"unknown init {init!r}; expected one of {', '.join(INITS)}")
        if len(demo) == 0:
            raise SettingsError("the demonstration has no frames")
        if not 0 <= frame < len(demo):
            raise SettingsError(f"frame {frame} is outside 0..{len(demo) - 1}")
        if model_loader is None:
            from nlo_lab.train import load_pretrained

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
        names = list(ROBOTS) + ([robot_obj.name] if robot_obj.name not in ROBOTS else [])
        self.controls["init"] = W.Dropdown(options=list(INITS), value=init, description="init", style=style)
        self.controls["iterations"] = W.IntSlider(value=iterations, min=0, max=300, step=5, description="iterations", style=style, continuous_update=False)
        self.controls["robot"] = W.Dropdown(options=names, value=robot_obj.name, description="robot", style=style)
        self.controls["frame"] = W.IntSlider(value=frame, min=0, max=len(demo) - 1, description="frame", style=style)
        self.play = W.Play(value=frame, min=0, max=len(demo) - 1, interval=150, description="play")
        W.link((self.play, "value"), (self.controls["frame"], "value"))  # kernel-side link: works headless too
        self.button = W.Button(description="re-optimise the whole sequence", layout=W.Layout(width="260px"))
        self.plot = W.HTML()
        self.status = W.HTML()
        self._view = _View(view, height)
        self.scene = None
        self.curves: list[tuple[str, list[float]]] = []
        self.history: list[float] = []
        self.last: OptimizeResult | None = None
        self.last_seconds = 0.0
        self._busy = False
        self._set_robot(robot_obj.name)

        for name in TERMS:
            self.controls[name].observe(lambda ch: self.reoptimise_frame(warm=True), names="value")
        self.controls["init"].observe(lambda ch: self.reoptimise_frame(warm=False), names="value")
        self.controls["iterations"].observe(lambda ch: self.reoptimise_frame(warm=False), names="value")
        self.controls["frame"].observe(lambda ch: self.reoptimise_frame(warm=True), names="value")
        self.controls["robot"].observe(lambda ch: self._set_robot(ch["new"]), names="value")
        self.button.on_click(lambda b: self.optimise_sequence())

        weights_box = W.VBox([self.controls[n] for n in TERMS])
        setup_box = W.VBox([self.controls[n] for n in ("robot", "init", "iterations")] + [self.button])
        frames = W.HBox([self.play, self.controls["frame"]])
        left = W.VBox([W.HBox([weights_box, setup_box]), frames, self.status, self.plot])
        right = [self._view.widget] if self._view.widget is not None else []
        self.widget = W.HBox([left, W.VBox(right, layout=W.Layout(width="45%"))] if right else [left])

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
        return LossWeights(**{n: float(self.controls[n].value) for n in TERMS}, latent=self._latent_weight)

    def settings(self, iterations: int | None = None) -> OptimizeSettings:
        """Optimisation settings from the controls."""
        its = int(self.controls["iterations"].value) if iterations is None else int(iterations)
        return OptimizeSettings(init=self.controls["init"].value, iterations=its)

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
        from nlo_lab.robots import load_robot

        r = load_robot(robot)
        self._models[r.name] = (r, None)
        return r

    def _set_robot(self, name: str) -> None:
        robot = self._robot(name)
        if self._models[name][1] is None:
            self._models[name] = (robot, self.model_loader(robot))
        self.targets: Targets = targets_from_demonstration(self.demo, dtype=robot.lower_limits.dtype)
        with torch.no_grad():
            self.latents = initial_latent(self.model, self.targets, self.settings()).clone()
            self.angles = self.model.decode(self.latents).to(robot.lower_limits.dtype).cpu().double().numpy()  # (T, n)
        self.curves = []
        if self._view.vis is not None:
            from nlo_lab.viz import RetargetScene

            self._view.vis.delete()
            self.scene = RetargetScene(self._view.vis, robot, self.angles, demo=self.demo)
        self.reoptimise_frame(warm=True)

    def reoptimise_frame(self, warm: bool = True) -> OptimizeResult:
        """Re-optimise the current frame and update the plot and the view.

        Args:
            warm: start from the frame's current latent with at most
                ``frame_iterations`` steps; else start from the chosen
                initialisation with the full iteration budget.
        """
        t = self.frame
        one = self.targets.index(slice(t, t + 1))
        budget = int(self.controls["iterations"].value)
        if warm:
            settings = self.settings(min(self.frame_iterations, budget))
            z0 = self.latents[t : t + 1]
        else:
            settings, z0 = self.settings(), None
        with single_thread():
            start = time.perf_counter()
            result = optimize_latent(self.model, self.robot, one, settings, weights=self.weights, z0=z0)
            self.last_seconds = time.perf_counter() - start
        self.latents[t] = result.z[0].detach()
        self.angles[t] = result.q[0].detach().cpu().double().numpy()
        label = f"frame {t}: {'warm' if warm else settings.init}, {result.iterations} it"
        self._show(result, label)
        return result

    def optimise_sequence(self) -> OptimizeResult:
        """Optimise every frame from the chosen initialisation with the full budget (the button)."""
        settings = self.settings()
        live_every = 10

        def progress(it: int, loss: float) -> None:  # a live curve while the sequence runs
            if it % live_every == 0 and it > 0:
                self._draw(self.curves + [("sequence (running)", running + [loss])])
            running.append(loss)

        running: list[float] = []
        start = time.perf_counter()
        result = optimize_latent(self.model, self.robot, self.targets, settings, weights=self.weights, callback=progress)
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
        if self.scene is not None:
            self.scene.angles[t] = self.angles[t]
            self.scene.set_frame(t)
            self._view.refresh()

    def _draw(self, curves) -> None:
        self.plot_data = [(label, list(h)) for label, h in curves]
        self.plot.value = svg_convergence(self.plot_data)

    def _repr_mimebundle_(self, **kwargs):
        return self.widget._repr_mimebundle_(**kwargs)

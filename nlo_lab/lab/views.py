"""What the panels share: the 3-D view, errors shown in the panel, the convergence plot.

* :class:`View`: a panel's 3-D view: its own scene widget (``view="auto"``,
  :class:`nlo_lab.viz.SceneWidget`, meshcat's viewer over the notebook's connection;
  a move sends only the transforms that changed), ``None`` for none, or an injected
  meshcat ``Visualizer``.
* :func:`guarded`: an observer's error is shown in the panel (``panel.error``, the
  status line, the view), then raised.
* :func:`svg_convergence`: loss histories as a small SVG plot.
"""

from __future__ import annotations

import contextlib
import html
from collections.abc import Callable
from typing import Any

import numpy as np

from nlo_lab.errors import SettingsError

__all__ = ["View", "guarded", "svg_convergence"]


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
            pts = " ".join(f"{a:.1f},{b:.1f}" for a, b in zip(px, py, strict=True))
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


class View:
    """A panel's 3-D view: its own scene widget (``"auto"``), an injected meshcat ``Visualizer``, or none."""

    def __init__(self, view: Any, height: int):
        self.widget = None
        self.vis = None
        if view is None or view is False:
            return
        if isinstance(view, str):
            if view != "auto":
                raise SettingsError(f"view must be 'auto', None or a meshcat Visualizer, got {view!r}")
            # lazy: anywidget and ipywidgets: only when a view is drawn in a kernel
            from nlo_lab.viz import SceneWidget

            self.widget = SceneWidget(height=height)
            self.vis = self.widget.vis
        elif hasattr(view, "__getitem__") and hasattr(view, "delete"):
            self.vis = view  # an injected meshcat Visualizer (e.g. nlo_lab.viz.recording_visualizer())
        else:
            raise SettingsError(f"view must be 'auto', None or a meshcat Visualizer, got {view!r}")

    def hold(self):
        """Send the commands of one update as one message."""
        return self.widget.hold() if self.widget is not None else contextlib.nullcontext()

    def sync(self) -> None:
        if self.widget is not None:
            self.widget.sync()

    def show_message(self, text: str) -> None:
        if self.widget is not None:
            self.widget.show_message(text)


def guarded(panel, action: Callable[..., Any]) -> Callable[..., Any]:
    """``action`` for an observer: an error is shown in the panel (status line and view), then raised.

    A widget callback's exception never reaches the cell's output, so without this the learner
    would see nothing at all.
    """

    def run(*args, **kwargs):
        try:
            result = action(*args, **kwargs)
        except Exception as exc:
            text = f"{type(exc).__name__}: {exc}"
            panel.error = text
            panel.status.value = f'<span class="nlo-lab-panel-error" style="color: #b00020"><b>error</b>: {html.escape(text)}</span>'
            panel._view.show_message(f"Not updated: {text}")
            raise
        if panel.error:
            panel.error = ""
            panel._view.show_message("")
        return result

    return run

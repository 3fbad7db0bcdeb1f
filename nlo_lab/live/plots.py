"""Plots of a live stream: where each frame's latency went."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_latency"]

_COLOURS = {"decode": "#8c564b", "mediapipe": "#1f77b4", "filter": "#2ca02c", "optimization": "#ff7f0e", "view": "#9467bd"}


def plot_latency(history, parts=("decode", "mediapipe", "filter", "optimization", "view"), last: int = 60, figsize=(6, 3.2)):
    """The latency of the last ``last`` processed frames, each bar split into its parts [ms].

    Args:
        history: rows ``{"latency_ms", part: ms, ...}`` (a :class:`~nlo_lab.live.CameraView`'s ``history``).

    Returns:
        The matplotlib figure.
    """
    import matplotlib.pyplot as plt  # lazy: pyplot picks a backend on import

    rows = list(history)[-last:]
    fig, ax = plt.subplots(figsize=figsize)
    x = np.arange(len(rows))
    bottom = np.zeros(len(rows))
    for part in parts:
        values = np.array([r.get(part, 0.0) for r in rows])
        ax.bar(x, values, bottom=bottom, width=0.85, label=part, color=_COLOURS.get(part))
        bottom += values
    total = np.array([r["latency_ms"] for r in rows])
    ax.plot(x, total, "k.", ms=3, label="total (arrival to view)")
    ax.set(xlabel="processed frame", ylabel="latency [ms]")
    ax.legend(fontsize="x-small", ncol=3, loc="upper right")
    fig.tight_layout()
    return fig

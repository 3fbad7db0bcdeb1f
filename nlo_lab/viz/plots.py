"""matplotlib helpers: convergence, joint trajectories against limits, per-term losses."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from nlo_lab.errors import SettingsError
from nlo_lab.metrics import joint_speed_ratios

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["plot_convergence", "plot_joint_trajectories", "plot_loss_terms", "fastest_joints", "plot_joint_speeds"]


def _axes(ax):
    if ax is not None:
        return ax.figure, ax
    # lazy: pyplot picks a backend on import: only when a figure is drawn
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
    return fig, ax


def _numpy(x: Any) -> np.ndarray:
    if hasattr(x, "detach"):
        x = x.detach().cpu().numpy()
    return np.asarray(x, dtype=np.float64)


def plot_convergence(histories: Mapping[str, Any] | Any, ax=None, log: bool = True, title: str = "Convergence"):
    """Loss against iteration, one line per run.

    Args:
        histories: ``{label: (iterations,) losses}`` or one ``(iterations,)`` array.
        ax: axes to draw into (a new figure if None).
        log: logarithmic loss axis (if every loss is > 0).

    Returns:
        ``(fig, ax)``.
    """
    fig, ax = _axes(ax)
    if not isinstance(histories, Mapping):
        histories = {"loss": histories}
    positive = True
    for label, h in histories.items():
        y = _numpy(h).reshape(-1)
        if y.size == 0:
            raise SettingsError(f"history {label!r} is empty")
        positive &= bool((y > 0).all())
        ax.plot(np.arange(y.size), y, label=str(label))
    if log and positive:
        ax.set_yscale("log")
    ax.set_xlabel("iteration")
    ax.set_ylabel("objective")
    ax.set_title(title)
    ax.legend(fontsize="small")
    ax.grid(True, alpha=0.3)
    return fig, ax


def plot_joint_trajectories(angles: Any, joint_names: Sequence[str], lower: Any = None, upper: Any = None, fps: float = 1.0, joints: Sequence[int] | None = None, ncols: int = 4):
    """One small panel per joint: its angle over time [rad] with the limits as dashed lines.

    Args:
        angles: ``(T, n)`` [rad].
        joint_names: ``(n,)`` names.
        lower, upper: ``(n,)`` limits [rad] (optional).
        fps: frames per second for the time axis (1 gives frames).
        joints: indices to plot (all by default).

    Returns:
        ``(fig, axes)``.
    """
    # lazy: pyplot picks a backend on import: only when a figure is drawn
    import matplotlib.pyplot as plt

    q = _numpy(angles)
    if q.ndim != 2 or q.shape[1] != len(joint_names):
        raise SettingsError(f"angles must be (T, {len(joint_names)}), got shape {q.shape}")
    idx = list(range(q.shape[1])) if joints is None else list(joints)
    lo = None if lower is None else _numpy(lower)
    hi = None if upper is None else _numpy(upper)
    ncols = max(1, min(ncols, len(idx)))
    nrows = int(np.ceil(len(idx) / ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=(3 * ncols, 1.8 * nrows), squeeze=False, sharex=True)
    t = np.arange(q.shape[0]) / fps
    for k, ax in enumerate(axes.flat):
        if k >= len(idx):
            ax.set_visible(False)
            continue
        j = idx[k]
        ax.plot(t, q[:, j], lw=1.2)
        if lo is not None:
            ax.axhline(lo[j], ls="--", color="k", lw=0.8)
        if hi is not None:
            ax.axhline(hi[j], ls="--", color="k", lw=0.8)
        outside = np.zeros(q.shape[0], bool)
        if lo is not None:
            outside |= q[:, j] < lo[j]
        if hi is not None:
            outside |= q[:, j] > hi[j]
        if outside.any():
            ax.plot(t[outside], q[outside, j], "rx", ms=3)
        ax.set_title(joint_names[j], fontsize="small")
    for ax in axes[-1]:
        ax.set_xlabel("time [s]" if fps != 1.0 else "frame")
    fig.tight_layout()
    return fig, axes


def plot_loss_terms(terms: Mapping[str, Any], ax=None, weights: Mapping[str, float] | None = None, title: str = "Objective terms"):
    """Bar chart of each loss term (mean over frames if given per frame).

    Args:
        terms: ``{name: value or (B,) values}``.
        weights: optional ``{name: weight}``; bars then show weight × term.

    Returns:
        ``(fig, ax)``.
    """
    fig, ax = _axes(ax)
    names = list(terms)
    values = [float(_numpy(terms[n]).mean()) * (float(weights.get(n, 1.0)) if weights else 1.0) for n in names]
    bars = ax.bar(names, values, color="#E8731A")
    ax.bar_label(bars, fmt="%.3g", fontsize="small")
    ax.set_ylabel("weighted value" if weights else "value")
    ax.set_title(title)
    return fig, ax


# ------------------------------------------------------------------ joint speeds (notebook 08)
def fastest_joints(robot: Robot, trajectory, k: int = 3) -> list[int]:
    """Indices of the ``k`` joints with the largest speed over their limit in ``trajectory``
    (frames 1/fps apart, i.e. before retiming)."""
    ratios = joint_speed_ratios(robot, trajectory.angles, fps=trajectory.fps)  # (T-1, n)
    return [int(j) for j in np.argsort(-ratios.max(axis=0))[:k]]


def plot_joint_speeds(robot: Robot, trajectories: Mapping[str, Any], joints: Sequence[int] | None = None, figsize=(9, 4.5)):
    """Angle (top row) and speed (bottom row) of a few joints, each trajectory on its own time base.

    The bottom row shows the joint's published velocity limit as dashed lines at ``±v_max``:
    a curve beyond them is motion the robot cannot play at that speed.

    Args:
        robot: the robot (joint names, ``velocity_limits``).
        trajectories: ``{label: RobotTrajectory}``.
        joints: joint indices (default: the 3 fastest of the first trajectory).

    Returns:
        The matplotlib figure.
    """
    # lazy: pyplot picks a backend on import: only when a figure is drawn
    import matplotlib.pyplot as plt

    first = next(iter(trajectories.values()))
    joints = list(joints) if joints is not None else fastest_joints(robot, first)
    limits = robot.velocity_limits.double().cpu().numpy()
    fig, axes = plt.subplots(2, len(joints), figsize=figsize, sharex=True, squeeze=False)
    for c, j in enumerate(joints):
        for label, traj in trajectories.items():
            t, q = traj.times, traj.angles[:, j]
            axes[0, c].plot(t, q, lw=1.2, label=label)
            v = np.diff(q) / np.diff(t)
            axes[1, c].step(t[1:], v, where="pre", lw=1.0, label=label)
        for sign in (1, -1):
            axes[1, c].axhline(sign * limits[j], color="k", ls="--", lw=0.8)
        axes[0, c].set_title(robot.joint_names[j], fontsize=8)
        axes[1, c].set_xlabel("time [s]")
        for ax in axes[:, c]:
            ax.grid(alpha=0.3)
            ax.tick_params(labelsize=7)
    axes[0, 0].set_ylabel("angle [rad]")
    axes[1, 0].set_ylabel("speed [rad/s]\n(dashed: limit)")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    return fig

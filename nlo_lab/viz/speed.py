"""Joint curves against the robot's velocity limits (matplotlib), for the smoothness section of notebook 08."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from nlo_lab.metrics import joint_speed_ratios

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["fastest_joints", "plot_joint_speeds"]


def fastest_joints(robot: Robot, trajectory, k: int = 3) -> list[int]:
    """Indices of the ``k`` joints with the largest speed over their limit in ``trajectory``
    (frames 1/fps apart, i.e. before retiming)."""
    ratios = joint_speed_ratios(robot, trajectory.angles, fps=trajectory.fps)  # (T-1, n)
    return [int(j) for j in np.argsort(-ratios.max(axis=0))[:k]]


def plot_joint_speeds(robot: Robot, trajectories: Mapping[str, object], joints: Sequence[int] | None = None, figsize=(9, 4.5)):
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

"""Handshape pictures: the human hand's landmarks beside the robot hand, in the wrist frame (notebook 12).

Both hands are drawn in their own wrist frame (x wrist -> middle knuckle, up; y little -> index
knuckle), the human's scaled to the robot hand's length, side by side in one 3-D axes per
handshape, as seen from the palm side.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

__all__ = ["HUMAN_FINGERS", "draw_hand_pair", "handshape_gallery"]

# MediaPipe landmark chains from the wrist (0), thumb..pinky
HUMAN_FINGERS = ((0, 1, 2, 3, 4), (0, 5, 6, 7, 8), (0, 9, 10, 11, 12), (0, 13, 14, 15, 16), (0, 17, 18, 19, 20))
_HUMAN, _ROBOT = "#d62728", "#1f4e9c"


def draw_hand_pair(ax, human: np.ndarray, robot: Mapping[str, np.ndarray], title: str = "", gap: float = 0.25) -> None:
    """Draw one handshape on a 3-D matplotlib axes.

    Args:
        ax: a ``projection="3d"`` axes.
        human: ``(21, 3)`` the human hand's landmarks in its wrist frame, at the robot's size [m].
        robot: per finger the robot chain's points ``(k, 3)`` in its wrist frame [m] (wrist first).
        title: shown above.
        gap: the human hand's shift beside the robot's [m].
    """
    shift = np.array([0.0, gap, 0.0])
    for chain in HUMAN_FINGERS:
        p = human[list(chain)] + shift
        ax.plot(p[:, 1], p[:, 2], p[:, 0], color=_HUMAN, lw=1.5)
        ax.scatter(p[1:, 1], p[1:, 2], p[1:, 0], color=_HUMAN, s=6)
    for points in robot.values():
        ax.plot(points[:, 1], points[:, 2], points[:, 0], color=_ROBOT, lw=2.5)
        ax.scatter(points[-1:, 1], points[-1:, 2], points[-1:, 0], color=_ROBOT, s=12)
    ax.set_title(title, fontsize=9)
    ax.view_init(elev=20, azim=-70)
    ax.set_box_aspect((1.6, 1.0, 1.0))
    ax.set_xlim(-0.12, gap + 0.12)
    ax.set_ylim(-0.12, 0.12)
    ax.set_zlim(-0.02, 0.26)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_zticks([])


def handshape_gallery(labels: Sequence[str], humans: Sequence[np.ndarray], robots: Sequence[Mapping[str, np.ndarray]],
                      captions: Sequence[str] | None = None, columns: int = 4):
    """A grid of :func:`draw_hand_pair`, one per handshape (human red, robot blue). Returns the figure."""
    # lazy: pyplot picks a backend on import: only when a figure is drawn
    import matplotlib.pyplot as plt

    n = len(labels)
    rows = (n + columns - 1) // columns
    fig = plt.figure(figsize=(3.2 * columns, 3.0 * rows))
    for i in range(n):
        ax = fig.add_subplot(rows, columns, i + 1, projection="3d")
        title = labels[i] + ("\n" + captions[i] if captions else "")
        draw_hand_pair(ax, humans[i], robots[i], title)
    fig.suptitle("human landmarks (red, right) beside the robot hand (blue), each in its wrist frame", fontsize=10)
    fig.tight_layout()
    return fig

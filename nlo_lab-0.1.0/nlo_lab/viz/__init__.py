"""The 3-D viewer (meshcat) and matplotlib plots.

* scenes: :class:`RobotScene`, :class:`HumanScene`, :class:`RetargetScene` (side by side or overlaid, one frame or animated;
  the human at the robot's size or as recorded; the camera framed on the whole trajectory: :func:`frame_points`);
* :func:`export_html` / :func:`static_html`: self-contained animated pages that work offline;
* :class:`Viewer` / :func:`live_viewer`: a live server on 127.0.0.1 that dies with its owner; :func:`show` falls back to the static page;
* plots: :func:`plot_convergence`, :func:`plot_joint_trajectories`, :func:`plot_loss_terms`.
"""

from nlo_lab.viz.camera import CameraView, frame_points
from nlo_lab.viz.export import export_html, iframe_html, recording_visualizer, static_html
from nlo_lab.viz.plots import plot_convergence, plot_joint_trajectories, plot_loss_terms
from nlo_lab.viz.scene import GROUP_COLOURS, HUMAN_COLOURS, HUMAN_SCALES, HumanScene, RetargetScene, RobotScene, link_groups, robot_visuals, style_viewer
from nlo_lab.viz.server import STATIC_ENV, Viewer, ViewerError, live_viewer, show, static_viewer_requested

__all__ = [
    "export_html",
    "static_html",
    "iframe_html",
    "recording_visualizer",
    "RobotScene",
    "HumanScene",
    "RetargetScene",
    "robot_visuals",
    "link_groups",
    "style_viewer",
    "GROUP_COLOURS",
    "HUMAN_COLOURS",
    "HUMAN_SCALES",
    "CameraView",
    "frame_points",
    "Viewer",
    "ViewerError",
    "live_viewer",
    "show",
    "static_viewer_requested",
    "STATIC_ENV",
    "plot_convergence",
    "plot_joint_trajectories",
    "plot_loss_terms",
]

"""The 3-D viewer (meshcat) and matplotlib plots.

* scenes: :class:`RobotScene`, :class:`HumanScene`, :class:`RetargetScene` (side by side or overlaid, one frame or animated;
  the human at the robot's size or as recorded; the camera framed on the whole trajectory: :func:`frame_points`);
* :class:`SceneWidget`: the live view in a notebook, meshcat's viewer inside a widget that talks over the
  notebook's own connection (no server, no port);
* :func:`export_html` / :func:`static_html`: self-contained animated pages for files (work offline);
* plots: :func:`plot_convergence`, :func:`plot_joint_trajectories`, :func:`plot_loss_terms`, :func:`plot_joint_speeds`;
  handshapes: :func:`handshape_gallery`, :func:`draw_hand_pair` (human landmarks beside the robot hand).
"""

from nlo_lab.viz.camera import CameraView, frame_points
from nlo_lab.viz.export import export_html, recording_visualizer, static_html
from nlo_lab.viz.hands import HUMAN_FINGERS, draw_hand_pair, handshape_gallery
from nlo_lab.viz.plots import fastest_joints, plot_convergence, plot_joint_speeds, plot_joint_trajectories, plot_loss_terms
from nlo_lab.viz.scene import (
    GROUP_COLOURS,
    HUMAN_COLOURS,
    HUMAN_SCALES,
    HumanScene,
    RetargetScene,
    RobotScene,
    link_groups,
    robot_visuals,
    style_viewer,
)

__all__ = [
    "handshape_gallery",
    "draw_hand_pair",
    "HUMAN_FINGERS",
    "export_html",
    "static_html",
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
    "SceneWidget",
    "plot_convergence",
    "plot_joint_trajectories",
    "plot_loss_terms",
    "plot_joint_speeds",
    "fastest_joints",
]


def __getattr__(name: str):
    # The widget needs ipywidgets and anywidget: imported when first asked for, so the command line stays light.
    if name == "SceneWidget":
        # lazy: anywidget and ipywidgets: only when a view is drawn in a kernel
        from nlo_lab.viz.widget import SceneWidget

        return SceneWidget
    raise AttributeError(f"module 'nlo_lab.viz' has no attribute {name!r}")

"""The notebooks' side of nlo_lab: cell helpers, interactive panels, the video view, ``nlo-lab lab``.

* :mod:`~nlo_lab.lab.cells`: :func:`setup`, :func:`budget` and ``show_*`` helpers that keep cells thin.
* :mod:`~nlo_lab.lab.graph_plot`: :func:`plot_graph`, a graph drawn as a tree (the robot and skeleton graphs).
* :mod:`~nlo_lab.lab.views`: what the panels share (:class:`View`, :func:`guarded`, :func:`svg_convergence`).
* :mod:`~nlo_lab.lab.joint_panel`: :class:`JointPanel`, joints on sliders and FK of a link.
* :mod:`~nlo_lab.lab.retarget_panel`: :class:`RetargetPanel`, the method's controls, live.
* :mod:`~nlo_lab.lab.weights_panel`: :class:`WeightsPanel`, the loss weights and the pose they give for one frame.
* :mod:`~nlo_lab.lab.hand_panel`: :class:`HandPanel`, the hand weights and one handshape in close-up.
* :mod:`~nlo_lab.lab.video_view`: :class:`VideoView`, a video beside the skeleton and the robot.
* :mod:`~nlo_lab.lab.launch`: ``nlo-lab lab``: the learner's copy of the notebooks in JupyterLab.
* :mod:`~nlo_lab.lab.own_robot`: notebook 10's lesson robot and spec variants.

ipywidgets, PIL and JupyterLab are imported only when a panel, a view or the launcher needs them.
"""

from nlo_lab.lab.cells import (
    RECORDINGS_DIR,
    TEST_ENV,
    TEST_MODE,
    WORK_ENV,
    budget,
    is_test_mode,
    joint_table,
    recording_path,
    setup,
    show_human,
    show_robot,
    show_view,
    time_bar,
    work_folder,
)
from nlo_lab.lab.graph_plot import GraphLayout, graph_layout, plot_graph
from nlo_lab.lab.hand_panel import HAND_SLIDERS, HandPanel
from nlo_lab.lab.joint_panel import JointPanel
from nlo_lab.lab.launch import (
    bundled_notebooks,
    copy_notebooks,
    lab_command,
    notebook_revision,
    open_hint,
    other_version_copies,
    root_refusal,
    running_jupyter,
)
from nlo_lab.lab.own_robot import LESSON_URDF, lesson_urdf, retarget_report, spec_variant
from nlo_lab.lab.retarget_panel import RetargetPanel
from nlo_lab.lab.video_view import VideoView, jpeg_bytes, save_upload
from nlo_lab.lab.views import View, guarded, svg_convergence
from nlo_lab.lab.weights_panel import WeightsPanel

__all__ = [
    # cells
    "TEST_ENV", "TEST_MODE", "is_test_mode", "budget", "setup", "show_robot", "show_view", "show_human",
    "joint_table", "plot_graph", "graph_layout", "GraphLayout", "RECORDINGS_DIR", "recording_path", "WORK_ENV", "work_folder", "time_bar",
    # views, panels, the video view
    "View", "guarded", "svg_convergence", "JointPanel", "RetargetPanel", "WeightsPanel", "HandPanel", "HAND_SLIDERS",
    "VideoView", "jpeg_bytes", "save_upload",
    # notebook 10
    "LESSON_URDF", "lesson_urdf", "spec_variant", "retarget_report",
    # launch
    "bundled_notebooks", "copy_notebooks", "lab_command", "notebook_revision", "other_version_copies",
    "running_jupyter", "open_hint", "root_refusal",
]

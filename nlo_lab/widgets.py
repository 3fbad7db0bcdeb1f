"""Old import path of the panels (:mod:`nlo_lab.lab`), kept for notebooks copied by earlier versions."""

from nlo_lab.lab.joint_panel import JointPanel
from nlo_lab.lab.retarget_panel import RetargetPanel
from nlo_lab.lab.views import svg_convergence

__all__ = ["JointPanel", "RetargetPanel", "svg_convergence"]

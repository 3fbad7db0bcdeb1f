"""The old import path of :class:`RobotTrajectory`: it lives in :mod:`nlo_lab.inference.trajectory`."""

from nlo_lab.inference.trajectory import FORMAT_VERSION, RobotTrajectory, TrajectoryError

__all__ = ["RobotTrajectory", "TrajectoryError", "FORMAT_VERSION"]

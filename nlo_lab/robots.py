"""Old import path of :mod:`nlo_lab.robot` (``from nlo_lab.robots import load_robot`` keeps working)."""

from nlo_lab.robot import ArmSpec, CapsuleSpec, Robot, RobotSpec, known_robots, load_robot, load_spec

__all__ = ["ArmSpec", "CapsuleSpec", "RobotSpec", "Robot", "load_robot", "load_spec", "known_robots"]

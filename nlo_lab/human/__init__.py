"""Human demonstrations: the data model, readers and writers, the skeleton graph, the synthetic corpus."""

from nlo_lab.human.demonstration import ARM_JOINTS, FINGER_POINTS, FINGERS, SIDES, Demonstration

__all__ = ["Demonstration", "SIDES", "ARM_JOINTS", "FINGERS", "FINGER_POINTS"]

"""The old import path of retiming: it lives in :mod:`nlo_lab.inference.retime`."""

from nlo_lab.inference.retime import SAFETY, joint_speeds, retime_times, segment_durations, speed_ratios

__all__ = ["SAFETY", "segment_durations", "retime_times", "joint_speeds", "speed_ratios"]

"""Human demonstrations: the data model, its readers and writer (:mod:`nlo_lab.human.readers`), the skeleton graph.

The synthetic sign corpus is built on this package and lives after it, in :mod:`nlo_lab.corpus`.
"""

from nlo_lab.human.demonstration import ARM_JOINTS, FINGER_POINTS, FINGERS, SIDES, Demonstration
from nlo_lab.human.readers import (
    VIDEO_SUFFIXES,
    VideoPose,
    VideoWarning,
    estimate_pose,
    load_demonstration,
    load_h5_sequences,
    load_npz,
    load_pose,
    load_video,
    pose_to_demonstration,
    read_video_frames,
    save_npz,
    video_info,
)
from nlo_lab.human.skeleton import NODE_NAMES, edge_features, node_features, skeleton_graph
from nlo_lab.human.transforms import map_to_robot, normalize_arm_lengths, resample, wrist_frame_from_hand

__all__ = [
    "Demonstration",
    "SIDES",
    "ARM_JOINTS",
    "FINGERS",
    "FINGER_POINTS",
    "load_demonstration",
    "load_pose",
    "load_video",
    "load_npz",
    "load_h5_sequences",
    "save_npz",
    "estimate_pose",
    "pose_to_demonstration",
    "read_video_frames",
    "video_info",
    "VIDEO_SUFFIXES",
    "VideoPose",
    "VideoWarning",
    "NODE_NAMES",
    "skeleton_graph",
    "node_features",
    "edge_features",
    "normalize_arm_lengths",
    "resample",
    "map_to_robot",
    "wrist_frame_from_hand",
]


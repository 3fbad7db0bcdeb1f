"""Human demonstrations: the data model, readers and writers, the skeleton graph.

The synthetic sign corpus is built on this package and lives after it, in :mod:`nlo_lab.corpus`.
"""

from nlo_lab.human.demonstration import ARM_JOINTS, FINGER_POINTS, FINGERS, SIDES, Demonstration
from nlo_lab.human.io import load_demonstration, load_h5_sequences, save_npz
from nlo_lab.human.skeleton import NODE_NAMES, edge_features, node_features, skeleton_graph
from nlo_lab.human.transforms import map_to_robot, normalize_arm_lengths, resample, wrist_frame_from_hand

__all__ = [
    "Demonstration",
    "SIDES",
    "ARM_JOINTS",
    "FINGERS",
    "FINGER_POINTS",
    "load_demonstration",
    "load_h5_sequences",
    "save_npz",
    "NODE_NAMES",
    "skeleton_graph",
    "node_features",
    "edge_features",
    "normalize_arm_lengths",
    "resample",
    "map_to_robot",
    "wrist_frame_from_hand",
]


"""Human demonstrations: the data model, readers and writers, the skeleton graph.

``sign_corpus``, ``corpus_clip`` and ``corpus_names`` (the synthetic corpus, which lives in
:mod:`nlo_lab.corpus`) are re-exported here on first use: the corpus is built on this
package, so importing it eagerly would make the two import each other.
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
    "sign_corpus", "corpus_clip", "corpus_names",
]


def __getattr__(name: str):
    """``nlo_lab.human.sign_corpus`` & co.: the objects of :mod:`nlo_lab.corpus`, imported on first use."""
    if name in ("sign_corpus", "corpus_clip", "corpus_names"):
        import nlo_lab.corpus

        return getattr(nlo_lab.corpus, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

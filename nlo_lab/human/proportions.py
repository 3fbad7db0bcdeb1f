"""Proportions of a nominal adult [m]: the default synthetic signer, and the scale of recordings without one.

The ``.pose`` reader scales image-only recordings to :data:`SHOULDER_WIDTH` and takes the
body's proportions (upper arm, forearm and hand per shoulder width) from these values;
the synthetic corpus' default signer (``nlo_lab.corpus.BodyParams()``) has exactly these
dimensions. Adult values: shoulder joint to shoulder joint 0.32-0.40 m, upper arm (shoulder
joint -> elbow joint) 0.27-0.32 m, forearm 0.23-0.28 m, hand (wrist crease -> middle
fingertip) 0.17-0.20 m; hand lengths after Buchholz, Armstrong & Goldstein (1992),
"Anthropometric data for describing the kinematics of the human hand", Ergonomics 35(3).
"""

__all__ = ["SHOULDER_WIDTH", "UPPER_ARM", "FOREARM", "HAND_LENGTH"]

SHOULDER_WIDTH = 0.36  # shoulder joint centre to shoulder joint centre
UPPER_ARM = 0.30  # shoulder joint -> elbow joint
FOREARM = 0.26  # elbow joint -> wrist joint
HAND_LENGTH = 0.19  # wrist crease -> middle fingertip

"""The synthetic signers' body: dimensions (:class:`BodyParams`), joints and their ranges.

Its surface (torso, neck, head) is here too: signed distances for clearance checks, the torso
a rounded box, the neck a capsule, the head a sphere, negative inside. The kinematics of this
body are in :mod:`nlo_lab.corpus.arm_kinematics`.

Frame and units: the body frame of :mod:`nlo_lab.human.demonstration`, metres, radians.
The joints (``ARM_JOINT_NAMES``, ``FINGER_JOINT_NAMES``) and what their angles mean are
described with the kinematics, :mod:`nlo_lab.corpus.arm_kinematics`.

Finger segment lengths are fractions of hand length after Buchholz, Armstrong & Goldstein (1992),
"Anthropometric data for describing the kinematics of the human hand", Ergonomics 35(3).
Joint ranges are the usual clinical ranges of motion (AAOS / Norkin & White); see
``ARM_RANGES`` and ``FINGER_RANGES``. Body-size ranges of the synthetic signers are in
``BODY_RANGES``: adult values (upper arm shoulder->elbow joint 0.27-0.32 m, forearm
0.23-0.28 m, hand 0.17-0.20 m); note the paper's demonstrator measured with OptiTrack
markers has a shorter upper arm (about 0.20 m) and a 0.24 m forearm (the paper's data set).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nlo_lab.human import proportions
from nlo_lab.settings import check_range, validate_fields

__all__ = [
    "ARM_JOINT_NAMES",
    "FINGER_JOINT_NAMES",
    "ARM_RANGES",
    "FINGER_RANGES",
    "BODY_RANGES",
    "BASE_INDEX",
    "FINGER_SEGMENTS",
    "BodyParams",
    "torso_signed_distance",
    "head_signed_distance",
    "body_signed_distance",
    "body_gradient",
    "random_body",
]

ARM_JOINT_NAMES = (
    "shoulder_flexion",
    "shoulder_abduction",
    "shoulder_rotation",  # internal (+) / external (-) rotation of the humerus
    "elbow_flexion",
    "forearm_pronation",  # pronation (+) / supination (-), 0 = thumb side up with the elbow at 90 deg
    "wrist_flexion",  # flexion (+, towards the palm) / extension (-)
    "wrist_deviation",  # ulnar (+) / radial (-)
)
FINGER_JOINT_NAMES = ("flexion_1", "spread_1", "flexion_2", "flexion_3")  # thumb: CMC flex, CMC abduction, MCP, IP

_D = np.pi / 180.0
# (7, 2) [rad]; shoulder from the clinical ROM (flexion 180, extension 60, abduction 180,
# adduction across the body 50 (horizontal adduction when flexed), internal rotation 90 (70 is
# the clinical value with the arm abducted; reaching across the belly takes up to about 90),
# external 90), elbow 0-150, pronation/supination 80/80, wrist flexion 80 / extension 70,
# ulnar 30 / radial deviation 20.
ARM_RANGES = np.array(
    [[-60, 180], [-50, 180], [-90, 90], [0, 150], [-80, 80], [-70, 80], [-20, 30]], dtype=np.float64
) * _D
# (5, 4, 2) [rad]; fingers: MCP flexion 90 / hyperextension 20, spread +-20, PIP 0-110, DIP 0-80;
# thumb: CMC flexion 50 / extension 20, palmar abduction 0-70, MCP 0-60 (10 hyperextension), IP 80 / 15.
FINGER_RANGES = np.array(
    [[[-20, 50], [0, 70], [-10, 60], [-15, 80]]] + [[[-20, 90], [-20, 20], [0, 110], [0, 80]]] * 4,
    dtype=np.float64,
) * _D
BASE_INDEX = np.array([2, 1, 1, 1, 1])  # chain point of the MCP joint, thumb..pinky

# Ranges of the synthetic signers' dimensions [m].
BODY_RANGES = {
    "shoulder_width": (0.32, 0.40),  # between the shoulder joint centres
    "upper_arm": (0.27, 0.32),  # shoulder joint -> elbow joint
    "forearm": (0.23, 0.28),  # elbow joint -> wrist joint
    "hand_length": (0.17, 0.20),  # wrist crease -> middle fingertip
    "head_radius": (0.090, 0.105),
    "chest_depth": (0.20, 0.26),  # torso front to back
}

# Hand geometry, fractions of hand length, in hand coordinates (X radial, Y palmar, Z proximal:
# a finger points along -Z). Segment lengths (Buchholz et al. 1992): proximal, middle, distal
# phalanx; for the thumb metacarpal, proximal, distal.
FINGER_SEGMENTS = np.array(
    [[0.251, 0.196, 0.158], [0.245, 0.143, 0.097], [0.266, 0.170, 0.108], [0.244, 0.165, 0.107], [0.204, 0.117, 0.093]]
)


def _in_body_range(name: str, value) -> float:
    """The check of one dimension: ``"BodyParams.upper_arm"`` must lie in ``BODY_RANGES["upper_arm"]``."""
    return check_range(name, value, *BODY_RANGES[name.removeprefix("BodyParams.")], "m")

@dataclass(frozen=True)
class BodyParams:
    """Dimensions of one synthetic signer [m]; see ``BODY_RANGES`` for the accepted ranges."""

    shoulder_width: float = proportions.SHOULDER_WIDTH
    upper_arm: float = proportions.UPPER_ARM
    forearm: float = proportions.FOREARM
    hand_length: float = proportions.HAND_LENGTH
    head_radius: float = 0.10
    chest_depth: float = 0.23

    def __post_init__(self) -> None:
        validate_fields(self, _in_body_range, prefix="BodyParams.")

    # Derived primitives (a rounded box for the torso, a capsule for the neck, a sphere for the head).
    @property
    def torso_center(self) -> np.ndarray:
        """``(3,)`` centre of the torso box [m]; the chest front is at x = chest_depth / 2."""
        return np.array([-0.01, 0.0, -0.26])

    @property
    def torso_half_extents(self) -> np.ndarray:
        """``(3,)`` half sizes of the torso box including its rounding radius [m]."""
        return np.array([self.chest_depth / 2, self.shoulder_width / 2 - 0.035, 0.29])

    torso_rounding = 0.05  # [m]

    @property
    def head_center(self) -> np.ndarray:
        """``(3,)`` centre of the head sphere [m]."""
        return np.array([0.02, 0.0, 0.13 + self.head_radius + 0.01])

    @property
    def neck(self) -> tuple[np.ndarray, np.ndarray, float]:
        """Neck capsule: two end points and a radius [m]."""
        return np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, 0.16]), 0.06

    def segment_lengths(self) -> np.ndarray:
        """``(5, 3)`` finger segment lengths after the j1 joint [m], thumb..pinky."""
        return FINGER_SEGMENTS * self.hand_length


def random_body(rng: np.random.Generator) -> BodyParams:
    """A signer drawn uniformly inside ``BODY_RANGES``, limb lengths correlated with stature."""
    size = rng.uniform(0.0, 1.0)  # common factor: tall signers have long arms and hands
    values = {}
    for name, (lo, hi) in BODY_RANGES.items():
        u = np.clip(0.6 * size + 0.4 * rng.uniform(0.0, 1.0), 0.0, 1.0)
        values[name] = float(lo + (hi - lo) * u)
    return BodyParams(**values)


# ------------------------------------------------------------------ the surface
def _norm(v: np.ndarray) -> np.ndarray:
    """Euclidean norm over the last axis (cheaper than np.linalg.norm on small arrays)."""
    return np.sqrt(np.sum(v * v, axis=-1))


def torso_signed_distance(params: BodyParams, points: np.ndarray) -> np.ndarray:
    """Signed distance [m] of ``(..., 3)`` points to the torso (rounded box); < 0 inside."""
    q = np.abs(np.asarray(points) - params.torso_center) - (params.torso_half_extents - params.torso_rounding)
    outside = _norm(np.maximum(q, 0.0))
    inside = np.minimum(np.max(q, axis=-1), 0.0)
    return outside + inside - params.torso_rounding


def head_signed_distance(params: BodyParams, points: np.ndarray) -> np.ndarray:
    """Signed distance [m] of ``(..., 3)`` points to the head sphere and neck capsule; < 0 inside."""
    p = np.asarray(points)
    head = _norm(p - params.head_center) - params.head_radius
    a, b, r = params.neck
    t = np.clip(np.sum((p - a) * (b - a), axis=-1) / np.sum((b - a) ** 2), 0.0, 1.0)
    neck = _norm(p - (a + t[..., None] * (b - a))) - r
    return np.minimum(head, neck)


def body_signed_distance(params: BodyParams, points: np.ndarray) -> np.ndarray:
    """Signed distance [m] of ``(..., 3)`` points to torso, neck and head; < 0 inside."""
    return np.minimum(torso_signed_distance(params, points), head_signed_distance(params, points))


def body_gradient(params: BodyParams, points: np.ndarray, eps: float = 1e-4) -> np.ndarray:
    """``(..., 3)`` unit outward direction of :func:`body_signed_distance` (central differences)."""
    p = np.asarray(points, dtype=np.float64)[..., None, :]
    steps = np.concatenate([np.eye(3), -np.eye(3)]) * eps  # (6, 3): one call for all six probes
    sd = body_signed_distance(params, p + steps)  # (..., 6)
    g = sd[..., :3] - sd[..., 3:]
    return g / np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-12)

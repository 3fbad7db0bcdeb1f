"""The synthetic sign corpus: signers' bodies, a sign vocabulary, and sentences generated from them.

::

    from nlo_lab.corpus import corpus_clip, corpus_names, sign_corpus
    demo = corpus_clip("hospital_03")        # one sequence, a Demonstration
    test = sign_corpus("test")               # the 25 test sequences (two scenarios)

Modules, along the data's path: :mod:`~nlo_lab.corpus.body` (dimensions, joints, ranges, the
signed distances to torso, neck and head),
:mod:`~nlo_lab.corpus.arm_kinematics` (arm and hand FK, analytic arm IK),
:mod:`~nlo_lab.corpus.signs` (handshapes, locations, movements, held-out combinations),
:mod:`~nlo_lab.corpus.sign_motion` (one sign on one signer's body),
:mod:`~nlo_lab.corpus.generate` (one sentence, checked until plausible) and
:mod:`~nlo_lab.corpus.corpus` (the five scenarios, cached per seed).
"""

from nlo_lab.corpus.arm_kinematics import ArmPose, arm_fk, arm_ik, hand_frame, knuckle_centre, rot_x, rot_y, rot_z, wrist_position
from nlo_lab.corpus.body import (
                                 ARM_JOINT_NAMES,
                                 ARM_RANGES,
                                 BASE_INDEX,
                                 BODY_RANGES,
                                 FINGER_JOINT_NAMES,
                                 FINGER_RANGES,
                                 FINGER_SEGMENTS,
                                 BodyParams,  # fmt: skip
                                 body_gradient,
                                 body_signed_distance,
                                 head_signed_distance,
                                 random_body,
                                 torso_signed_distance,
)
from nlo_lab.corpus.corpus import (
                                 N_SIGNERS,
                                 SCENARIOS,
                                 SPLITS,
                                 Scenario,
                                 corpus_angles,
                                 corpus_clip,
                                 corpus_lexicon,
                                 corpus_names,
                                 sign_corpus,
)
from nlo_lab.corpus.generate import (
                                 CLEARANCE,
                                 ELBOW_CLEARANCE,
                                 FINGERTIP_ACCEL_LIMIT,
                                 HAND_CLEARANCE,
                                 WRIST_ACCEL_LIMIT,
                                 WRIST_SPEED_LIMIT,
                                 Clip,  # fmt: skip
                                 generate_sequence,
                                 plausible,
)
from nlo_lab.corpus.sign_motion import PATH_ACCEL, PUSH_CLEARANCE, Signer, sign_duration_floor, sign_segment
from nlo_lab.corpus.signs import (
                                 CONTACT_LOCATIONS,
                                 HANDSHAPES,
                                 HELD_OUT_PAIRS,
                                 LOCATIONS,
                                 MOVEMENTS,
                                 PALMS,
                                 PATTERNS,
                                 Sign,
                                 handshape,
                                 is_test_combination,  # fmt: skip
                                 location_normal,
                                 location_point,
                                 minimum_jerk,
                                 movement_path,
                                 random_sign,
)

__all__ = [
    # corpus
    "sign_corpus", "corpus_clip", "corpus_names", "corpus_angles", "corpus_lexicon",
    "Scenario", "SCENARIOS", "SPLITS", "N_SIGNERS",
    # body
    "BodyParams", "random_body", "ARM_JOINT_NAMES", "FINGER_JOINT_NAMES", "ARM_RANGES", "FINGER_RANGES",
    "BODY_RANGES", "BASE_INDEX", "FINGER_SEGMENTS",
    # arm_kinematics
    "ArmPose", "arm_fk", "arm_ik", "hand_frame", "knuckle_centre", "wrist_position", "rot_x", "rot_y", "rot_z",
    "torso_signed_distance", "head_signed_distance", "body_signed_distance", "body_gradient",
    # signs
    "HANDSHAPES", "LOCATIONS", "CONTACT_LOCATIONS", "PALMS", "MOVEMENTS", "PATTERNS", "HELD_OUT_PAIRS", "Sign",
    "minimum_jerk", "handshape", "location_point", "location_normal", "movement_path", "is_test_combination",
    "random_sign",
    # sign_motion
    "Signer", "sign_segment", "sign_duration_floor", "PUSH_CLEARANCE", "PATH_ACCEL",
    # generate
    "Clip", "generate_sequence", "plausible", "CLEARANCE", "HAND_CLEARANCE", "ELBOW_CLEARANCE",
    "WRIST_ACCEL_LIMIT", "WRIST_SPEED_LIMIT", "FINGERTIP_ACCEL_LIMIT",
]  # fmt: skip

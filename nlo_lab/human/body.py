"""The old import path of the synthetic signers' body and its kinematics: everything lives in :mod:`nlo_lab.corpus`.

Kept because notebooks of earlier versions, which ``nlo-lab lab`` never overwrites
in a learner's folder, import ``nlo_lab.human.body``.
"""

from nlo_lab.corpus import (
    ARM_JOINT_NAMES,
    ARM_RANGES,
    BASE_INDEX,
    BODY_RANGES,
    FINGER_JOINT_NAMES,
    FINGER_RANGES,
    ArmPose,
    BodyParams,
    arm_fk,
    arm_ik,
    body_gradient,
    body_signed_distance,
    hand_frame,
    head_signed_distance,
    knuckle_centre,
    random_body,
    rot_x,
    rot_y,
    rot_z,
    torso_signed_distance,
    wrist_position,
)

__all__ = [
    "ARM_JOINT_NAMES",
    "FINGER_JOINT_NAMES",
    "ARM_RANGES",
    "FINGER_RANGES",
    "BODY_RANGES",
    "BASE_INDEX",
    "BodyParams",
    "ArmPose",
    "random_body",
    "rot_x",
    "rot_y",
    "rot_z",
    "arm_fk",
    "hand_frame",
    "arm_ik",
    "knuckle_centre",
    "wrist_position",
    "torso_signed_distance",
    "head_signed_distance",
    "body_signed_distance",
    "body_gradient",
]

"""The URDF model as the robot drives it: the joints it does not actuate fixed, the robot frame at the root.

A real robot's URDF moves more than the two arms: legs, a torso lift, a head, wheels and
casters, gripper fingers. Retargeting actuates the joints on the chains from the base to
the wrists and fingertips (a spec's ``actuated_joints``); every other moving joint is fixed
at the value the spec gives it (``fixed_joints``; ``nlo-lab robot init`` writes zero, or the
limit nearest to zero), and a mimic joint follows its source, actuated or fixed.
:func:`fixed_model` turns each such joint into a fixed one whose origin holds that value.

The objective compares directions in the robot frame (origin between the shoulders, X
forward, Y left, Z up). The bundled robots' URDF root is that frame. For another URDF the
spec names a ``base_link`` and the ``robot_frame`` on it; :func:`framed_model` puts a fixed
root link ``nlo_lab_robot_frame`` above the URDF's root so that the world frame of forward
kinematics is the robot frame.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np

from nlo_lab.errors import RobotDescriptionError
from nlo_lab.robot.urdf import MOVING_TYPES, JointInfo, URDFModel
from nlo_lab.rotations import rpy_to_matrix

__all__ = ["FRAME_LINK", "joint_motion", "fixed_model", "framed_model"]

FRAME_LINK = "nlo_lab_robot_frame"  # the root link framed_model adds


def joint_motion(joint: JointInfo, value: float) -> np.ndarray:
    """``(4, 4)`` the joint's own motion at ``value`` (rad about the axis, m along it; identity otherwise)."""
    T = np.eye(4)
    if joint.type in MOVING_TYPES:
        T[:3, :3] = _rotation(joint.axis, value)
    elif joint.type == "prismatic":
        T[:3, 3] = value * np.asarray(joint.axis)
    return T


def _rotation(axis, angle: float) -> np.ndarray:
    a = np.asarray(axis, dtype=np.float64)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


def fixed_model(model: URDFModel, actuated: Sequence[str], fixed: Mapping[str, float] | None, where) -> URDFModel:
    """``model`` with every moving joint that is neither actuated nor a mimic of an actuated one fixed.

    Args:
        model: the parsed URDF.
        actuated: the actuated joints.
        fixed: joint -> value [rad or m] (a spec's ``fixed_joints``), or None: then only the
            joints nlo_lab cannot actuate (prismatic, floating, planar) are an error, and the
            others are left for :class:`~nlo_lab.robot.kinematics.KinematicTree` to refuse.
        where: the spec file, for messages.

    Raises:
        RobotDescriptionError: a joint of ``fixed`` that does not exist, a moving joint neither
            actuated, nor a mimic of one, nor listed in ``fixed``.
    """
    joints = {j.name: j for j in model.joints}
    values = dict(fixed or {})
    unknown = sorted(set(values) - set(joints))
    if unknown:
        raise RobotDescriptionError(f"{where}: fixed_joints names joints {unknown} that do not exist in {model.path}")
    act = set(actuated)

    def value_of(j: JointInfo, depth: int = 0) -> float | None:
        """The fixed value of a joint that is not actuated (None: it follows an actuated joint)."""
        if depth > len(joints):
            raise RobotDescriptionError(f"{model.path}: mimic joints form a cycle at {j.name!r}")
        if j.name in act:
            return None
        if j.type == "fixed":  # the source of a mimic joint may be fixed in the URDF (Talos' reduced model)
            return 0.0
        if j.mimic is not None and j.mimic[0] in joints:
            source = value_of(joints[j.mimic[0]], depth + 1)
            return None if source is None else j.mimic[1] * source + j.mimic[2]
        if j.name in values:
            return values[j.name]
        if fixed is not None or j.type not in MOVING_TYPES:
            hint = "list it in the spec's fixed_joints" + ("" if j.type not in MOVING_TYPES else " or actuated_joints")
            raise RobotDescriptionError(f"{where}: {j.type} joint {j.name!r} is neither actuated nor a mimic of an actuated joint: {hint}")
        return None  # no fixed_joints: the kinematic tree names the joint

    out = []
    for j in model.joints:
        value = None if j.type == "fixed" else value_of(j)
        if value is None:
            out.append(j)
        else:
            out.append(dataclasses.replace(j, type="fixed", mimic=None, origin=j.origin @ joint_motion(j, value)))
    return dataclasses.replace(model, joints=tuple(out))


def framed_model(model: URDFModel, base_link: str, frame, where) -> URDFModel:
    """``model`` with the robot frame as its root (unchanged when that is the URDF's root already).

    Args:
        model: a model whose joints above ``base_link`` are fixed (:func:`fixed_model`).
        base_link: the link the robot frame sits on.
        frame: ``(xyz, rpy)`` of the robot frame in ``base_link``'s frame, or None (base_link's frame).
        where: the spec file, for messages.

    Raises:
        RobotDescriptionError: an unknown base_link, or one below a moving joint.
    """
    if base_link not in model.links:
        raise RobotDescriptionError(f"{where}: base_link {base_link!r} does not exist in {model.path}")
    T = np.eye(4)
    link = base_link
    while link != model.root:
        j = model.joint_above(link)
        if j.type != "fixed":
            raise RobotDescriptionError(f"{where}: base_link {base_link!r} hangs below the moving joint {j.name!r}: "
                                        "the base must sit above both arms")
        T = j.origin @ T
        link = j.parent
    if frame is not None:
        F = np.eye(4)
        F[:3, :3], F[:3, 3] = rpy_to_matrix(frame[1]), frame[0]
        T = T @ F
    if np.allclose(T, np.eye(4), atol=1e-12):
        return model
    if FRAME_LINK in model.links:
        raise RobotDescriptionError(f"{model.path}: a link is named {FRAME_LINK!r}, the name nlo_lab gives the robot frame")
    root_joint = JointInfo(f"{FRAME_LINK}_joint", "fixed", FRAME_LINK, model.root, np.linalg.inv(T), np.array([1.0, 0.0, 0.0]), 0.0, 0.0)
    return dataclasses.replace(model, root=FRAME_LINK, links=(FRAME_LINK, *model.links), joints=(root_joint, *model.joints))

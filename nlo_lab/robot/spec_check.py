"""A spec checked against its URDF, and its summary: what ``nlo-lab robot check SPEC.json`` prints.

:func:`check_spec` loads the robot (every check of :func:`~nlo_lab.robot.load_robot`: the
spec's fields, the URDF's safety and tree, each named link and joint, with the closest names
in the URDF for one that does not exist) and measures it: joints per arm and per hand, arm
lengths, fingers, capsules, pairs, and the pairs that touch at the rest pose.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
import torch

from nlo_lab.human.demonstration import SIDES
from nlo_lab.robot.robot import Robot, load_robot

__all__ = ["SpecReport", "check_spec", "spec_summary"]


@dataclass
class SpecReport:
    """What a spec describes.

    Attributes:
        robot: the loaded robot.
        arm_joints, hand_joints: side -> actuated joints of the arm, of the hand.
        lengths: side -> (upper arm, forearm) [m] at the reference pose.
        fingers: side -> the fingers the spec names.
        fixed: how many moving joints of the URDF the spec fixes.
        colliding: checked pairs closer than 0 at the neutral pose, with their distance [m].
        own_fingers: side -> the fingers with a joint of their own (:meth:`Robot.finger_joints
            <nlo_lab.robot.Robot.finger_joints>`): those the hand stage's finger search can move.
    """

    robot: Robot
    arm_joints: dict[str, list[str]]
    hand_joints: dict[str, list[str]]
    lengths: dict[str, tuple[float, float]]
    fingers: dict[str, list[str]]
    fixed: int
    colliding: list[tuple[str, str, float]] = field(default_factory=list)
    own_fingers: dict[str, list[str]] = field(default_factory=dict)


def _below(model, link: str) -> set[str]:
    return set(model.subtree(link))


def check_spec(path) -> SpecReport:
    """Load and measure the spec at ``path`` (or a bundled name).

    Raises:
        RobotDescriptionError: the first problem, in one line naming the file and the field (and,
            for an unknown link or joint, the closest names in the URDF).
    """
    robot = load_robot(path)
    model = robot.model
    joint = {j.name: j for j in model.joints}
    arm_joints, hand_joints, lengths, fingers = {}, {}, {}, {}
    for side in SIDES:
        arm = robot.arm(side)
        hand = _below(model, arm.wrist) - {arm.wrist}
        wrist_up = set()
        link = arm.wrist
        while (j := model.parent_joint(link)) is not None:
            wrist_up.add(j.child)
            link = j.parent
        arm_joints[side] = [n for n in robot.joint_names if joint[n].child in wrist_up and joint[n].child not in hand]
        hand_joints[side] = [n for n in robot.joint_names if joint[n].child in hand]
        up, fore = robot.zero_pose_lengths(side)
        lengths[side] = (float(up), float(fore))
        fingers[side] = list(arm.fingers)
    with torch.no_grad():
        d = robot.capsule_distances(robot.forward_kinematics(robot.neutral_q[None].double().to(robot.dtype)))[0]
    colliding = [(a, b, float(v)) for (a, b), v in zip(robot.spec.collision_pairs, d.tolist(), strict=True) if v < 0]
    fixed = len(robot.spec.fixed_joints or ())
    own = {side: [f for f in fingers[side] if robot.finger_joints(side, f)] for side in SIDES}
    return SpecReport(robot, arm_joints, hand_joints, lengths, fingers, fixed, colliding, own)


def spec_summary(report: SpecReport) -> list[str]:
    """The summary lines ``nlo-lab robot check`` prints."""
    r = report.robot
    lines = [f"{r.name}: {r.n_joints} actuated joints ({sum(len(v) for v in report.arm_joints.values())} arm, "
             f"{sum(len(v) for v in report.hand_joints.values())} hand), {report.fixed} fixed; URDF {os.path.normpath(r.spec.urdf)}"]
    for side in SIDES:
        up, fore = report.lengths[side]
        arm = r.arm(side)
        fingers = ", ".join(report.fingers[side]) or "none"
        own = report.own_fingers.get(side, [])
        if report.fingers[side] and own == report.fingers[side]:
            fingers += " (each with a joint of its own)"
        elif report.fingers[side]:  # the finger search (--hand-search) moves a finger's own joints only
            alone = f"a joint of its own: {', '.join(own)}; " if own else ""
            rest = [f for f in report.fingers[side] if f not in own]
            fingers += f" ({alone}no joint of its own, the finger search cannot move: {', '.join(rest)})"
        lines.append(f"  {side:<5} arm: {len(report.arm_joints[side])} joints, upper arm {up:.3f} m + forearm {fore:.3f} m "
                     f"(shoulder {arm.shoulder}, elbow {arm.elbow}, wrist {arm.wrist}); "
                     f"hand: {len(report.hand_joints[side])} joints, fingers {fingers}")
    margins = r.collision_margins.detach().double().numpy()
    margin = f"margin {float(np.median(margins)):.3f} m" if len(margins) else "no pairs"
    lines.append(f"  collision: {len(r.spec.capsules)} capsules, {len(r.spec.collision_pairs)} checked pairs, {margin}")
    if report.colliding:
        worst = min(report.colliding, key=lambda c: c[2])
        lines.append(f"  at the rest pose {len(report.colliding)} pairs are in collision (deepest {worst[0]} / {worst[1]}: "
                     f"{-worst[2] * 1000:.1f} mm): add a collision-free \"neutral_pose\" or remove those pairs")
    else:
        lines.append("  at the rest pose no checked pair is in collision")
    return lines

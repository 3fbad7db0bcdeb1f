"""A complete robot spec drafted from any URDF: what ``nlo-lab robot init URDF --out SPEC.json`` writes.

:func:`draft_spec` decides, in order:

1. **The arms**: given (``left_arm=(shoulder, elbow, wrist)``) or found from the tree and the names
   (:func:`~nlo_lab.robot.arm_finder.find_arms`); **the fingers**: given (finger -> tip link; the
   base is the child of the first moving joint below the wrist) or found by name below the wrist.
2. **The base**: given, or the link where the two arms' chains meet.
3. **Actuated joints**: the moving joints on the chains from the base to the wrists and to the
   fingertips (the joint whose child is the shoulder is one of them); a mimic joint on a chain
   follows its source, which is actuated in its place. Every other moving joint is fixed at zero,
   or at its limit nearest to zero (``fixed_joints``). Continuous joints get [-pi, pi] (a note says
   so); an actuated joint without a ``<limit>`` is an error.
4. **Velocity limits**: the URDF's ``<limit velocity>``; where it is missing or not > 0,
   :data:`DEFAULT_VELOCITY` and a warning naming the joint.
5. **The robot frame** (``robot_frame`` on the base): origin between the shoulders at rest, Y from
   the right shoulder to the left one, Z the URDF root's up made square to Y, X = Y x Z.
6. **Wrist alignments**, derived (:mod:`~nlo_lab.robot.wrist_alignment`).
7. **Capsules and checked pairs** fitted to the collision geometry, else the visual geometry
   (:mod:`~nlo_lab.robot.capsule_draft`), with the margin :data:`MARGIN` scaled by arm length;
   the link pairs the robot's SRDF disables (``srdf=``) are not checked.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nlo_lab.errors import RobotDescriptionError, escape
from nlo_lab.human.demonstration import FINGERS, SIDES
from nlo_lab.robot.arm_finder import ArmChain, find_arms, find_fingers
from nlo_lab.robot.capsule_draft import REACH_SAMPLES, Arms, CapsuleDraft, draft_collision
from nlo_lab.robot.robot import Robot, closest
from nlo_lab.robot.spec import FINGER_ALIASES, ArmSpec, CapsuleSpec, RobotSpec
from nlo_lab.robot.srdf import disabled_pairs
from nlo_lab.robot.urdf import MOVING_TYPES, URDFModel, parse_urdf
from nlo_lab.robot.wrist_alignment import wrist_alignment
from nlo_lab.rotations import matrix_to_rpy

__all__ = ["DEFAULT_VELOCITY", "MARGIN", "Draft", "draft_spec", "robot_frame"]

DEFAULT_VELOCITY = 2.0  # [rad/s] where a URDF states none: a moderate speed for a servo (the Inspire hand's assumed figure)
MARGIN = 0.005  # [m] collision margin for an arm as long as YuMi's (0.52 m); scaled by arm length, at least 0.002


@dataclass
class Draft:
    """What :func:`draft_spec` made.

    Attributes:
        spec: the spec as JSON-ready data.
        robot: the robot it describes (a ``Robot``).
        arms: side -> the arm chain found or given.
        fingers: side -> finger -> (base, tip).
        found: the arms were found (not given).
        notes: what the user should know (continuous joints limited to +-pi, a neutral pose needed ...).
        warnings: defaults that stand in for missing facts (velocity limits).
        collision: the capsule draft.
    """

    spec: dict
    robot: Robot
    arms: dict[str, ArmChain]
    fingers: dict[str, dict[str, tuple[str, str]]]
    found: bool
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    collision: CapsuleDraft | None = None

    def summary(self) -> list[str]:
        """What ``nlo-lab robot init`` prints: the arms it found, what it wrote, the notes."""
        draft, out = self, self.robot.spec.path
        spec, robot = draft.spec, draft.robot
        lines = []
        if draft.found:
            lines.append("arms found from the tree and the names (correct them with --left-arm / --right-arm SHOULDER,ELBOW,WRIST):")
            for side in ("left", "right"):
                a = draft.arms[side]
                lines.append(f"  {side:<5} shoulder {a.shoulder}, elbow {a.elbow}, wrist {a.wrist}")
        counts = {s: sum(1 for n in draft.arms[s].joints if n in robot.joint_names) for s in ("left", "right")}
        hand = robot.n_joints - len({n for s in ("left", "right") for n in draft.arms[s].joints} & set(robot.joint_names))
        lines.append(f"wrote {escape(out)}: robot {escape(spec['name'])}, base {spec['base_link']}")
        lines.append(f"  {robot.n_joints} actuated joints (left arm {counts['left']}, right arm {counts['right']}, hands {hand}), "
                     f"{len(spec['fixed_joints'])} fixed")
        for side in ("left", "right"):
            fingers = ", ".join(draft.fingers[side]) or "none"
            up, fore = robot.zero_pose_lengths(side)
            lines.append(f"  {side:<5} arm {up + fore:.3f} m (upper {up:.3f} + fore {fore:.3f}); fingers: {fingers}")
        c = draft.collision
        assert c is not None  # set by draft_spec
        lines.append(f"  collision: {len(spec['capsules'])} capsules fitted to the URDF's geometry, {len(spec['collision_pairs'])} "
                     f"checked pairs ({c.thinned} with thinned capsules), margin {spec['collision_margin']['default']} m")
        defaults = len(draft.warnings)
        lines.append("  velocity limits from the URDF" + (f" ({defaults} joints at the assumed default)" if defaults else ""))
        lines.extend(f"  note: {n}" for n in draft.notes)
        lines.append(f"next: nlo-lab robot check {escape(out)}; nlo-lab train --robot {escape(out)} --out {escape(Path(out).with_suffix('.pt'))}")
        return lines


def _link(model: URDFModel, name: str, what: str) -> str:
    if name not in model.links:
        raise RobotDescriptionError(f"{model.path}: {what} names link {name!r}, which does not exist{closest(name, model.links)}")
    return name


def _path_joints(model: URDFModel, top: str, bottom: str, what: str) -> list:
    """The joints from link ``top`` down to link ``bottom`` (top first)."""
    out, link = [], bottom
    while link != top:
        j = model.parent_joint(link)
        if j is None:
            raise RobotDescriptionError(f"{model.path}: {what}: link {bottom!r} does not hang below {top!r}")
        out.append(j)
        link = j.parent
    return out[::-1]


def _ancestors(model: URDFModel, link: str) -> list[str]:
    out = [link]
    while (j := model.parent_joint(out[-1])) is not None:
        out.append(j.parent)
    return out


def _given_arm(model: URDFModel, side: str, links: tuple[str, str, str]) -> ArmChain:
    shoulder, elbow, wrist = (_link(model, name, f"--{side}-arm") for name in links)
    if shoulder not in _ancestors(model, elbow) or elbow not in _ancestors(model, wrist):
        raise RobotDescriptionError(f"{model.path}: --{side}-arm: {shoulder!r}, {elbow!r}, {wrist!r} must hang one below the other")
    top = model.parent_joint(shoulder)
    joints = [j.name for j in _path_joints(model, shoulder, wrist, f"--{side}-arm") if j.type != "fixed"]
    return ArmChain(side, tuple(([top.name] if top is not None and top.type != "fixed" else []) + joints), shoulder, elbow, wrist)


def _given_fingers(model: URDFModel, side: str, wrist: str, tips: dict[str, str]) -> dict[str, tuple[str, str]]:
    out = {}
    for finger, tip in tips.items():
        finger = FINGER_ALIASES.get(finger, finger)
        if finger not in FINGERS:
            raise RobotDescriptionError(f"--{side}-hand: unknown finger {finger!r}; fingers are thumb, index, middle, ring, little (or pinky)")
        _link(model, tip, f"--{side}-hand {finger}")
        moving = [j for j in _path_joints(model, wrist, tip, f"--{side}-hand {finger}") if j.type != "fixed"]
        if not moving:
            raise RobotDescriptionError(f"{model.path}: --{side}-hand {finger}: no moving joint between the wrist {wrist!r} and {tip!r}")
        out[finger] = (moving[0].child, tip)
    return out


def _lca(model: URDFModel, a: str, b: str) -> str:
    up = set(_ancestors(model, b))
    return next(link for link in _ancestors(model, a) if link in up)


def robot_frame(poses: dict, base: str, root: str, left_shoulder: str, right_shoulder: str) -> np.ndarray:
    """``(4, 4)`` the robot frame in ``base``'s frame from link poses at rest (see the module docstring).

    Up is the URDF root's Z (URDFs are Z-up: REP 103), else the base's, made square to the shoulder line.
    """
    T_base = poses[base]
    pl, pr = poses[left_shoulder][:3, 3], poses[right_shoulder][:3, 3]
    y = pl - pr
    if np.linalg.norm(y) < 1e-6:
        raise RobotDescriptionError("the two shoulders are at one point: no robot frame")
    y /= np.linalg.norm(y)
    for up in (poses[root][:3, 2], T_base[:3, 2]):
        up = up - (up @ y) * y
        if np.linalg.norm(up) > 1e-3:
            break
    else:
        raise RobotDescriptionError("the root's and the base's Z both run through the shoulders: no up direction")
    z = up / np.linalg.norm(up)
    F = np.eye(4)
    F[:3, :3] = np.stack([np.cross(y, z), y, z], axis=1)
    F[:3, 3] = 0.5 * (pl + pr)
    return np.linalg.inv(T_base) @ F


def _actuated(model: URDFModel, base: str, arms: dict[str, ArmChain], fingers: dict, notes: list[str]) -> list[str]:
    """The joints on the chains from the base to the wrists and fingertips, mimic joints replaced by their sources."""
    joints = {j.name: j for j in model.joints}
    order: list[str] = []

    def add(chain: list, what: str) -> None:
        for j in chain:
            while j.mimic is not None and j.mimic[0] in joints and joints[j.mimic[0]].type != "fixed":
                j = joints[j.mimic[0]]  # a mimic joint follows its source: the source is actuated
            if j.type == "fixed" or j.name in order:
                continue
            if j.type not in MOVING_TYPES:
                raise RobotDescriptionError(f"{model.path}: {what} moves through the {j.type} joint {j.name!r}; "
                                            "nlo_lab actuates revolute and continuous joints (choose other links, or --base)")
            if not j.has_limit:
                raise RobotDescriptionError(f"{model.path}: joint {j.name!r} on the {what} has no <limit>: "
                                            "give it lower and upper (rad) in the URDF")
            order.append(j.name)

    for side in SIDES:
        add(_path_joints(model, base, arms[side].wrist, f"{side} arm"), f"{side} arm")
    for side in SIDES:
        for finger, (_, tip) in fingers[side].items():
            add(_path_joints(model, arms[side].wrist, tip, f"{side} {finger} finger"), f"{side} {finger} finger")
    continuous = [n for n in order if joints[n].type == "continuous"]
    if continuous:
        notes.append(f"continuous joints are limited to [-pi, pi] rad: {', '.join(continuous)}")
    return order


def _arms_spec(arms, fingers, alignments) -> dict:
    out = {}
    for side in SIDES:
        arm = {"shoulder": arms[side].shoulder, "elbow": arms[side].elbow, "wrist": arms[side].wrist,
               "wrist_alignment_rpy": [round(float(v), 9) for v in alignments[side]]}
        if fingers[side]:
            arm["fingers"] = {f: list(pair) for f, pair in fingers[side].items()}
        out[side] = arm
    return out


def _spec_object(data: dict, path: Path, urdf: Path) -> RobotSpec:
    """A :class:`RobotSpec` from drafted data (the file is not written yet)."""
    arms = {s: ArmSpec(s, a["shoulder"], a["elbow"], a["wrist"], tuple(a["wrist_alignment_rpy"]),
                       {f: tuple(p) for f, p in a.get("fingers", {}).items()}) for s, a in data["arms"].items()}
    frame = data.get("robot_frame")
    capsules = tuple(CapsuleSpec(c["name"], c["link"], tuple(c["p0"]), tuple(c["p1"]), c["radius"]) for c in data.get("capsules", []))
    pairs = tuple(tuple(p) for p in data.get("collision_pairs", []))
    margin = data.get("collision_margin", {}).get("default", 0.0)
    return RobotSpec(
        name=data["name"], path=path, urdf=urdf, base_link=data["base_link"], actuated_joints=tuple(data["actuated_joints"]),
        arms=arms, capsules=capsules, collision_pairs=pairs, pair_margins=(margin,) * len(pairs), fixed_joints=tuple(data["fixed_joints"].items()),
        velocity_limits=tuple(data["velocity_limits"].items()),
        robot_frame=None if frame is None else (tuple(frame["xyz"]), tuple(frame["rpy"])),
        srdf=None if data.get("srdf") is None else Path(os.path.normpath(path.parent / data["srdf"])),
        shape_contacts=tuple(tuple(p) for p in data.get("shape_contacts", [])),
    )


def draft_spec(urdf, out, *, left_arm=None, right_arm=None, left_hand=None, right_hand=None, base=None, name=None,
               srdf=None, samples: int | None = None, prefilter: bool = True, progress: bool = False) -> Draft:
    """Draft the spec of the robot in ``urdf``, to be written at ``out`` (see the module docstring).

    Args:
        urdf: the URDF file.
        out: where the spec will be written (its ``urdf`` field is relative to it).
        left_arm, right_arm: ``(shoulder, elbow, wrist)`` link names, or None to find the arm.
        left_hand, right_hand: ``{finger: tip link}`` (``{}``: no fingers), or None to find them by name.
        base: the base link, or None for the link where the arms meet.
        name: the robot's name (default: the URDF's).
        srdf: the robot's SRDF, if it has one: the link pairs it disables are not checked (and the spec names it).
        samples: random poses of the capsule reach test (default: ``capsule_draft.REACH_SAMPLES``).
        prefilter: the capsule draft's fast path (:func:`~nlo_lab.robot.capsule_draft.draft_collision`; the same spec).
        progress: show a tqdm progress bar over the capsule pairs weighed (iCub's draft takes a minute or two).

    Raises:
        RobotDescriptionError: a URDF without two arms, an unknown link (with the closest names),
            a missing joint limit on an actuated joint, a cycle, an unsafe file (one line each).
    """
    urdf, out = Path(urdf), Path(out)
    model = parse_urdf(urdf)
    disabled = disabled_pairs(srdf) if srdf is not None else set()
    found = left_arm is None or right_arm is None
    arms = find_arms(model) if found else {}
    given = {"left": left_arm, "right": right_arm}
    for side in SIDES:
        if given[side] is not None:
            arms[side] = _given_arm(model, side, tuple(given[side]))
    hands = {"left": left_hand, "right": right_hand}
    fingers = {s: find_fingers(model, arms[s].wrist) if hands[s] is None else _given_fingers(model, s, arms[s].wrist, hands[s]) for s in SIDES}
    starts = {s: model.joint(arms[s].joints[0]).parent for s in SIDES}
    base = _link(model, base, "--base") if base is not None else _lca(model, starts["left"], starts["right"])
    for side in SIDES:
        if base not in _ancestors(model, arms[side].shoulder):
            raise RobotDescriptionError(f"{model.path}: --base {base!r} is not above the {side} shoulder {arms[side].shoulder!r}")
    notes: list[str] = []
    warnings_: list[str] = []
    actuated = _actuated(model, base, arms, fingers, notes)
    joints = {j.name: j for j in model.joints}
    fixed = {j.name: round(float(np.clip(0.0, j.lower, j.upper)) if j.has_limit else 0.0, 9)
             for j in model.joints if j.type != "fixed" and j.name not in actuated and j.mimic is None}
    velocity = {}
    for n in actuated:
        velocity[n] = joints[n].velocity or DEFAULT_VELOCITY
        if joints[n].velocity is None:
            warnings_.append(f"joint {n!r} has no velocity limit in the URDF: {DEFAULT_VELOCITY} rad/s assumed")
    data = {
        "name": name or model.name or urdf.stem,
        "description": f"drafted by nlo-lab robot init from {urdf.name}",
        "urdf": os.path.relpath(urdf.resolve(), out.resolve().parent),
        "base_link": base,
        "actuated_joints": actuated,
        "arms": _arms_spec(arms, fingers, {s: (0.0, 0.0, 0.0) for s in SIDES}),
        "fixed_joints": fixed,
        "velocity_limits": velocity,
        "velocity_limits_source": "the URDF's <limit velocity>" + (f"; {DEFAULT_VELOCITY} rad/s assumed where it gives none" if warnings_ else ""),
    }
    if srdf is not None:
        data["srdf"] = os.path.relpath(Path(srdf).resolve(), out.resolve().parent)
    robot = Robot(_spec_object(data, out, urdf), model)  # the base's frame, to place the robot frame
    rest = {n: T for n, T in zip(robot.link_names, robot.forward_kinematics_tensor(robot.reference_q.double()).numpy(), strict=True)}
    F = robot_frame(rest, base, model.root, arms["left"].shoulder, arms["right"].shoulder)
    data["robot_frame"] = {"xyz": [round(float(v), 6) + 0.0 for v in F[:3, 3]], "rpy": [round(float(v), 9) + 0.0 for v in matrix_to_rpy(F[:3, :3])]}
    robot = Robot(_spec_object(data, out, urdf), model)
    alignments = {s: matrix_to_rpy(wrist_alignment(robot, s, fingers[s])) for s in SIDES}
    data["arms"] = _arms_spec(arms, fingers, alignments)
    robot = Robot(_spec_object(data, out, urdf), model)
    length = float(np.mean([sum(robot.zero_pose_lengths(s)) for s in SIDES]))
    margin = max(0.002, round(MARGIN * length / 0.52, 3))
    sides = {s: set(robot.model.subtree(arms[s].shoulder)) for s in SIDES}
    collision = draft_collision(robot.model, robot.tree, robot.reference_q.double().numpy(), robot.lower_limits.double().numpy(),
                                robot.upper_limits.double().numpy(), Arms(sides, {s: arms[s].wrist for s in SIDES}), margin,
                                samples=REACH_SAMPLES if samples is None else samples, disabled=disabled, prefilter=prefilter,
                                progress=progress)
    data["capsules"] = [{"name": c.name, "link": c.link, "p0": list(c.p0), "p1": list(c.p1), "radius": c.radius} for c in collision.capsules]
    data["collision_pairs"] = [list(p) for p in collision.pairs]
    data["collision_margin"] = {"default": margin, **{f"{a}/{b}": m for (a, b), m in collision.margins.items()}}
    if collision.arms_touching:
        notes.append(f"the arms touch at the rest pose ({len(collision.arms_touching)} capsule pairs, e.g. "
                     f"{collision.arms_touching[0][0]} / {collision.arms_touching[0][1]}): add a collision-free \"neutral_pose\"")
    if collision.blind:
        notes.append(f"capsules too loose to tell the rest pose from a collision of their geometry: {len(collision.blind)} link "
                     f"pair(s), e.g. {collision.blind[0][0]} / {collision.blind[0][1]} (check the output with GeometryCollision)")
    if collision.shape_contacts:
        data["shape_contacts"] = [list(p) for p in collision.shape_contacts]
        notes.append(f"collision shapes that meet where the parts do not (their visual shapes never do): {len(collision.shape_contacts)} "
                     f"link pair(s), e.g. {collision.shape_contacts[0][0]} / {collision.shape_contacts[0][1]}; left out of the check by "
                     "the URDF's geometry as \"shape_contacts\" (check the URDF's collision elements)")
    if collision.unchecked:
        notes.append(f"{len(collision.unchecked)} link pairs are not checked: their capsules touch at rest though their geometry does not")
    if not math.isfinite(length) or length <= 0:
        raise RobotDescriptionError(f"{model.path}: the arms have no length at the rest pose")
    robot = Robot(_spec_object(data, out, urdf), model)  # with its capsules: the robot the file describes
    return Draft(data, robot, arms, fingers, found, notes, warnings_, collision)

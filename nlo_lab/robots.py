"""Robots: a URDF plus a small spec file, with FK, capsule distances and the structure graph.

``load_robot("nao")`` reads ``assets/robots/nao.json`` (the spec) and the URDF
it names. The spec fixes the order of the actuated joints, the role links of
each arm (shoulder, elbow, wrist; finger base and tip), the wrist frame's
alignment to the human wrist convention of :mod:`nlo_lab.human.demonstration`,
the collision capsules, the checked pairs and their margins (see
``docs/ARCHITECTURE.md`` for the format).

Structure graph: nodes are the actuated joints; an edge goes from each joint's
nearest actuated ancestor to the joint (parent -> child, as in the paper).
Mimic joints are not nodes (their angle follows their source). The first
joint of each arm has no actuated ancestor; instead of a virtual root node
(which would add a node without an angle), the arm roots are joined to each
other by one edge in each direction, so that every node receives messages and
the two arms can coordinate (the collision term couples them). Edge features
are the child joint's origin (xyz [m], rpy [rad]) relative to the parent
joint's frame, fixed joints in between folded in; for the root-to-root edges,
the child root's frame relative to the other root's frame.
"""

from __future__ import annotations

import copy
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import torch

from nlo_lab.collision import segment_distance_ends
from nlo_lab.errors import NloLabError, RobotDescriptionError, UnknownRobotError
from nlo_lab.graph import NODE_ARM, NODE_HAND, Graph
from nlo_lab.human.demonstration import FINGERS, SIDES
from nlo_lab.kinematics import KinematicTree, URDFModel, parse_urdf
from nlo_lab.rotations import matrix_to_rpy, rpy_to_matrix
from nlo_lab.paths import BUNDLED_ROBOTS, ROBOTS_DIR, is_bundled, repair_hint

__all__ = ["ArmSpec", "CapsuleSpec", "RobotSpec", "Robot", "load_robot", "load_spec", "known_robots", "check_angles"]


# --------------------------------------------------------------------------- spec
@dataclass(frozen=True)
class ArmSpec:
    """Role links of one arm.

    Attributes:
        side: ``"left"`` or ``"right"``.
        shoulder, elbow, wrist: link names whose origins are the shoulder,
            elbow and wrist / end-effector points.
        wrist_alignment_rpy: ``(r, p, y)`` [rad] of ``R_wristlink_handframe``: the
            human wrist frame (x along the hand, y little finger -> index,
            z = x cross y) expressed in the wrist link frame.
        fingers: finger name -> ``(base_link, tip_link)`` (empty without hands).
    """

    side: str
    shoulder: str
    elbow: str
    wrist: str
    wrist_alignment_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    fingers: Mapping[str, tuple[str, str]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.side not in SIDES:
            raise RobotDescriptionError(f"arm side must be one of {SIDES}, got {self.side!r}")
        if len(self.wrist_alignment_rpy) != 3 or not all(math.isfinite(v) for v in self.wrist_alignment_rpy):
            raise RobotDescriptionError(f"{self.side} arm: wrist_alignment_rpy must be 3 finite numbers")
        unknown = sorted(set(self.fingers) - set(FINGERS))
        if unknown:
            raise RobotDescriptionError(f"{self.side} arm: unknown fingers {unknown}; expected names from {FINGERS}")

    @property
    def wrist_alignment(self) -> torch.Tensor:
        """``(3, 3)`` float64 ``R_wristlink_handframe``."""
        return torch.as_tensor(rpy_to_matrix(self.wrist_alignment_rpy))

    @property
    def links(self) -> tuple[str, ...]:
        """Every link the arm names (roles and finger frames)."""
        return (self.shoulder, self.elbow, self.wrist) + tuple(x for pair in self.fingers.values() for x in pair)


@dataclass(frozen=True)
class CapsuleSpec:
    """A collision capsule: a segment in a link frame swept by a sphere.

    Attributes:
        name: unique name (``"l_forearm"``).
        link: the link it is attached to.
        p0, p1: segment end points in the link frame [m].
        radius: [m], > 0.
    """

    name: str
    link: str
    p0: tuple[float, float, float]
    p1: tuple[float, float, float]
    radius: float

    def __post_init__(self) -> None:
        if not (isinstance(self.radius, (int, float)) and self.radius > 0 and math.isfinite(self.radius)):
            raise RobotDescriptionError(f"capsule {self.name!r}: radius must be > 0, got {self.radius!r}")
        for key in ("p0", "p1"):
            v = getattr(self, key)
            if len(v) != 3 or not all(math.isfinite(x) for x in v):
                raise RobotDescriptionError(f"capsule {self.name!r}: {key} must be 3 finite numbers, got {v!r}")


@dataclass(frozen=True)
class RobotSpec:
    """The contents of a robot spec file.

    Attributes:
        name: robot name.
        path: the spec file.
        urdf: the URDF file (resolved).
        base_link: the root link (the robot frame: origin between the shoulders).
        actuated_joints: order of :attr:`Robot.joint_names`.
        arms: ``{"left": ArmSpec, "right": ArmSpec}``.
        capsules: the collision capsules.
        collision_pairs: pairs of capsule names that are checked.
        pair_margins: d_min [m] of each pair, same order.
        description: free text.
        neutral_pose: optional ``((joint, angle [rad]), ...)``: a collision-free
            rest pose (YuMi's all-zero pose crosses the forearms).
        velocity_limits: optional ``((joint, max speed [rad/s]), ...)``, the published
            joint velocity limits (spec ``"velocity_limits"``; source in ``"velocity_limits_source"``).
        velocity_limits_source: where the velocity limits come from (free text).
    """

    name: str
    path: Path
    urdf: Path
    base_link: str
    actuated_joints: tuple[str, ...]
    arms: Mapping[str, ArmSpec]
    capsules: tuple[CapsuleSpec, ...]
    collision_pairs: tuple[tuple[str, str], ...]
    pair_margins: tuple[float, ...]
    description: str = ""
    neutral_pose: tuple[tuple[str, float], ...] | None = None
    velocity_limits: tuple[tuple[str, float], ...] | None = None
    velocity_limits_source: str = ""

    def __post_init__(self) -> None:
        if set(self.arms) != set(SIDES):
            raise RobotDescriptionError(f"{self.path}: 'arms' must have exactly {SIDES}, got {sorted(self.arms)}")
        if len(self.pair_margins) != len(self.collision_pairs):
            raise RobotDescriptionError(f"{self.path}: one margin per collision pair expected")
        if any(not (m >= 0 and math.isfinite(m)) for m in self.pair_margins):
            raise RobotDescriptionError(f"{self.path}: collision margins must be finite and >= 0")

    def capsule(self, name: str) -> CapsuleSpec:
        for c in self.capsules:
            if c.name == name:
                return c
        raise KeyError(name)


def known_robots() -> list[str]:
    """Names of the bundled robots (spec files in ``assets/robots``)."""
    return sorted(p.stem for p in ROBOTS_DIR.glob("*.json"))


def _resolve(name_or_path: str | Path) -> Path:
    p = Path(name_or_path)
    # A bundled name wins over a same-named file or folder in the working directory.
    if isinstance(name_or_path, str) and name_or_path in known_robots():
        return ROBOTS_DIR / f"{name_or_path}.json"
    if p.suffix == ".json" or p.exists() or len(p.parts) > 1:
        if not p.is_file():
            raise RobotDescriptionError(f"robot spec file not found: {p}")
        return p
    spec = ROBOTS_DIR / f"{name_or_path}.json"
    if not spec.is_file() and name_or_path in BUNDLED_ROBOTS:
        raise RobotDescriptionError(f"robot spec file not found: {spec}; {repair_hint(spec)}")
    if not spec.is_file():
        raise UnknownRobotError(f"unknown robot {str(name_or_path)!r}; known robots: {', '.join(known_robots())} (or give a path to a spec .json)")
    return spec


def _need(d: dict, key: str, where: str, path: Path):
    if not isinstance(d, dict) or key not in d:
        raise RobotDescriptionError(f"{path}: {where} is missing the field {key!r}")
    return d[key]


def _vec3(v, what: str, path: Path) -> tuple[float, float, float]:
    try:
        out = tuple(float(x) for x in v)
    except (TypeError, ValueError):
        raise RobotDescriptionError(f"{path}: {what} must be 3 numbers, got {v!r}") from None
    if len(out) != 3:
        raise RobotDescriptionError(f"{path}: {what} must be 3 numbers, got {v!r}")
    return out  # type: ignore[return-value]


def load_spec(name_or_path: str | Path) -> RobotSpec:
    """Read a robot spec file (no URDF checks; :func:`load_robot` does those).

    Args:
        name_or_path: a bundled robot name or a path to a spec ``.json``.

    Raises:
        UnknownRobotError: a name that is not bundled.
        RobotDescriptionError: a missing or malformed file or field.
    """
    path = _resolve(name_or_path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        hint = f"; {repair_hint(path)}" if is_bundled(path) else ""
        raise RobotDescriptionError(f"{path}: not a text file (a robot spec is UTF-8 JSON){hint}") from None
    except (json.JSONDecodeError, RecursionError) as e:
        hint = f"; {repair_hint(path)}" if is_bundled(path) else ""
        raise RobotDescriptionError(f"{path}: malformed JSON ({e}){hint}") from None
    if not isinstance(data, dict):
        raise RobotDescriptionError(f"{path}: the spec must be a JSON object")
    urdf = path.parent / str(_need(data, "urdf", "the spec", path))
    actuated = _need(data, "actuated_joints", "the spec", path)
    if not isinstance(actuated, list) or not all(isinstance(a, str) for a in actuated) or not actuated:
        raise RobotDescriptionError(f"{path}: 'actuated_joints' must be a non-empty list of joint names")
    arms = {}
    arms_data = _need(data, "arms", "the spec", path)
    for side in SIDES:
        a = _need(arms_data, side, "'arms'", path)
        fingers = {}
        for fname, pair in (a.get("fingers") or {}).items():
            if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(x, str) for x in pair)):
                raise RobotDescriptionError(f"{path}: arms.{side}.fingers.{fname} must be [base_link, tip_link]")
            fingers[fname] = (pair[0], pair[1])
        try:
            arms[side] = ArmSpec(
                side,
                str(_need(a, "shoulder", f"arms.{side}", path)),
                str(_need(a, "elbow", f"arms.{side}", path)),
                str(_need(a, "wrist", f"arms.{side}", path)),
                _vec3(a.get("wrist_alignment_rpy", [0, 0, 0]), f"arms.{side}.wrist_alignment_rpy", path),
                fingers,
            )
        except RobotDescriptionError as e:
            raise RobotDescriptionError(f"{path}: {e}") from None
    capsules = []
    for i, c in enumerate(data.get("capsules", [])):
        where = f"capsules[{i}]"
        try:
            capsules.append(
                CapsuleSpec(
                    str(_need(c, "name", where, path)),
                    str(_need(c, "link", where, path)),
                    _vec3(_need(c, "p0", where, path), f"{where}.p0", path),
                    _vec3(_need(c, "p1", where, path), f"{where}.p1", path),
                    float(_need(c, "radius", where, path)),
                )
            )
        except (TypeError, ValueError):
            raise RobotDescriptionError(f"{path}: {where}.radius must be a number") from None
        except RobotDescriptionError as e:
            raise RobotDescriptionError(f"{path}: {e}" if str(path) not in str(e) else str(e)) from None
    names = [c.name for c in capsules]
    if len(set(names)) != len(names):
        raise RobotDescriptionError(f"{path}: duplicate capsule names {sorted({n for n in names if names.count(n) > 1})}")
    pairs = []
    for i, pr in enumerate(data.get("collision_pairs", [])):
        if not (isinstance(pr, list) and len(pr) == 2):
            raise RobotDescriptionError(f"{path}: collision_pairs[{i}] must be [capsule_a, capsule_b]")
        for n in pr:
            if n not in names:
                raise RobotDescriptionError(f"{path}: collision_pairs[{i}] names capsule {n!r}, which does not exist")
        if pr[0] == pr[1]:
            raise RobotDescriptionError(f"{path}: collision_pairs[{i}] pairs capsule {pr[0]!r} with itself")
        pairs.append((pr[0], pr[1]))
    margin_data = data.get("collision_margin", {"default": 0.1})
    if isinstance(margin_data, (int, float)) and not isinstance(margin_data, bool):
        margin_data = {"default": margin_data}
    if not isinstance(margin_data, dict) or not all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in margin_data.values()
    ):
        raise RobotDescriptionError(f"{path}: collision_margin must be a number or map 'default' and 'a/b' pairs to numbers [m]")
    default = float(margin_data.get("default", 0.1))
    overrides = {}
    for key, value in margin_data.items():
        if key == "default":
            continue
        a, _, b = key.partition("/")
        if (a, b) not in pairs and (b, a) not in pairs:
            raise RobotDescriptionError(f"{path}: collision_margin names the pair {key!r}, which is not in collision_pairs")
        overrides[frozenset((a, b))] = float(value)
    margins = tuple(overrides.get(frozenset(p), default) for p in pairs)
    neutral = data.get("neutral_pose")
    if neutral is not None:
        if not isinstance(neutral, dict) or not all(isinstance(v, (int, float)) for v in neutral.values()):
            raise RobotDescriptionError(f"{path}: 'neutral_pose' must map joint names to angles [rad]")
        unknown = sorted(set(neutral) - set(actuated))
        if unknown:
            raise RobotDescriptionError(f"{path}: neutral_pose names joints {unknown} that are not in actuated_joints")
        neutral = tuple((str(k), float(v)) for k, v in neutral.items())
    velocity = data.get("velocity_limits")
    if velocity is not None:
        if not isinstance(velocity, dict) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0 and math.isfinite(v) for v in velocity.values()
        ):
            raise RobotDescriptionError(f"{path}: 'velocity_limits' must map joint names to speeds > 0 [rad/s]")
        velocity = tuple((str(k), float(v)) for k, v in velocity.items())
    return RobotSpec(
        name=str(data.get("name", path.stem)),
        path=path,
        urdf=urdf,
        base_link=str(data.get("base_link", "world")),
        actuated_joints=tuple(actuated),
        arms=arms,
        capsules=tuple(capsules),
        collision_pairs=tuple(pairs),
        pair_margins=margins,
        description=str(data.get("description", "")),
        neutral_pose=neutral,
        velocity_limits=velocity,
        velocity_limits_source=str(data.get("velocity_limits_source", "")),
    )


# --------------------------------------------------------------------------- robot
def check_angles(q, n_joints: int, robot: str = "robot", joint_names: Sequence[str] | None = None) -> np.ndarray:
    """Joint angles as a float64 ``(T, n)`` array, or one clear error.

    Args:
        q: ``(n,)`` or ``(T, n)`` angles [rad] (array, list or tensor).
        n_joints: ``n``; robot: its name and joint_names its joints, for the message.

    Raises:
        NloLabError: the wrong shape, or a NaN or infinite angle (the message
            names the frame and the joint).
    """
    if isinstance(q, torch.Tensor):
        q = q.detach().cpu().numpy()
    try:
        a = np.asarray(q, dtype=np.float64)
    except (TypeError, ValueError):
        raise NloLabError(f"angles for robot {robot!r} must be numbers, got {type(q).__name__}") from None
    if a.ndim == 1:
        a = a[None]
    if a.ndim != 2 or a.shape[1] != n_joints:
        raise NloLabError(f"angles for robot {robot!r} must be ({n_joints},) or (T, {n_joints}), got shape {np.shape(q)}")
    if not np.isfinite(a).all():
        frame, joint = np.argwhere(~np.isfinite(a))[0]
        name = repr(joint_names[joint]) if joint_names is not None else str(joint)
        raise NloLabError(f"angles for robot {robot!r} are not finite (frame {frame}, joint {name})")
    return a


class Robot:
    """A robot: joint order and limits, batched FK, capsule distances and structure graph.

    Build with :func:`load_robot`. Tensors live on :attr:`device` in :attr:`dtype`
    (float32 on CPU by default); :meth:`to` returns a moved copy. FK itself
    follows the dtype and device of the angles it is given.
    """

    def __init__(self, spec: RobotSpec, model: URDFModel, dtype: torch.dtype = torch.float32, device=None):
        self.spec = spec
        self.model = model
        self.name = spec.name
        try:
            self.tree = KinematicTree(model, spec.actuated_joints)
        except RobotDescriptionError as e:
            raise RobotDescriptionError(f"{spec.path}: {e}") from None
        self.joint_names: list[str] = list(spec.actuated_joints)
        self.n_joints = len(self.joint_names)
        self.link_names: list[str] = list(model.links)
        self._check_spec()
        self._lower = np.array([model.joint(n).lower for n in self.joint_names])
        self._upper = np.array([model.joint(n).upper for n in self.joint_names])
        speeds = dict(spec.velocity_limits or ())
        unknown = sorted(set(speeds) - set(self.joint_names))
        if unknown:  # checked after _check_spec, whose message about a misnamed joint comes first
            raise RobotDescriptionError(f"{spec.path}: velocity_limits names joints {unknown} that are not in actuated_joints")
        self._velocity = np.array([speeds.get(n, np.inf) for n in self.joint_names])
        caps = spec.capsules
        cap_index = {c.name: i for i, c in enumerate(caps)}
        self._cap_link = [self.tree.link_index[c.link] for c in caps]
        self._cap_pts = np.array([[c.p0, c.p1] for c in caps]).reshape(len(caps), 2, 3)  # (C, 2, 3) [m]
        self._cap_r = np.array([c.radius for c in caps])
        self._pair_idx = np.array([[cap_index[a], cap_index[b]] for a, b in spec.collision_pairs], dtype=np.int64).reshape(-1, 2)
        self._graph64 = self._build_graph()
        # reference pose: q = 0 clamped into the limits
        self._q_ref = np.clip(np.zeros(self.n_joints), self._lower, self._upper)
        self._q_neutral = self._q_ref.copy()
        for joint, angle in spec.neutral_pose or ():
            i = self.joint_names.index(joint)
            if not self._lower[i] <= angle <= self._upper[i]:
                raise RobotDescriptionError(f"{spec.path}: neutral_pose {joint} = {angle} is outside [{self._lower[i]}, {self._upper[i]}]")
            self._q_neutral[i] = angle
        with torch.no_grad():
            T = self.tree.forward(torch.as_tensor(self._q_ref, dtype=torch.float64))  # (L, 4, 4)
        self._ref_poses = {n: T[i] for i, n in enumerate(self.link_names)}
        self._set_tensors(dtype, torch.device(device) if device is not None else torch.device("cpu"))

    # ----------------------------------------------------------------- setup
    def _check_spec(self) -> None:
        spec, links = self.spec, set(self.model.links)
        where = f"{spec.path}"
        if spec.base_link != self.model.root:
            raise RobotDescriptionError(f"{where}: base_link {spec.base_link!r} is not the URDF root link {self.model.root!r} ({spec.urdf})")
        for side, arm in spec.arms.items():
            for role, link in (("shoulder", arm.shoulder), ("elbow", arm.elbow), ("wrist", arm.wrist)):
                if link not in links:
                    raise RobotDescriptionError(f"{where}: arms.{side}.{role} names link {link!r}, which does not exist in {spec.urdf}")
            for finger, pair in arm.fingers.items():
                for link in pair:
                    if link not in links:
                        raise RobotDescriptionError(f"{where}: arms.{side}.fingers.{finger} names link {link!r}, which does not exist in {spec.urdf}")
        for c in spec.capsules:
            if c.link not in links:
                raise RobotDescriptionError(f"{where}: capsule {c.name!r} names link {c.link!r}, which does not exist in {spec.urdf}")
        for a, b in spec.collision_pairs:
            la, lb = spec.capsule(a).link, spec.capsule(b).link
            pa, pb = self.model.parent_joint(la), self.model.parent_joint(lb)
            if la == lb or (pa is not None and pa.parent == lb) or (pb is not None and pb.parent == la):
                raise RobotDescriptionError(f"{where}: collision pair ({a!r}, {b!r}) joins adjacent links {la!r} and {lb!r}")

    def _build_graph(self) -> Graph:
        """Structure graph in float64 (see the module docstring)."""
        tree, model = self.tree, self.model
        joints = {j.name: j for j in model.joints}
        act = {n: i for i, n in enumerate(self.joint_names)}
        moving_idx = {n: k for k, n in enumerate(tree.moving_names)}
        pre = tree.moving_pre  # (M, 4, 4) T_parentbody_joint

        def actuated_parent(name: str) -> tuple[int, np.ndarray]:
            """Nearest actuated ancestor (node index or -1) and T_ancestorframe_jointframe."""
            T = pre[moving_idx[name]]
            k = tree.moving_parent[moving_idx[name]]
            while k >= 0:
                pname = tree.moving_names[k]
                if pname in act:
                    return act[pname], T
                T = pre[k] @ T  # a mimic joint in between: at its zero angle
                k = tree.moving_parent[k]
            return -1, T

        edges, attrs, roots = [], [], []
        for name in self.joint_names:
            p, T = actuated_parent(name)
            if p < 0:
                roots.append((act[name], T))
            else:
                edges.append((p, act[name]))
                attrs.append(np.concatenate([T[:3, 3], matrix_to_rpy(T[:3, :3])]))
        for i, Ti in roots:  # arm roots joined both ways (see the module docstring)
            for j, Tj in roots:
                if i != j:
                    Tij = np.linalg.inv(Ti) @ Tj
                    edges.append((i, j))
                    attrs.append(np.concatenate([Tij[:3, 3], matrix_to_rpy(Tij[:3, :3])]))
        hand_joints = self._hand_joints(joints)
        node_type = [NODE_HAND if n in hand_joints else NODE_ARM for n in self.joint_names]
        return Graph(
            tuple(self.joint_names),
            torch.tensor(edges, dtype=torch.long).reshape(-1, 2).T.contiguous(),
            torch.as_tensor(np.array(attrs).reshape(-1, 6)),
            torch.tensor(node_type, dtype=torch.long),
        )

    def _hand_joints(self, joints) -> set[str]:
        """Actuated joints below a wrist link (finger joints) are hand nodes."""
        wrists = {arm.wrist for arm in self.spec.arms.values()} if self.has_fingers else set()
        out = set()
        for name in self.joint_names:
            link = joints[name].parent
            while link is not None:
                if link in wrists:
                    out.add(name)
                    break
                pj = self.model.parent_joint(link)
                link = None if pj is None else pj.parent
        return out

    def _set_tensors(self, dtype: torch.dtype, device: torch.device) -> None:
        self.dtype, self.device = dtype, device
        f = lambda a: torch.as_tensor(a, dtype=dtype, device=device)  # noqa: E731
        self.lower_limits = f(self._lower)  # (n,) [rad]
        self.upper_limits = f(self._upper)  # (n,) [rad]
        self.velocity_limits = f(self._velocity)  # (n,) [rad/s], inf where the spec gives none
        self.collision_margins = f(np.array(self.spec.pair_margins))  # (P,) [m]
        self.graph = self._graph64.to(device=device, dtype=dtype)
        self._cap_link_t = torch.as_tensor(self._cap_link, dtype=torch.long, device=device)
        self._pair_flat_t = torch.as_tensor(self._pair_idx.reshape(-1), dtype=torch.long, device=device)  # (2P,) capsule a, capsule b of each pair

    # ----------------------------------------------------------------- API
    @property
    def has_fingers(self) -> bool:
        """True when the spec names finger frames (YuMi with hands)."""
        return any(arm.fingers for arm in self.spec.arms.values())

    def arm(self, side: str) -> ArmSpec:
        """Role links of ``side`` (``"left"`` / ``"right"``)."""
        if side not in self.spec.arms:
            raise RobotDescriptionError(f"{self.name}: unknown side {side!r}; expected one of {SIDES}")
        return self.spec.arms[side]

    def wrist_alignment(self, side: str) -> torch.Tensor:
        """``(3, 3)`` ``R_wristlink_handframe`` of ``side`` in the robot's dtype and device."""
        return self.arm(side).wrist_alignment.to(dtype=self.dtype, device=self.device)

    @property
    def root_link(self) -> str:
        """The URDF's root link: the robot frame (origin between the shoulders)."""
        return self.model.root

    def point_map(self, links: Sequence[str], vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fixed points and directions on links, prepared for :meth:`KinematicTree.map_points`.

        Args:
            links: ``k`` link names.
            vectors: ``(k, 4)`` homogeneous vectors in those link frames: points
                ``(x, y, z, 1)`` [m] and directions ``(x, y, z, 0)``.

        Returns:
            ``body (k,)`` indices into :meth:`KinematicTree.body_poses` and the
            ``(k, 4)`` vectors expressed in those body frames; then
            ``robot.tree.map_points(q, body, vectors)`` gives them in the world.
        """
        unknown = sorted(set(links) - set(self.link_names))
        if unknown:
            raise RobotDescriptionError(f"{self.name}: no link named {unknown[0]!r}")
        return self.tree.point_map(list(links), np.asarray(vectors, dtype=np.float64))

    def map_points(self, q: torch.Tensor, body: torch.Tensor, vectors: torch.Tensor) -> torch.Tensor:
        """``q (B, n)`` -> ``(B, k, 3)``: the vectors of :meth:`point_map` in the world [m].

        ``body`` and ``vectors`` are :meth:`point_map`'s results as tensors (long,
        and the dtype of ``q``). Differentiable in ``q``.
        """
        return self.tree.map_points(q, body, vectors)

    @property
    def capsule_radii(self) -> torch.Tensor:
        """``(C,)`` radius of each capsule [m], spec order, in the robot's dtype and device."""
        return torch.as_tensor(self._cap_r, dtype=self.dtype, device=self.device)

    @property
    def pair_capsules(self) -> np.ndarray:
        """``(P, 2)`` int64 capsule indices (spec order) of each collision pair."""
        return self._pair_idx.copy()

    @property
    def pair_radii(self) -> torch.Tensor:
        """``(P,)`` radius of a + radius of b per collision pair [m], in the robot's dtype and device."""
        return self._pair_radii(self.dtype, self.device)

    def check_angles(self, q) -> np.ndarray:
        """:func:`check_angles` for this robot: ``(n,)`` or ``(T, n)`` -> float64 ``(T, n)``."""
        return check_angles(q, self.n_joints, self.name, self.joint_names)

    def link_index(self, link: str) -> int:
        """Index of ``link`` in :meth:`forward_kinematics_tensor`'s link dimension."""
        try:
            return self.tree.link_index[link]
        except KeyError:
            raise RobotDescriptionError(f"{self.name}: no link named {link!r}") from None

    def forward_kinematics_tensor(self, q: torch.Tensor) -> torch.Tensor:
        """World poses of every link as one tensor.

        Args:
            q: ``(..., n)`` actuated angles [rad] in :attr:`joint_names` order.

        Returns:
            ``(..., L, 4, 4)`` ``T_world_link``, links in :attr:`link_names` order.
        """
        return self.tree.forward(q)

    def forward_kinematics(self, q: torch.Tensor) -> dict[str, torch.Tensor]:
        """World poses of every link.

        Args:
            q: ``(B, n)`` (or any ``(..., n)``) actuated angles [rad].

        Returns:
            ``{link: T_world_link (..., 4, 4)}`` for every link of the URDF.
        """
        T = self.tree.forward(q)  # (..., L, 4, 4)
        return dict(zip(self.link_names, T.unbind(-3)))

    def forward_kinematics_links(self, q: torch.Tensor, links: Sequence[str]) -> torch.Tensor:
        """World poses of some links only (cheaper than every link).

        Args:
            q: ``(..., n)`` actuated angles [rad].
            links: link names.

        Returns:
            ``(..., len(links), 4, 4)`` ``T_world_link`` in the order given.
        """
        idx = torch.tensor([self.link_index(n) for n in links], dtype=torch.long, device=q.device)
        return self.tree.forward_links(q, idx)

    def capsule_segments(self, poses: Mapping[str, torch.Tensor] | torch.Tensor) -> torch.Tensor:
        """World end points of every capsule axis.

        Args:
            poses: the dict of :meth:`forward_kinematics` or the tensor of
                :meth:`forward_kinematics_tensor`.

        Returns:
            ``(..., C, 2, 3)`` [m], capsules in spec order.
        """
        if isinstance(poses, torch.Tensor):
            T = poses.index_select(-3, self._cap_link_t.to(poses.device))  # (..., C, 4, 4)
        else:
            T = torch.stack([poses[c.link] for c in self.spec.capsules], -3)
        pts = torch.as_tensor(self._cap_pts, dtype=T.dtype, device=T.device)  # (C, 2, 3)
        R, t = T[..., None, :3, :3], T[..., None, :3, 3]  # (..., C, 1, 3, 3), (..., C, 1, 3)
        return (R @ pts[..., None]).squeeze(-1) + t

    def capsule_distances(self, poses: Mapping[str, torch.Tensor] | torch.Tensor) -> torch.Tensor:
        """Surface distance of each collision pair (< 0: penetration).

        Args:
            poses: the dict of :meth:`forward_kinematics` or the tensor of
                :meth:`forward_kinematics_tensor`.

        Returns:
            ``(..., P)`` [m], pairs in :attr:`RobotSpec.collision_pairs` order.
        """
        seg = self.capsule_segments(poses)  # (..., C, 2, 3)
        P = self._pair_idx.shape[0]
        ends = seg.index_select(-3, self._pair_flat_t.to(seg.device))  # (..., 2P, 2, 3): a, b of every pair
        ends = ends.reshape(*seg.shape[:-3], P, 4, 3)  # rows a0, a1, b0, b1
        return segment_distance_ends(ends) - self._pair_radii(seg.dtype, seg.device)

    def _pair_radii(self, dtype: torch.dtype, device) -> torch.Tensor:
        """``(P,)`` radius of a + radius of b per collision pair [m]."""
        return torch.as_tensor(self._cap_r[self._pair_idx].sum(-1), dtype=dtype, device=device)

    @property
    def reference_q(self) -> torch.Tensor:
        """``(n,)`` the reference pose: zero clamped into the limits [rad]."""
        return torch.as_tensor(self._q_ref, dtype=self.dtype, device=self.device)

    @property
    def neutral_q(self) -> torch.Tensor:
        """``(n,)`` a collision-free rest pose [rad]: the spec's ``neutral_pose``
        (unlisted joints at the reference pose), else :attr:`reference_q`."""
        return torch.as_tensor(self._q_neutral, dtype=self.dtype, device=self.device)

    def zero_pose_lengths(self, side: str) -> tuple[float, float]:
        """``(upper, fore)`` = shoulder->elbow, elbow->wrist distances [m] at the reference pose."""
        arm = self.arm(side)
        P = {k: self._ref_poses[k][:3, 3] for k in (arm.shoulder, arm.elbow, arm.wrist)}
        return float((P[arm.elbow] - P[arm.shoulder]).norm()), float((P[arm.wrist] - P[arm.elbow]).norm())

    def shoulder_position(self, side: str) -> torch.Tensor:
        """``(3,)`` shoulder link position [m] at the reference pose."""
        return self._ref_poses[self.arm(side).shoulder][:3, 3].to(dtype=self.dtype, device=self.device)

    def to(self, device=None, dtype: torch.dtype | None = None) -> "Robot":
        """A copy whose tensors are on ``device`` in ``dtype`` (either may be ``None`` = keep)."""
        out = copy.copy(self)
        out._set_tensors(dtype or self.dtype, torch.device(device) if device is not None else self.device)
        return out

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, joints={self.n_joints}, links={len(self.link_names)}, dtype={self.dtype}, device={self.device})"


def load_robot(name_or_path: str | Path) -> Robot:
    """Load a bundled robot (``"yumi"``, ``"nao"``, ``"pepper"``) or a spec file.

    Args:
        name_or_path: a bundled name, or a path to a spec ``.json`` whose
            ``urdf`` field is relative to the spec file.

    Returns:
        The :class:`Robot` (float32, CPU; use :meth:`Robot.to`).

    Raises:
        UnknownRobotError: an unknown name (the message lists the known robots).
        RobotDescriptionError: a missing or malformed spec or URDF, or a spec
            naming a link or joint that the URDF does not have.
    """
    spec = load_spec(name_or_path)
    try:
        model = parse_urdf(spec.urdf)
        return Robot(spec, model)
    except RobotDescriptionError as exc:
        if is_bundled(spec.urdf):  # a damaged install, not the user's file
            raise RobotDescriptionError(f"{exc}; {repair_hint(spec.urdf)}") from None
        raise

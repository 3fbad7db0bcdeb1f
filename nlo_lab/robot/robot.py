"""A robot: a URDF plus its spec, with FK, capsule distances and the structure graph.

``load_robot("nao")`` reads the spec (:mod:`nlo_lab.robot.spec`) and the URDF it
names (:mod:`nlo_lab.robot.urdf`), builds the kinematic tree
(:mod:`nlo_lab.robot.kinematics`) and the structure graph
(:mod:`nlo_lab.robot.structure_graph`), and checks that the spec's links and
joints exist in the URDF.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import torch

from nlo_lab.errors import RobotDescriptionError, SettingsError, SettingsTypeError
from nlo_lab.human.demonstration import SIDES
from nlo_lab.paths import is_bundled, repair_hint
from nlo_lab.robot.collision import segment_distance_ends
from nlo_lab.robot.fixed_joints import fixed_model, framed_model
from nlo_lab.robot.kinematics import KinematicTree
from nlo_lab.robot.spec import ArmSpec, RobotSpec, load_spec
from nlo_lab.robot.structure_graph import structure_graph
from nlo_lab.robot.urdf import MOVING_TYPES, URDFModel, parse_urdf

__all__ = ["Robot", "load_robot", "as_robot", "check_angles", "closest"]


def closest(name: str, names, count: int = 3) -> str:
    """``"; closest: a, b, c"``: the names most like ``name`` (a misspelt link or joint), or ``""``."""
    import difflib

    found = difflib.get_close_matches(name, sorted(names), n=count, cutoff=0.4)
    return f"; closest: {', '.join(found)}" if found else ""


def _check_actuated(spec: RobotSpec, model: URDFModel) -> None:
    """Each actuated joint exists (else the closest names), turns, and has limits."""
    joints = {j.name: j for j in model.joints}
    for name in spec.actuated_joints:
        j = joints.get(name)
        if j is None:
            raise RobotDescriptionError(f"{spec.path}: actuated joint {name!r} does not exist in {spec.urdf}{closest(name, joints)}")
        if j.type not in MOVING_TYPES:
            raise RobotDescriptionError(f"{spec.path}: actuated joint {name!r} is a {j.type} joint; nlo_lab actuates "
                                        f"revolute and continuous joints (fix it in fixed_joints)")
        if not j.has_limit:
            raise RobotDescriptionError(f"{spec.path}: actuated joint {name!r} has no <limit> in {spec.urdf}: "
                                        "give it lower and upper, or fix it in fixed_joints")


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
        raise SettingsTypeError(f"angles for robot {robot!r} must be numbers, got {type(q).__name__}") from None
    if a.ndim == 1:
        a = a[None]
    if a.ndim != 2 or a.shape[1] != n_joints:
        raise SettingsError(f"angles for robot {robot!r} must be ({n_joints},) or (T, {n_joints}), got shape {np.shape(q)}")
    if not np.isfinite(a).all():
        frame, joint = np.argwhere(~np.isfinite(a))[0]
        name = repr(joint_names[joint]) if joint_names is not None else str(joint)
        raise SettingsError(f"angles for robot {robot!r} are not finite (frame {frame}, joint {name})")
    return a


class Robot:
    """A robot: joint order and limits, batched FK, capsule distances and structure graph.

    Build with :func:`load_robot`. Tensors live on :attr:`device` in :attr:`dtype`
    (float32 on CPU by default); :meth:`to` returns a moved copy. FK itself
    follows the dtype and device of the angles it is given.
    """

    def __init__(self, spec: RobotSpec, model: URDFModel, dtype: torch.dtype = torch.float32, device=None):
        self.spec = spec
        self.name = spec.name
        _check_actuated(spec, model)
        fixed = dict(spec.fixed_joints) if spec.fixed_joints is not None else None
        model = framed_model(fixed_model(model, spec.actuated_joints, fixed, spec.path), spec.base_link, spec.robot_frame, spec.path)
        self.model = model  # moving joints the spec does not actuate are fixed; the root is the robot frame
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
        self._graph64 = structure_graph(spec, model, self.tree)
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
        for side, arm in spec.arms.items():
            for role, link in (("shoulder", arm.shoulder), ("elbow", arm.elbow), ("wrist", arm.wrist)):
                if link not in links:
                    raise RobotDescriptionError(f"{where}: arms.{side}.{role} names link {link!r}, which does not exist in {spec.urdf}{closest(link, links)}")
            for finger, pair in arm.fingers.items():
                for link in pair:
                    if link not in links:
                        raise RobotDescriptionError(
                            f"{where}: arms.{side}.fingers.{finger} names link {link!r}, which does not exist in {spec.urdf}{closest(link, links)}")
        for c in spec.capsules:
            if c.link not in links:
                raise RobotDescriptionError(f"{where}: capsule {c.name!r} names link {c.link!r}, which does not exist in {spec.urdf}{closest(c.link, links)}")
        for pair in spec.shape_contacts:
            for link in pair:
                if link not in links:
                    raise RobotDescriptionError(f"{where}: shape_contacts names link {link!r}, which does not exist in {spec.urdf}{closest(link, links)}")
        for a, b in spec.collision_pairs:
            la, lb = spec.capsule(a).link, spec.capsule(b).link
            pa, pb = self.model.parent_joint(la), self.model.parent_joint(lb)
            if la == lb or (pa is not None and pa.parent == lb) or (pb is not None and pb.parent == la):
                raise RobotDescriptionError(f"{where}: collision pair ({a!r}, {b!r}) joins adjacent links {la!r} and {lb!r}")

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

    def finger_joints(self, side: str, finger: str) -> list[int]:
        """Indices into :attr:`joint_names` of the actuated joints that move ``finger``'s tip link of ``side`` and no
        other finger's (a mimic joint counts as the joint it follows): what the hand stage's search of that finger
        sets. Empty when the arm has no such finger, or every joint above its tip moves another finger too."""
        arm = self.arm(side)

        def above(link: str) -> set[int]:  # the actuated joints between the wrist link and ``link``
            out: set[int] = set()
            while link != arm.wrist:
                joint = self.model.parent_joint(link)
                if joint is None:  # not below the wrist: no hand joint moves it
                    return set()
                name = joint.mimic[0] if joint.mimic else joint.name
                if joint.moving and name in self.joint_names:
                    out.add(self.joint_names.index(name))
                link = joint.parent
            return out

        if finger not in arm.fingers:
            return []
        own = above(arm.fingers[finger][1])
        for other, (_, tip) in arm.fingers.items():
            if other != finger:
                own -= above(tip)
        return sorted(own)

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

    def map_points(self, q: torch.Tensor, body: torch.Tensor, vectors: torch.Tensor, analytic_gradient: bool = False) -> torch.Tensor:
        """``q (B, n)`` -> ``(B, k, 3)``: the vectors of :meth:`point_map` in the world [m].

        ``body`` and ``vectors`` are :meth:`point_map`'s results as tensors (long,
        and the dtype of ``q``). Differentiable in ``q``: by autograd through the FK
        (the default), or with ``analytic_gradient=True`` in closed form (faster, same
        numbers; :meth:`KinematicTree.map_points`).
        """
        return self.tree.map_points(q, body, vectors, analytic_gradient)

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
        return dict(zip(self.link_names, T.unbind(-3), strict=True))

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
        if not self.spec.capsules:  # a spec without capsules checks no pair
            some = poses if isinstance(poses, torch.Tensor) else next(iter(poses.values()))
            lead = some.shape[:-3] if isinstance(poses, torch.Tensor) else some.shape[:-2]
            return some.new_zeros((*lead, 0, 2, 3))
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

    def to(self, device=None, dtype: torch.dtype | None = None) -> Robot:
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


def as_robot(robot: Robot | str | Path) -> Robot:
    """``robot`` itself, or the robot :func:`load_robot` loads by that name or spec path."""
    return robot if isinstance(robot, Robot) else load_robot(robot)

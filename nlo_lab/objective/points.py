"""The robot side of the objective: every point and direction the terms read, mapped by one FK.

Each term compares quantities of the robot with the same quantities of the
demonstration. On the robot they are fixed vectors in link frames:

* ``shoulder``: a point fixed to the body (the root link), where the shoulder link
  sits at the reference pose (``robot.shoulder_position``), which is also where the
  metric places the human shoulder. (YuMi's shoulder link sits off joint 1's axis and
  swings by up to 6 cm; measuring from it, the optimum put the wrist that far from
  where the metric scores it.)
* ``elbow``, ``wrist``: the origins of the spec's elbow and wrist links.
* ``wrist_axes``: the three columns of the spec's ``wrist_alignment`` as directions
  in the wrist link (robot wrist link -> human wrist convention); mapped to the
  world they are the columns of ``R_wrist R_align``.
* ``finger_base``, ``finger_tip``: origins of the links of the fingers the robot has.
* ``capsule_ends``: the two axis end points of every capsule of every collision pair.

:class:`PointPlan` lists them once (``Robot.point_map``); a call maps all of them
with one ``Robot.map_points`` and splits the result into :class:`RobotPoints`.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import numpy as np
import torch

from nlo_lab.human.demonstration import FINGERS, SIDES

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["RobotPoints", "PointPlan", "point_plan", "robot_points"]


@dataclass(frozen=True)
class RobotPoints:
    """The robot quantities the terms compare, for B configurations, in the robot frame.

    Attributes:
        shoulder, elbow, wrist: ``(B, 2, 3)`` per side (left, right) [m].
        wrist_rotation: ``(B, 2, 3, 3)`` ``R_wrist R_align`` (human wrist convention).
        finger_base, finger_tip: ``(B, K, 3)`` the robot's K fingers [m] (K = 0 without hands).
        capsule_ends: ``(B, P, 4, 3)`` axis end points a0, a1, b0, b1 of each collision pair [m].
    """

    shoulder: torch.Tensor
    elbow: torch.Tensor
    wrist: torch.Tensor
    wrist_rotation: torch.Tensor
    finger_base: torch.Tensor
    finger_tip: torch.Tensor
    capsule_ends: torch.Tensor


class PointPlan:
    """Every point and direction of :class:`RobotPoints` as a fixed vector in a link frame.

    Args:
        robot: a loaded :class:`nlo_lab.robot.Robot` (only its public interface is used).
        dtype, device: of the tensors below (the targets').

    Attributes:
        links: ``k`` link names; ``link_vectors``: ``(k, 4)`` homogeneous vectors in them
            (points ``w = 1`` [m], directions ``w = 0``).
        rows: ``{role: slice}`` of each :class:`RobotPoints` field's vectors (capsule ends: the
            capsules' distinct end points, mapped once though thinned copies of a capsule share
            them; ``capsule_end_rows`` and ``pair_points`` pick them per capsule and per pair).
        capsule_end_rows: ``(2C,)`` long, the vectors p0, p1 of each capsule (spec order).
        pair_points: ``(4P,)`` long, the vectors a0, a1, b0, b1 of each collision pair.
        arm_length, fore_length: ``(2,)`` the robot's zero-pose upper + fore arm and forearm [m].
        finger_side, finger_index: ``(K,)`` long, the side and the finger (thumb..pinky) of each robot finger.
        hand_length: ``(2,)`` per side the mean wrist -> finger base (knuckle) distance of the fingers other
            than the thumb, at the reference pose (1 without fingers) [m]: the hand terms' unit.
        thumb_pairs: ``(J, 2)`` long, (thumb, other finger) of the same hand, indices into the K fingers;
            pair_side: ``(J,)`` long, their side.
        pair_radii, margins: ``(P,)`` summed capsule radii and d_min of each pair [m].
    """

    def __init__(self, robot: Robot, dtype: torch.dtype, device=None):
        self.robot = robot
        arms = [robot.arm(s) for s in SIDES]
        entries: list[tuple[str, tuple[float, ...]]] = []
        self.rows: dict[str, slice] = {}

        def group(role: str, items) -> None:
            start = len(entries)
            entries.extend(items)
            self.rows[role] = slice(start, len(entries))

        origin = (0.0, 0.0, 0.0, 1.0)
        group("shoulder", [(robot.root_link, (*robot.shoulder_position(s).double().tolist(), 1.0)) for s in SIDES])
        group("elbow", [(arm.elbow, origin) for arm in arms])
        group("wrist", [(arm.wrist, origin) for arm in arms])
        align = [np.asarray(arm.wrist_alignment, dtype=np.float64) for arm in arms]
        group("wrist_axes", [(arm.wrist, (*a[:, j], 0.0)) for arm, a in zip(arms, align, strict=True) for j in range(3)])
        fingers = [(s, f, *arm.fingers[name]) for s, arm in enumerate(arms) if robot.has_fingers and arm.fingers
                   for f, name in enumerate(FINGERS) if name in arm.fingers]  # (side, finger, base link, tip link)
        group("finger_base", [(base, origin) for *_, base, _ in fingers])
        group("finger_tip", [(tip, origin) for *_, tip in fingers])
        capsule_ends = [(cap.link, (*map(float, end), 1.0)) for cap in robot.spec.capsules for end in (cap.p0, cap.p1)]
        distinct = list(dict.fromkeys(capsule_ends))  # YuMi: 232 ends, 124 distinct (fewer points to map)
        group("capsule_ends", distinct)

        self.links = [link for link, _ in entries]
        self.link_vectors = np.array([v for _, v in entries], dtype=np.float64).reshape(-1, 4)
        body, vectors = robot.point_map(self.links, self.link_vectors)
        self.body = torch.as_tensor(body, dtype=torch.long, device=device)  # (k,)
        self.vectors = torch.as_tensor(vectors, dtype=dtype, device=device)  # (k, 4) in body frames
        end_rows = self.rows["capsule_ends"].start + np.array([distinct.index(e) for e in capsule_ends], dtype=np.int64)
        self.capsule_end_rows = torch.as_tensor(end_rows, dtype=torch.long, device=device)  # (2C,)
        ends = end_rows.reshape(-1, 2)[robot.pair_capsules]  # (P, 2, 2): a0, a1 / b0, b1
        self.pair_points = torch.as_tensor(ends.reshape(-1), dtype=torch.long, device=device)  # (4P,)
        lengths = [robot.zero_pose_lengths(s) for s in SIDES]
        self.arm_length = torch.tensor([float(u) + float(f) for u, f in lengths], dtype=dtype, device=device)
        self.fore_length = torch.tensor([float(f) for _, f in lengths], dtype=dtype, device=device)
        self.finger_side = torch.tensor([s for s, *_ in fingers], dtype=torch.long, device=device)
        self.finger_index = torch.tensor([f for _, f, *_ in fingers], dtype=torch.long, device=device)
        self._set_hand(fingers, dtype, device)
        self.pair_radii = robot.pair_radii.to(device=device, dtype=dtype)
        self.margins = torch.as_tensor(robot.collision_margins).to(device=device, dtype=dtype)

    def _set_hand(self, fingers, dtype, device) -> None:
        """The hand terms' constants: hand lengths and thumb pairs (see the class attributes)."""
        thumb = FINGERS.index("thumb")
        pairs = [(kt, kf) for kt, (st, ft, *_) in enumerate(fingers) if ft == thumb
                 for kf, (sf, ff, *_) in enumerate(fingers) if sf == st and ff != thumb]
        self.thumb_pairs = torch.tensor(pairs, dtype=torch.long, device=device).reshape(-1, 2)
        self.pair_side = self.finger_side[self.thumb_pairs[:, 1]] if pairs else self.finger_side[:0]
        lengths = [1.0, 1.0]
        if fingers:
            with torch.no_grad():
                p = self.split(self.map(self.robot.reference_q.to(device=device, dtype=dtype)[None]))
            for s in range(2):
                ks = [k for k, (sk, fk, *_) in enumerate(fingers) if sk == s and fk != thumb]
                if ks:
                    lengths[s] = float((p.finger_base[0, ks] - p.wrist[0, s]).norm(dim=-1).mean())
        self.hand_length = torch.tensor(lengths, dtype=dtype, device=device)
        self._pinch_floor: torch.Tensor | None = None

    def pinch_floor(self, samples: int = 16384, seed: int = 0) -> torch.Tensor:
        """``(J,)`` per thumb pair the closest its two tips come over the joint ranges, in hand lengths.

        Found once (then kept) from ``samples`` random configurations within the limits (the tips'
        distance depends on the hand's joints only; about 0.2 s for YuMi); an upper bound of the
        true minimum by the sampling's resolution (a few mm on YuMi's Inspire hands).
        """
        if self._pinch_floor is None:
            gen = torch.Generator().manual_seed(seed)
            lo, hi = (x.to(self.vectors.dtype).cpu() for x in (self.robot.lower_limits, self.robot.upper_limits))
            u = torch.rand(samples, lo.shape[0], generator=gen, dtype=torch.float64).to(lo.dtype)
            q = (lo + (hi - lo) * u).to(self.vectors.device)
            rows = self.rows["finger_tip"]
            pairs = self.thumb_pairs
            closest = []
            with torch.no_grad():
                # the fingertips alone, 2048 samples at a time: split() of every point of 16384 samples held
                # 690 MB of capsule ends (YuMi's 873 pairs), the peak of a long recording's retargeting
                for part in q.split(2048):
                    tip = self.robot.map_points(part, self.body[rows], self.vectors[rows])  # (b, K, 3)
                    d = (tip[:, pairs[:, 1]] - tip[:, pairs[:, 0]]).norm(dim=-1) / self.hand_length[self.pair_side]
                    closest.append(d.min(0).values if pairs.shape[0] else d.new_zeros(0))
            self._pinch_floor = torch.stack(closest).min(0).values
        return self._pinch_floor

    def map(self, q: torch.Tensor, analytic_gradient: bool = False) -> torch.Tensor:
        """``q (B, n)`` -> every vector in the world, ``(B, k, 3)`` (one FK; ``analytic_gradient``:
        its closed-form derivative, see ``Robot.map_points``)."""
        return self.robot.map_points(q, self.body, self.vectors, analytic_gradient)

    def map_poses(self, poses: dict) -> torch.Tensor:
        """The same from given link poses (``robot.forward_kinematics(q)``): ``(B, k, 3)``."""
        vec = torch.as_tensor(self.link_vectors, dtype=self.vectors.dtype, device=self.vectors.device)
        return torch.stack([poses[link][..., :3, :] @ v for link, v in zip(self.links, vec, strict=True)], dim=1)

    def split(self, points: torch.Tensor) -> RobotPoints:
        """Mapped vectors ``(B, k, 3)`` -> :class:`RobotPoints`."""
        B = points.shape[0]
        role = {name: points[:, rows] for name, rows in self.rows.items()}
        return RobotPoints(
            shoulder=role["shoulder"],
            elbow=role["elbow"],
            wrist=role["wrist"],
            wrist_rotation=role["wrist_axes"].view(B, 2, 3, 3).transpose(-1, -2),  # axes become columns
            finger_base=role["finger_base"],
            finger_tip=role["finger_tip"],
            capsule_ends=points.index_select(1, self.pair_points).view(B, -1, 4, 3),
        )

    def __call__(self, q: torch.Tensor) -> RobotPoints:
        """``q (B, n)`` -> :class:`RobotPoints`."""
        return self.split(self.map(q))


_PLANS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # robot -> {(dtype, device): PointPlan}


def point_plan(robot: Robot, dtype: torch.dtype, device=None) -> PointPlan:
    """The :class:`PointPlan` of ``robot`` in ``dtype`` on ``device``, built once (about 8 ms, mostly the
    spec's wrist alignments) and kept as long as the robot object lives."""
    plans = _PLANS.setdefault(robot, {})
    key = (dtype, str(torch.device(device) if device is not None else torch.device("cpu")))
    if key not in plans:
        plans[key] = PointPlan(robot, dtype, device)
    return plans[key]


def robot_points(robot: Robot, poses: dict) -> dict[str, torch.Tensor]:
    """The robot's :class:`RobotPoints` from FK poses (``robot.forward_kinematics(q)``), as a dict.

    Returns:
        ``shoulder`` (the fixed reference point), ``elbow``, ``wrist`` ``(B, 2, 3)``, ``wrist_rotation``
        ``(B, 2, 3, 3)`` (aligned to the human wrist convention), ``finger_base``, ``finger_tip``
        ``(B, K, 3)`` for the robot's K fingers (K = 0 without hands), ``capsule_ends`` ``(B, P, 4, 3)``.
    """
    some = next(iter(poses.values()))
    plan = point_plan(robot, some.dtype, some.device)
    points = plan.split(plan.map_poses(poses))
    return {f.name: getattr(points, f.name) for f in fields(points)}

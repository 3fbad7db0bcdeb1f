"""The retargeting objective ``L(D, K(q))``: the terms of :mod:`nlo_lab.objective.terms`, weighted and summed.

``L = w_ee L_ee + w_ori L_ori + w_elbow L_elbow + w_finger L_finger + w_col L_col``
``  + w_tip L_tip + w_thumb L_thumb + w_pinch L_pinch + w_tip_dir L_tip_dir + w_finger_dir L_finger_dir + w_gap L_gap``
per frame (the paper's Eq. 5-9, then our hand terms; the latent term ``||z||²/σ²`` and the
smoothness term are added where ``z`` and the whole sequence live: optimisation and training).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import torch

from nlo_lab.errors import SettingsError
from nlo_lab.objective.near_pairs import near_pair_distances
from nlo_lab.objective.numpy_backend import PointTerms, point_terms
from nlo_lab.objective.points import RobotPoints, point_plan
from nlo_lab.objective.targets import Targets
from nlo_lab.objective.terms import (
    capsule_distances,
    collision_loss,
    elbow_loss,
    end_effector_loss,
    finger_direction_loss,
    finger_loss,
    fingertip_direction_loss,
    fingertip_loss,
    orientation_loss,
    pinch_loss,
    thumb_gap_loss,
    thumb_loss,
)
from nlo_lab.objective.weights import COLLISION_FORMS, TERMS, LossWeights
from nlo_lab.settings import check_choice

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["Objective", "objective"]


class Objective:
    """The objective for one robot, one set of targets (T frames) and weights: ``q (T, n)`` -> ``(T,)``.

    What does not depend on ``q`` is prepared once: the robot's point plan
    (:func:`~nlo_lab.objective.points.point_plan`, kept per robot) and the targets' masks. A call
    maps every point the terms need with one FK, then evaluates the terms
    (:meth:`terms`: each term's function, as the paper writes it). That is what runs
    unless the caller asks for a faster form (same numbers, tested equal): the terms
    in numpy with a written-out gradient (``fused``, the CPU only,
    :mod:`~nlo_lab.objective.numpy_backend`), exact capsule distances only for the pairs
    that may be near (``cull``, :mod:`~nlo_lab.objective.near_pairs`), and the FK's
    gradient in closed form (``analytic_fk``). The pipeline chooses them by batch size
    (:class:`nlo_lab.inference.FastPaths`).
    The hand terms (``HAND_TERMS``) run as written here (:meth:`hand_terms`); with
    ``fused`` their numpy form (:class:`~nlo_lab.objective.numpy_backend.HandTerms`) runs with the others.

    Args:
        robot: a loaded :class:`nlo_lab.robot.Robot`.
        targets: :class:`~nlo_lab.objective.targets.Targets` (T frames); their dtype and device are used.
        weights: :class:`~nlo_lab.objective.weights.LossWeights` (defaults: the paper's).
        collision_form: ``"hinge"`` or ``"paper"`` (see :func:`~nlo_lab.objective.terms.collision_loss`).
        fused: evaluate the terms in numpy with a written-out gradient (faster for few
            frames; targets on the CPU only).
        cull: in the torch terms, measure only the capsule pairs that may be within their margin.
        analytic_fk: map the points with FK's closed-form gradient (``Robot.map_points``).

    Raises:
        SettingsError: ``fused`` with targets off the CPU.
    """

    def __init__(self, robot: Robot, targets: Targets, weights: LossWeights | None = None, collision_form: str = "hinge",
                 fused: bool = False, cull: bool = False, analytic_fk: bool = False):
        check_choice("collision form", collision_form, COLLISION_FORMS)
        weights = weights or LossWeights()
        t = self.targets = targets
        self.robot, self.n_frames, self.collision_form = robot, len(targets), collision_form
        self.cull, self.analytic_fk = bool(cull), bool(analytic_fk)
        device = t.shoulder.device
        self.plan = point_plan(robot, t.dtype, device)
        self.weights = torch.tensor([getattr(weights, n) for n in TERMS], dtype=t.dtype, device=device)  # (len(TERMS),)
        am = t.arm_mask
        self.ee_mask, self.elbow_mask = am[..., 0] & am[..., 2], am[..., 1] & am[..., 2]  # (T, 2): both points observed
        fingers = (slice(None), self.plan.finger_side, self.plan.finger_index)  # the human fingers the robot has
        self.finger_base, self.finger_tip, self.finger_mask = t.finger_base[fingers], t.finger_tip[fingers], t.finger_mask[fingers]
        if fused and device.type != "cpu":
            raise SettingsError(f"the numpy terms (fused=True) need targets on the CPU, not {device}")
        # hand terms: a fingertip counts where it and its wrist frame are observed; a thumb pair where both tips do
        plan = self.plan
        self.tip_mask = self.finger_mask & t.wrist_mask[:, plan.finger_side]
        pairs = plan.thumb_pairs
        self.pair_mask = self.tip_mask[:, pairs[:, 0]] & self.tip_mask[:, pairs[:, 1]]
        self.pinch_floor = plan.pinch_floor()  # (J,) found once per robot
        self.numpy_terms = PointTerms.build(plan, targets, collision_form, self.tip_mask, self.pair_mask, self.pinch_floor) if fused else None

    def __call__(self, q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``q (T, n)`` -> ``total (T,)`` and the unweighted terms ``(T, len(TERMS))`` in ``TERMS`` order."""
        if q.shape[0] != self.n_frames:
            raise SettingsError(f"q has {q.shape[0]} frames but the targets have {self.n_frames}")
        return self.of_points(self.plan.map(q, self.analytic_fk))  # (T, k, 3): every point the terms need, one FK

    def of_points(self, points: torch.Tensor, numpy_terms: PointTerms | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """``total (T,)`` and the terms ``(T, len(TERMS))`` of the plan's points ``(T, k, 3)``, mapped already
        (``self.plan.map(q)``; the hand stage maps only the hands' points, :class:`~nlo_lab.inference.hand_stage.HandChains`).
        ``numpy_terms``: with ``fused``, another form of the objective's (:meth:`PointTerms.held`)."""
        numpy_terms = numpy_terms if numpy_terms is not None else self.numpy_terms
        if numpy_terms is not None:
            terms = point_terms(points, numpy_terms)  # every term, the hand terms too
        else:
            terms = self.terms(self.plan.split(points))
        return terms @ self.weights, terms

    def hand_terms(self, p: RobotPoints) -> torch.Tensor:
        """The unweighted hand terms ``(T, 6)`` (``HAND_TERMS`` order: tip, thumb, pinch, tip_dir, finger_dir, thumb_gap) of ``p``."""
        t, plan = self.targets, self.plan
        pairs, side = plan.thumb_pairs, plan.pair_side
        return torch.stack([
            fingertip_loss(p.wrist, p.wrist_rotation, p.finger_tip, plan.hand_length, t.wrist, t.wrist_rotation,
                           self.finger_tip, t.hand_length, plan.finger_side, self.tip_mask),
            thumb_loss(p.wrist_rotation, p.finger_tip, plan.hand_length, t.wrist_rotation, self.finger_tip,
                       t.hand_length, pairs, side, self.pair_mask),
            pinch_loss(p.finger_tip, plan.hand_length, self.finger_tip, t.hand_length, pairs, side, self.pinch_floor,
                       self.pair_mask),
            fingertip_direction_loss(p.wrist, p.wrist_rotation, p.finger_tip, plan.hand_length, t.wrist, t.wrist_rotation,
                                     self.finger_tip, t.hand_length, plan.finger_side, self.tip_mask),
            finger_direction_loss(p.wrist_rotation, p.finger_base, p.finger_tip, plan.hand_length, t.wrist_rotation,
                                  self.finger_base, self.finger_tip, t.hand_length, plan.finger_side, self.tip_mask),
            thumb_gap_loss(p.finger_tip, plan.hand_length, self.finger_tip, t.hand_length, pairs, side, self.pinch_floor,
                           self.pair_mask),
        ], dim=1)  # fmt: skip

    def terms(self, p: RobotPoints) -> torch.Tensor:
        """The unweighted terms ``(T, len(TERMS))`` (``TERMS`` order) of the robot quantities ``p``, term by term."""
        t, plan = self.targets, self.plan
        if self.cull:
            distances = near_pair_distances(p.capsule_ends, plan.pair_radii, plan.margins)
        else:
            distances = capsule_distances(p.capsule_ends, plan.pair_radii)
        return torch.stack([
            end_effector_loss(p.shoulder, p.wrist, plan.arm_length, t.shoulder, t.wrist, t.arm_length, self.ee_mask),
            orientation_loss(p.wrist_rotation, t.wrist_rotation, t.wrist_mask),
            elbow_loss(p.elbow, p.wrist, plan.fore_length, t.elbow, t.wrist, t.fore_length, self.elbow_mask),
            finger_loss(p.finger_base, p.finger_tip, self.finger_base, self.finger_tip, self.finger_mask),
            collision_loss(distances, plan.margins, self.collision_form),
            *self.hand_terms(p).unbind(1),
        ], dim=1)  # fmt: skip


def objective(robot: Robot, q: torch.Tensor, targets: Targets, weights: LossWeights | None = None, *,
              poses: dict | None = None, collision_form: str = "hinge",
              fused: bool = False, cull: bool = False, analytic_fk: bool = False) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """The weighted objective ``L(D, K(q))`` per sample (without the latent term).

    Args:
        robot: a loaded :class:`nlo_lab.robot.Robot`.
        q: ``(B, n)`` joint angles [rad].
        targets: :class:`~nlo_lab.objective.targets.Targets` with ``B`` frames.
        weights: :class:`~nlo_lab.objective.weights.LossWeights` (defaults of the paper).
        poses: FK of ``q`` (``robot.forward_kinematics(q)``) if already computed: the terms
            are then evaluated on the points those poses give.
        collision_form: see :func:`~nlo_lab.objective.terms.collision_loss`.
        fused, cull, analytic_fk: faster forms, as :class:`Objective`'s (``cull`` only
            with ``poses``); the default: the term functions.

    Returns:
        ``total (B,)`` and the unweighted terms ``{"ee", "ori", "elbow", "finger", "collision", "tip", "thumb",
        "pinch", "tip_dir", "finger_dir", "thumb_gap"}`` (``TERMS``), each ``(B,)``.
    """
    if len(targets) != q.shape[0]:
        raise SettingsError(f"q has {q.shape[0]} frames but the targets have {len(targets)}")
    if poses is None:
        total, terms = Objective(robot, targets, weights, collision_form, fused, cull, analytic_fk)(q)
    else:
        loss = Objective(robot, targets, weights, collision_form, cull=cull)
        terms = loss.terms(loss.plan.split(loss.plan.map_poses(poses)))
        total = terms @ loss.weights
    return total, dict(zip(TERMS, terms.unbind(1), strict=True))

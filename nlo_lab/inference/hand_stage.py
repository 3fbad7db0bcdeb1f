"""The hand stage: after the latent optimisation, the hands' joints alone, on the same objective.

The decoder maps one latent to the whole robot, so the latent optimisation moves the fingers
only as far as the decoder's hands reach, and 100 steps shared with the arms leave them short
of the objective's best handshape (``benchmarks/hands.py`` measured it: docs/RESULTS.md,
"Handshapes"). The hand joints do not move the wrist, so this stage optimises them alone,
in joint space, on the same weighted objective (collision and smoothness included), the arms
kept where the latent optimisation put them:

``q_hand* = argmin_(q_hand in limits) sum_t L(D_t, K(q_arm,t, q_hand,t)) + w_smooth L_smooth``

Adam from the decoder's hands (warm start), every frame at once, the limits by clamping after
each step (projected gradient), the best point of the whole sequence kept (patience as the
latent optimisation's). Where the arm and wrist are scored (Table I) nothing changes.

It never makes the robot slower: after the descent, each hand joint's step between consecutive
frames is clamped, frame by frame, to the larger of what its velocity limit allows at the recording's
rate and the start's own step there (the retiming then slows no segment more than it would the
start; without this the stage's hands stretched one real clip's retimed duration from 2.9x to 3.5x,
``benchmarks/motion.py``, 2026-11-26).

It never adds a self-collision: a frame where the stage's hands would put two capsules into each
other (surface distance < 0) and the start's did not keeps the start's hands (the collision term
is a penalty the hand terms can outweigh; on Table I's YuMi test clips the stage alone put 2 more
frames into collision before this rule, measured 2026-11-26).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch

from nlo_lab.inference.descent import descend, smoothness_term
from nlo_lab.inference.fast_paths import FastPaths, fast_paths
from nlo_lab.objective import LossWeights, Objective, Targets, near_pair_distances

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["hand_joint_mask", "refine_hands", "penetrating", "within_speed", "HandStageResult"]


def hand_joint_mask(robot: Robot) -> torch.Tensor:
    """``(n,)`` bool: the actuated joints that move a link below a wrist link (the fingers)."""
    mask = torch.zeros(robot.n_joints, dtype=torch.bool)
    for side in ("left", "right"):
        wrist = robot.arm(side).wrist
        for link in robot.model.subtree(wrist):
            joint = robot.model.parent_joint(link)
            if link == wrist or joint is None or not joint.moving:
                continue
            name = joint.mimic[0] if joint.mimic else joint.name
            if name in robot.joint_names:
                mask[robot.joint_names.index(name)] = True
    return mask


@dataclass
class HandStageResult:
    """What :func:`refine_hands` found.

    Attributes:
        q: ``(T, n)`` the angles, hand joints optimised, the others as given.
        loss: ``(T,)`` the objective per frame at ``q`` (without the latent term; the smoothness
            term's share of each frame included when it applies).
        terms: ``(T, len(TERMS))`` unweighted terms at ``q``.
        history: mean loss per evaluation; steps: Adam steps taken; seconds: wall time.
        kept: ``(T,)`` bool, the frames that kept the start's hands (the stage's would collide, the start's not).
    """

    q: torch.Tensor
    loss: torch.Tensor
    terms: torch.Tensor
    history: list[float]
    steps: int
    seconds: float
    kept: torch.Tensor


def refine_hands(robot: Robot, q: torch.Tensor, targets: Targets, weights: LossWeights | None = None, *,
                 iterations: int = 30, patience: int = 5, lr: float = 0.05, collision_form: str = "hinge",
                 anchor: torch.Tensor | None = None, fast: bool | FastPaths = False) -> HandStageResult:
    """Optimise the hand joints of ``q (T, n)`` on the objective of ``targets``, the other joints kept.

    Args:
        robot: the robot; without hand joints ``q`` comes back unchanged (0 steps).
        q: ``(T, n)`` start angles [rad] (the latent optimisation's).
        targets: :class:`~nlo_lab.objective.Targets` of the T frames.
        weights: the objective's weights (:class:`~nlo_lab.objective.LossWeights`), as the latent optimisation's.
        iterations, patience, lr: Adam's steps, the stop after ``patience`` evaluations without
            improvement, its step [rad].
        collision_form: as :class:`~nlo_lab.inference.OptimizeSettings`.
        anchor: ``(n,)`` the frame before ``targets`` (a previous chunk's last): frame 0 pays its step from it.
        fast: the objective's evaluation (:func:`~nlo_lab.inference.fast_paths`); same numbers either way.
    """
    start = time.perf_counter()
    weights = weights or LossWeights()
    dtype = robot.lower_limits.dtype
    targets = targets.to(dtype=dtype)
    q0 = q.detach().to(dtype)
    hand = hand_joint_mask(robot).to(q0.device)
    index = hand.nonzero().flatten()
    paths = fast_paths(fast, len(targets), targets.shoulder.device)
    loss_fn = Objective(robot, targets, weights, collision_form, **paths.objective_options())
    smooth = smoothness_term(robot, targets, weights, anchor)
    lo, hi = robot.lower_limits[index], robot.upper_limits[index]

    def angles(x: torch.Tensor) -> torch.Tensor:
        return q0.index_copy(1, index, x)  # the hand joints from x, the others as given

    def evaluate(x):
        full = angles(x)
        total, terms = loss_fn(full)
        if smooth is not None:
            total = total + smooth(full)
        return total, full, terms

    def project(x):  # inside the limits
        x.copy_(torch.maximum(torch.minimum(x, hi), lo))

    if index.numel() == 0 or len(targets) == 0:
        iterations = 0
    x0 = q0[:, index].clamp(lo, hi)
    _, best_q, loss, terms, history, steps = descend(x0, evaluate, project, iterations, patience, lr, None,
                                                      per_sample=smooth is None)
    best_q = best_q.detach()
    with torch.no_grad():
        if targets.fps is not None and len(targets) > 1:  # never slower than the start
            x = within_speed(best_q[:, index], q0[:, index], robot.velocity_limits[index] / float(targets.fps))
            best_q = angles(x)
            loss, _, terms = evaluate(x)
        # never a new self-collision: such a frame keeps the start's hands
        cull = paths.cull_far_pairs
        kept = penetrating(robot, best_q, cull) & ~penetrating(robot, q0, cull)
        if bool(kept.any()):
            best_q = torch.where(kept[:, None], angles(x0), best_q)
            loss, _, terms = evaluate(best_q[:, index])
    return HandStageResult(best_q, loss.detach(), terms.detach(), history, steps, time.perf_counter() - start, kept)


def within_speed(x: torch.Tensor, start: torch.Tensor, step: torch.Tensor) -> torch.Tensor:
    """``x (T, h)`` with each joint's step between consecutive frames at most ``max(step, |start's step|)``,
    clamped frame by frame from frame 0 (``step (h,)``: the velocity limit times the frame period [rad])."""
    cap = torch.maximum((start[1:] - start[:-1]).abs(), step)  # (T-1, h)
    out = [x[0]]
    for t in range(1, x.shape[0]):
        out.append(torch.minimum(torch.maximum(x[t], out[-1] - cap[t - 1]), out[-1] + cap[t - 1]))
    return torch.stack(out)


def penetrating(robot: Robot, q: torch.Tensor, cull: bool = False) -> torch.Tensor:
    """``(T,)`` bool: some checked capsule pair of ``q (T, n)`` penetrates (surface distance < 0), as the metrics count it.

    ``cull``: the faster form, the same verdicts: a pair's exact distance only where a lower bound
    does not clear it of contact (:func:`~nlo_lab.objective.near_pair_distances` with margins 0;
    most of YuMi's pairs are centimetres apart in every frame)."""
    if q.shape[0] == 0 or not robot.spec.collision_pairs:
        return torch.zeros(q.shape[0], dtype=torch.bool, device=q.device)
    with torch.no_grad():
        poses = robot.forward_kinematics(q)
        if not cull:
            return (robot.capsule_distances(poses) < 0).any(-1)
        segments = robot.capsule_segments(poses)  # (T, C, 2, 3)
        pairs = torch.as_tensor(robot.pair_capsules, device=q.device)  # (P, 2)
        ends = segments[:, pairs].reshape(q.shape[0], -1, 4, 3)  # a0, a1, b0, b1
        radii = robot.pair_radii.to(dtype=ends.dtype, device=ends.device)
        return (near_pair_distances(ends, radii, torch.zeros_like(radii)) < 0).any(-1)

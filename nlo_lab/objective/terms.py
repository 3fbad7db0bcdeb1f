"""The objective's terms, each as the paper writes it (Zhang et al., Sec. "Problem Statement").

Every term is returned per sample, shape ``(B,)``, summed over arms / fingers /
collision pairs. Robot quantities come from :class:`~nlo_lab.objective.points.RobotPoints`
(a term's ``needs`` names the fields it reads), human ones from
:class:`~nlo_lab.objective.targets.Targets`; a hat marks the human side.
Positions are in metres in the robot / body frame; every term is unitless.

These functions are what :class:`~nlo_lab.objective.total.Objective` runs by default;
asked for it (``Objective(fused=True)``, as the pipeline does for small CPU batches) the
same terms run in numpy with a written-out gradient (:mod:`nlo_lab.objective.numpy_backend`).

Temporal coherence is not in the paper (it has "no mechanism to ensure smoothness"):
:func:`smoothness_loss` couples consecutive frames and is added by the optimisers,
which see the whole sequence; it is not one of the per-frame ``TERMS``.
"""

from __future__ import annotations

import torch

from nlo_lab.errors import SettingsError
from nlo_lab.objective.weights import (
    COLLISION_FORMS,
    CONTACT_SCALE,
    PINCH_OFF,
    PINCH_ON,
    SMOOTH_MAX_STEP,
    SMOOTH_SPEED_CAP,
    SMOOTH_STEP_WIDTH,
)
from nlo_lab.robot.collision import segment_distance_ends

__all__ = [
    "end_effector_loss",
    "orientation_loss",
    "elbow_loss",
    "finger_loss",
    "fingertip_loss",
    "thumb_loss",
    "pinch_loss",
    "fingertip_direction_loss",
    "finger_direction_loss",
    "thumb_gap_loss",
    "pinch_activation",
    "in_wrist_frame",
    "collision_loss",
    "collision_scale",
    "capsule_distances",
    "latent_loss",
    "smoothness_loss",
    "smoothness_scale",
    "step_cost",
    "unit",
    "chord",
    "masked_sum",
    "UNIT_EPS",
    "CHORD_EPS",
]

UNIT_EPS = 1e-9  # [m^2] keeps the unit vector of a zero-length finger finite
CHORD_EPS = 1e-3  # rounds chord()'s kink at 0: below about this distance (0.06° between unit vectors) it is quadratic


def needs(*fields: str):
    """Mark a term with the :class:`~nlo_lab.objective.points.RobotPoints` fields it reads."""

    def mark(fn):
        fn.needs = fields
        return fn

    return mark


def masked_sum(values: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Sum over the dims after the first of ``values`` where ``mask``, exactly 0 (and no gradient) elsewhere."""
    return torch.where(mask, values, torch.zeros_like(values)).flatten(1).sum(1)


def unit(v: torch.Tensor, eps: float = UNIT_EPS) -> torch.Tensor:
    """``v / sqrt(|v|² + eps)``: the direction of ``v (..., 3)``, finite at 0."""
    return v / v.pow(2).sum(-1, keepdim=True).add(eps).sqrt()


@needs("shoulder", "wrist")
def end_effector_loss(shoulder, wrist, arm_length, t_shoulder, t_wrist, t_arm_length, mask) -> torch.Tensor:
    """``L_ee = sum_side ||(p_w - p_s)/l - (p̂_w - p̂_s)/l̂||²``.

    The wrist relative to the shoulder, in units of the arm's length: the robot's
    zero-pose upper + fore arm ``l``, the demonstrator's ``l̂`` (median over the sequence).

    Args:
        shoulder, wrist: ``(B, 2, 3)`` robot [m]; arm_length: ``(2,)`` or ``(B, 2)`` [m].
        t_shoulder, t_wrist: ``(B, 2, 3)`` human [m]; t_arm_length: ``(B, 2)`` [m].
        mask: ``(B, 2)`` both shoulder and wrist observed.

    Returns:
        ``(B,)``.
    """
    p = (wrist - shoulder) / arm_length[..., None]
    p_hat = (t_wrist - t_shoulder) / t_arm_length[..., None]
    return masked_sum((p - p_hat).pow(2).sum(-1), mask)


@needs("wrist_rotation")
def orientation_loss(rotation, t_rotation, mask) -> torch.Tensor:
    """``L_ori = sum_side ||R_wrist R_align - R̂||_F²``.

    Args:
        rotation: ``(B, 2, 3, 3)`` robot wrist rotation, already aligned to the human
            wrist convention (``R_align``: the spec's ``wrist_alignment``).
        t_rotation: ``(B, 2, 3, 3)`` human ``R_body_wrist``.
        mask: ``(B, 2)`` wrist orientation observed.

    Returns:
        ``(B,)``.
    """
    return masked_sum((rotation - t_rotation).pow(2).sum((-1, -2)), mask)


@needs("elbow", "wrist")
def elbow_loss(elbow, wrist, fore_length, t_elbow, t_wrist, t_fore_length, mask) -> torch.Tensor:
    """``L_elbow = sum_side ||(p_w - p_e)/l_fore - (p̂_w - p̂_e)/l̂_fore||²``.

    The forearm in units of its length. Shapes as :func:`end_effector_loss` (mask:
    elbow and wrist observed).
    """
    v = (wrist - elbow) / fore_length[..., None]
    v_hat = (t_wrist - t_elbow) / t_fore_length[..., None]
    return masked_sum((v - v_hat).pow(2).sum(-1), mask)


@needs("finger_base", "finger_tip")
def finger_loss(base, tip, t_base, t_tip, mask) -> torch.Tensor:
    """``L_finger = sum_finger ||u - û||²`` with ``u`` the unit base -> tip direction.

    A direction, not a position: robot and human fingers differ in length.

    Args:
        base, tip: ``(B, K, 3)`` robot [m]; t_base, t_tip: ``(B, K, 3)`` the matching
            human fingers [m]; mask: ``(B, K)``. K = 0 (no hands) gives zeros.

    Returns:
        ``(B,)``.
    """
    if base.shape[1] == 0:
        return base.new_zeros(base.shape[0])
    return masked_sum((unit(tip - base) - unit(t_tip - t_base)).pow(2).sum(-1), mask)


def in_wrist_frame(v: torch.Tensor, rotation: torch.Tensor, side: torch.Tensor, hand_length: torch.Tensor) -> torch.Tensor:
    """``R_sᵀ v / l_s``: vectors ``v (B, K, 3)`` [m] of the hand on ``side (K,)`` in that hand's wrist
    frame (``rotation (B, 2, 3, 3)``, columns = wrist axes), in units of its length ``hand_length``
    (``(2,)`` or ``(B, 2)`` [m])."""
    R = rotation[:, side]  # (B, K, 3, 3)
    length = hand_length[..., side] if hand_length.dim() == 1 else hand_length[:, side]
    return torch.einsum("bkji,bkj->bki", R, v) / length[..., None]


@needs("wrist", "wrist_rotation", "finger_tip")
def fingertip_loss(wrist, rotation, tip, hand_length, t_wrist, t_rotation, t_tip, t_hand_length, side, mask) -> torch.Tensor:
    """``L_tip = sum_side sum_finger ||R_wᵀ(p_tip - p_w)/l_h - R̂_wᵀ(p̂_tip - p̂_w)/l̂_h||²``.

    The wrist -> fingertip vectors, in the wrist frame, scaled from the human's hand to the
    robot's (the "vector" formulation of DexPilot / dex-retargeting, with the scale
    ``l_h / l̂_h``). ``l_h``: the hand length, the mean wrist -> finger base (knuckle) distance
    of the four fingers (the robot's at its reference pose, the demonstrator's median). In
    the wrist frame the term sees the handshape only: it does not move the arm.

    Args:
        wrist: ``(B, 2, 3)`` robot [m]; rotation: ``(B, 2, 3, 3)`` its aligned wrist frames;
            tip: ``(B, K, 3)`` the robot's K fingertips [m]; hand_length: ``(2,)`` [m].
        t_wrist, t_rotation: the human's, same shapes; t_tip: ``(B, K, 3)`` the matching
            human fingertips; t_hand_length: ``(B, 2)`` [m].
        side: ``(K,)`` long, the side of each finger; mask: ``(B, K)`` fingertip and wrist frame observed.

    Returns:
        ``(B,)``; exactly 0 when the robot's hand has the human's shape at the robot's size.
    """
    if tip.shape[1] == 0:
        return tip.new_zeros(tip.shape[0])
    v = in_wrist_frame(tip - wrist[:, side], rotation, side, hand_length)
    v_hat = in_wrist_frame(t_tip - t_wrist[:, side], t_rotation, side, t_hand_length)
    return masked_sum((v - v_hat).pow(2).sum(-1), mask)


@needs("wrist_rotation", "finger_tip")
def thumb_loss(rotation, tip, hand_length, t_rotation, t_tip, t_hand_length, pairs, side, mask) -> torch.Tensor:
    """``L_thumb = sum_side sum_(finger != thumb) ||u(R_wᵀ(p_f - p_th)) - u(R̂_wᵀ(p̂_f - p̂_th))||²``, ``u(v) = v/|v|``.

    The thumb tip -> other fingertip *directions*, in the wrist frame: where the thumb sits
    against the other fingers, whatever the two hands' sizes and proportions (``2 - 2 cos`` of
    the angle between the two directions). How close the thumb comes is the pinch term's
    job. Directions, not the scaled vectors of :func:`fingertip_loss`: on the real recordings
    of ``benchmarks/hands.py`` the vectors left the thumb at 27.6° from the human's (measured
    2026-11-26), the directions at 21-24° (docs/RESULTS.md, "Handshapes"): the Inspire thumb
    is shorter than a human's against the palm, so a scaled vector it cannot reach pulled it
    off the human's direction.

    Args:
        rotation, t_rotation: ``(B, 2, 3, 3)``; tip, t_tip: ``(B, K, 3)`` [m];
        hand_length: ``(2,)``, t_hand_length: ``(B, 2)`` [m] as in :func:`fingertip_loss`.
        pairs: ``(J, 2)`` long, (thumb, finger) indices into the K fingers, same hand;
        side: ``(J,)`` long, each pair's side; mask: ``(B, J)`` both tips and the wrist frame observed.

    Returns:
        ``(B,)``.
    """
    if pairs.shape[0] == 0:
        return tip.new_zeros(tip.shape[0])
    u = unit(in_wrist_frame(tip[:, pairs[:, 1]] - tip[:, pairs[:, 0]], rotation, side, hand_length))
    u_hat = unit(in_wrist_frame(t_tip[:, pairs[:, 1]] - t_tip[:, pairs[:, 0]], t_rotation, side, t_hand_length))
    return masked_sum((u - u_hat).pow(2).sum(-1), mask)


@needs("wrist", "wrist_rotation", "finger_tip")
def fingertip_direction_loss(wrist, rotation, tip, hand_length, t_wrist, t_rotation, t_tip, t_hand_length, side, mask) -> torch.Tensor:
    """``L_tip_dir = sum_side sum_finger chord(u(R_wᵀ(p_tip - p_w)), u(R̂_wᵀ(p̂_tip - p̂_w)))``, ``u(v) = v/|v|``,
    ``chord(u, û) = sqrt(||u - û||² + ε²) - ε`` (``ε`` = ``CHORD_EPS``).

    The wrist -> fingertip *directions* in the wrist frame: where each fingertip points from the wrist,
    whatever the hands' sizes and proportions; the measure ``benchmarks/hands.py`` scores. Each finger
    costs the chord ``||u - û|| = 2 sin(θ/2)`` of its angle ``θ`` (≈ ``θ``; ``ε`` only rounds the kink at
    0): like the measure, a mean of angles, so a fingertip the hand cannot point where the human's does
    (6 actuated joints for 12 finger joints) does not take the effort the others need, as the squared
    chord ``2 - 2 cos θ`` did (measured 2026-11-26 on the benchmark's recordings, hand stage of 60 steps:
    wrist->tip 17.4° squared against 17.1° with the chord, at the other three measures as good or better).
    :func:`fingertip_loss` compares the scaled vectors instead: a robot finger shorter or longer than the
    scaled human one there trades direction for length (docs/RESULTS.md, "Handshapes").

    Arguments as :func:`fingertip_loss` (the hand lengths scale both vectors, so they change only
    the tiny ``UNIT_EPS`` of a zero-length vector; kept so the numpy form is the same arithmetic).

    Returns:
        ``(B,)``; exactly 0 when every fingertip points where the human's does.
    """
    if tip.shape[1] == 0:
        return tip.new_zeros(tip.shape[0])
    u = unit(in_wrist_frame(tip - wrist[:, side], rotation, side, hand_length))
    u_hat = unit(in_wrist_frame(t_tip - t_wrist[:, side], t_rotation, side, t_hand_length))
    return masked_sum(chord((u - u_hat).pow(2).sum(-1)), mask)


def chord(square: torch.Tensor) -> torch.Tensor:
    """``sqrt(s + ε²) - ε`` of a squared distance ``s``: the distance, 0 at 0 with a finite gradient there (``ε`` = ``CHORD_EPS``)."""
    return square.add(CHORD_EPS * CHORD_EPS).sqrt() - CHORD_EPS


@needs("wrist_rotation", "finger_base", "finger_tip")
def finger_direction_loss(rotation, base, tip, hand_length, t_rotation, t_base, t_tip, t_hand_length, side, mask) -> torch.Tensor:
    """``L_finger_dir = sum_side sum_finger ||u(R_wᵀ(p_tip - p_base)) - u(R̂_wᵀ(p̂_tip - p̂_base))||²``.

    The finger base -> tip directions in the *wrist* frame: how each finger is bent, against the
    hand. The paper's :func:`finger_loss` compares the same directions in the body frame, so
    where the robot's wrist cannot turn as the human's does, it bends the fingers to make up for
    the wrist; this term asks for the handshape.

    Args:
        rotation, t_rotation: ``(B, 2, 3, 3)`` the aligned wrist frames; base, tip: ``(B, K, 3)``
            robot [m]; t_base, t_tip: the matching human fingers [m]; hand_length ``(2,)``,
            t_hand_length ``(B, 2)`` [m] (as in :func:`fingertip_direction_loss`); side: ``(K,)``;
            mask: ``(B, K)`` finger and wrist frame observed.

    Returns:
        ``(B,)``.
    """
    if tip.shape[1] == 0:
        return tip.new_zeros(tip.shape[0])
    u = unit(in_wrist_frame(tip - base, rotation, side, hand_length))
    u_hat = unit(in_wrist_frame(t_tip - t_base, t_rotation, side, t_hand_length))
    return masked_sum((u - u_hat).pow(2).sum(-1), mask)


@needs("finger_tip")
def thumb_gap_loss(tip, hand_length, t_tip, t_hand_length, pairs, side, floor, mask) -> torch.Tensor:
    """``L_gap = sum_side sum_(finger != thumb) e²``, ``e = d - d̂`` where ``d̂ >= d_min``, else ``(d - d_min)_+``.

    The thumb tip -> fingertip distances ``d``, ``d̂`` in hand lengths (as :func:`pinch_loss`'s), matched
    both ways in every frame: how far the thumb is from each finger follows the human's, opening as
    well as closing, never asked below ``d_min`` (what the hand can do; closer than that it is not pushed
    apart, so a robot hand that matches the human's costs 0). :func:`pinch_loss` acts only
    while the human pinches and only draws together; on the real recordings this term raised the
    thumb-index distance's correlation with the human's (the pinch measure of ``benchmarks/hands.py``).

    Args:
        as :func:`pinch_loss`.

    Returns:
        ``(B,)``; exactly 0 when every distance is the human's (or at most ``d_min`` where the human's is below it).
    """
    if pairs.shape[0] == 0:
        return tip.new_zeros(tip.shape[0])
    length = hand_length[side]
    gap = tip[:, pairs[:, 1]] - tip[:, pairs[:, 0]]
    d = gap.pow(2).sum(-1).add(UNIT_EPS).sqrt() / length  # (B, J)
    with torch.no_grad():  # the human side: a target
        d_hat = (t_tip[:, pairs[:, 1]] - t_tip[:, pairs[:, 0]]).norm(dim=-1) / t_hand_length[:, side]
        below = d_hat < floor
    e = torch.where(below, (d - floor).clamp_min(0.0), d - d_hat)
    return masked_sum(e.pow(2), mask)


def pinch_activation(distance: torch.Tensor) -> torch.Tensor:
    """``a(d̂) = clamp((PINCH_OFF - d̂)/(PINCH_OFF - PINCH_ON), 0, 1)``: 1 while the human's thumb and
    fingertip touch (``d̂`` in hand lengths below ``PINCH_ON``), 0 beyond ``PINCH_OFF``, linear between."""
    return ((PINCH_OFF - distance) / (PINCH_OFF - PINCH_ON)).clamp(0.0, 1.0)


@needs("finger_tip")
def pinch_loss(tip, hand_length, t_tip, t_hand_length, pairs, side, floor, mask) -> torch.Tensor:
    """``L_pinch = sum_side sum_(finger != thumb) a(d̂) ((d - max(d̂, d_min))_+)²``.

    ``d = |p_f - p_th|/l_h``, ``d̂ = |p̂_f - p̂_th|/l̂_h``: thumb-tip to fingertip distances in hand
    lengths; ``a`` = :func:`pinch_activation`. When the human's thumb and a fingertip touch, the
    robot's are drawn together, down to the human's distance but never below ``d_min``, the
    closest this robot's thumb and finger can come (``PointPlan.pinch_floor``): within what
    the hand can do. Never pushes tips apart; 0 at a perfect match.

    Args:
        tip, t_tip: ``(B, K, 3)`` [m]; hand_length ``(2,)``, t_hand_length ``(B, 2)`` [m];
        pairs, side: as in :func:`thumb_loss`; floor: ``(J,)`` ``d_min`` of each pair [hand lengths];
        mask: ``(B, J)``.

    Returns:
        ``(B,)``.
    """
    if pairs.shape[0] == 0:
        return tip.new_zeros(tip.shape[0])
    length = hand_length[side]
    gap = tip[:, pairs[:, 1]] - tip[:, pairs[:, 0]]
    d = gap.pow(2).sum(-1).add(UNIT_EPS).sqrt() / length  # (B, J)
    with torch.no_grad():  # the human side: a target, not a variable
        d_hat = (t_tip[:, pairs[:, 1]] - t_tip[:, pairs[:, 0]]).norm(dim=-1) / t_hand_length[:, side]
        goal = torch.maximum(d_hat, floor)
        active = pinch_activation(d_hat)
    return masked_sum(active * (d - goal).clamp_min(0.0).pow(2), mask)


def collision_scale(margins: torch.Tensor) -> torch.Tensor:
    """``s = d_min``, or ``CONTACT_SCALE`` for a pair whose margin is 0: the hinge's length unit per pair [m]."""
    return torch.where(margins > 0, margins, torch.full_like(margins, CONTACT_SCALE))


@needs("capsule_ends")
def collision_loss(distances: torch.Tensor, margins: torch.Tensor, form: str = "hinge") -> torch.Tensor:
    """Self-collision over the capsule pairs closer than their margin ``d_min``.

    ``"hinge"`` (default): ``L_col = sum_pairs ((d_min - d)/s)²`` for ``d < d_min``, ``s = d_min``
    (:func:`collision_scale`): 1 where the capsules touch. A pair with ``d_min = 0`` (a spec
    allowing contact) costs only penetration, in units of ``s = CONTACT_SCALE`` (YuMi's thumb
    against its own fingers has ``d_min`` = 1 mm instead: at 0 a pinch's optimum sat just inside
    contact, ``assets/robots/YUMI.md``).
    ``"paper"``: ``L_col = sum_pairs exp(-d²) [d < d_min]``. The paper's form jumps at
    ``d_min``, has almost no gradient near contact (``-2d e^{-d²}`` -> 0) and, with a
    surface distance (< 0 inside), pushes penetrating capsules *deeper*; the squared
    hinge is zero above ``d_min``, continuous with its gradient, and always pushes
    the capsules apart.

    Args:
        distances: ``(B, P)`` capsule surface distances [m] (< 0 = penetration), see
            :func:`capsule_distances`.
        margins: ``(P,)`` d_min per pair [m].
        form: ``"hinge"`` or ``"paper"``.

    Returns:
        ``(B,)``, exactly 0 when every pair is at least ``d_min`` apart.
    """
    if form not in COLLISION_FORMS:
        raise SettingsError(f"unknown collision form {form!r}; expected one of {COLLISION_FORMS}")
    if distances.shape[-1] == 0:
        return distances.new_zeros(distances.shape[0])
    if form == "paper":
        return masked_sum(torch.exp(-distances.pow(2)), distances < margins)
    # clamp: exactly 0 (and no gradient) at and above d_min
    return ((margins - distances) / collision_scale(margins)).clamp_min(0.0).pow(2).sum(-1)


def capsule_distances(ends: torch.Tensor, radii: torch.Tensor) -> torch.Tensor:
    """``d = dist(segment a, segment b) - r_a - r_b`` per pair: ``ends (B, P, 4, 3)`` [m] -> ``(B, P)`` [m]."""
    return segment_distance_ends(ends) - radii


def latent_loss(z: torch.Tensor, sigma: float = 1.0) -> torch.Tensor:
    """``L_z = ||z||²/σ²`` per sample: ``z (B, ...)`` -> ``(B,)`` (the paper's latent prior, σ = 1)."""
    return z.pow(2).flatten(1).sum(1) / (sigma * sigma)


def smoothness_scale(velocity_limits: torch.Tensor) -> torch.Tensor:
    """``(n,)`` the speed unit ``s_j`` of each joint in :func:`smoothness_loss` [rad/s]: its velocity
    limit, at most ``SMOOTH_SPEED_CAP`` (unlimited joints count at the cap)."""
    return velocity_limits.clamp(max=SMOOTH_SPEED_CAP)


def smoothness_loss(q: torch.Tensor, fps: float, velocity_limits: torch.Tensor) -> torch.Tensor:
    """``L_smooth,t = step_cost(q_t - q_{t-1})``: joint speed between consecutive frames, in units of each joint's limit.

    It removes jitter and branch flips (a jump between two arm configurations costs
    the square of its speed), and it weighs a joint by how slow the robot is there,
    so the motion the robot cannot follow is what it trades against tracking.

    Args:
        q: ``(T, n)`` joint angles of consecutive frames [rad].
        fps: frame rate [1/s].
        velocity_limits: ``(n,)`` [rad/s] (see :func:`smoothness_scale`).

    Returns:
        ``(T,)``: frame 0 holds 0.
    """
    if q.shape[0] == 0:
        return q.new_zeros(0)
    return torch.cat([q.new_zeros(1), step_cost(q[1:] - q[:-1], fps, velocity_limits)])


def step_cost(step: torch.Tensor, fps: float, velocity_limits: torch.Tensor) -> torch.Tensor:
    """``sum_j (Δq_j fps / s_j)² + sum_j ((|Δq_j| - MAX_STEP)_+ / STEP_WIDTH)²``: ``step (..., n)`` [rad] -> ``(...)``.

    ``s`` = :func:`smoothness_scale`. The second sum covers the joints that move more than
    ``SMOOTH_MAX_STEP`` in one frame: a fast joint (NAO's wrist, 24.6 rad/s) may follow
    a fast human rotation within its speed limit, but not by jumping half a radian
    between two samples (the robot's controller would see a step, not a motion).
    """
    speed = step * (fps / smoothness_scale(velocity_limits).to(step.dtype))
    jump = (step.abs() - SMOOTH_MAX_STEP).clamp_min(0.0) / SMOOTH_STEP_WIDTH
    return speed.pow(2).sum(-1) + jump.pow(2).sum(-1)

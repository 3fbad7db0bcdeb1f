"""One sign of one signer: the arm and finger angles that perform it on the signer's body.

A sign's hand path (:func:`nlo_lab.corpus.signs.movement_path` around its location) is
solved with the analytic arm IK (:func:`~nlo_lab.corpus.arm_kinematics.arm_ik`), then
shifted away from the body (and from a base hand) until the hand clears them by
``PUSH_CLEARANCE`` (more than the corpus' own ``CLEARANCE``, so the checks of
:mod:`nlo_lab.corpus.generate` rarely reject a sign). Signs last 0.5-1.2 s; a path too
fast for its duration is slowed down or made smaller (``PATH_ACCEL``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from nlo_lab.corpus.arm_kinematics import arm_fk, arm_ik, knuckle_centre
from nlo_lab.corpus.body import ARM_RANGES, FINGER_RANGES, BodyParams, body_gradient, body_signed_distance, torso_signed_distance
from nlo_lab.corpus.signs import PALMS, RELAXED, Sign, handshape, location_point, minimum_jerk, movement_path

__all__ = ["Signer", "PUSH_CLEARANCE", "PATH_ACCEL", "sign_duration_floor", "sign_segment"]

PUSH_CLEARANCE = 0.02  # [m] clearance from the body targeted while solving a sign (above the corpus' CLEARANCE)
_HAND_PUSH_CLEARANCE = 0.06  # [m] the same from a base hand (room for the approach of the dominant hand)
_ELBOW_PUSH_CLEARANCE = 0.05  # [m] elbow joint centre from the torso while solving a sign
PATH_ACCEL = 12.0  # [m/s^2] peak acceleration allowed for a sign's own movement path


@dataclass(frozen=True)
class Signer:
    """One synthetic signer: body, dominant side, elbow habit, pace and rest pose."""

    name: str
    body: BodyParams
    dominant: str  # "left" or "right"
    elbow_out: float  # sideways part of the elbow swivel reference
    speed: float  # > 1 signs faster
    rest: np.ndarray  # (7,) rest-pose arm angles [rad]


def _knuckle_centre(pose) -> np.ndarray:
    return pose.finger_base[..., 1:, :].mean(axis=-2)


def _solve(body: BodyParams, ref: np.ndarray, distal: np.ndarray, elbow_out: float, elbow_forward: float) -> np.ndarray:
    """Arm angles ``(n, 7)`` that put the knuckle centre on ``ref`` ``(n, 3)`` (canonical right arm)."""
    wrist = ref.copy()
    for _ in range(2):  # the hand offset depends on the forearm direction: a few fixed-point steps
        q = arm_ik(body, wrist, "right", distal, elbow_out, elbow_forward)
        wrist = wrist + (ref - knuckle_centre(body, q))
    return arm_ik(body, wrist, "right", distal, elbow_out, elbow_forward)


def _solve_clear(body, ref, distal, fingers, elbow_out, obstacle: np.ndarray | None = None) -> np.ndarray:
    """:func:`_solve`, then shift the whole sign away from the body (and from ``obstacle``,
    ``(m, 3)`` points such as the other hand) until its hand clears them by ``PUSH_CLEARANCE``;
    an elbow that would sink into the belly is brought forward."""
    forward = 0.0
    for _ in range(6):
        q = _solve(body, ref, distal, elbow_out, forward)
        pose = arm_fk(body, q, fingers, "right")
        pts = pose.hand_points()  # (n, 26, 3)
        sd = body_signed_distance(body, pts)
        worst = np.unravel_index(np.argmin(sd), sd.shape)
        push = body_gradient(body, pts[worst]) * max(PUSH_CLEARANCE - sd[worst] + 0.003, 0.0)
        if obstacle is not None:
            gap = np.linalg.norm(pts[:, :, None, :] - obstacle, axis=-1)  # (n, 26, m)
            t, i, j = np.unravel_index(np.argmin(gap), gap.shape)
            if gap[t, i, j] < _HAND_PUSH_CLEARANCE:
                away = (pts[t, i] - obstacle[j]) / max(gap[t, i, j], 1e-6)
                push = push + away * (_HAND_PUSH_CLEARANCE - gap[t, i, j] + 0.003)
        elbow_low = torso_signed_distance(body, pose.elbow).min() < _ELBOW_PUSH_CLEARANCE
        if elbow_low and forward < 2.0:
            forward += 0.5
        if not push.any() and not elbow_low:
            break
        ref = ref + push
    return q


def _path_accel(sign: Sign, duration: float) -> float:
    """Peak acceleration [m/s^2] of a sign's movement path (without the arm's own curvature)."""
    tau = np.linspace(0.0, 1.0, 201)
    off, twist = movement_path(sign, tau)
    off = off + 0.1 * np.stack([np.zeros_like(twist), np.sin(twist), 1 - np.cos(twist)], axis=-1)  # fingertips of a twist
    dt = duration / 200
    return float(np.linalg.norm(np.diff(off, n=2, axis=0), axis=-1).max() / dt**2)


def sign_duration_floor(sign: Sign) -> float:
    """Shortest duration [s] (at most 1.2) at which the sign's path stays below ``PATH_ACCEL``."""
    return float(np.clip(np.sqrt(_path_accel(sign, 1.0) / PATH_ACCEL), 0.5, 1.2))


def _paced(sign: Sign, duration: float) -> Sign:
    """The sign with its amplitude reduced if even 1.2 s is too short for its path."""
    peak = _path_accel(sign, max(duration, 1.2))
    if peak <= PATH_ACCEL:
        return sign
    return dataclasses.replace(sign, amplitude=sign.amplitude * PATH_ACCEL / peak)


def _finger_track(sign: Sign, tau: np.ndarray, jitter: np.ndarray) -> np.ndarray:
    start = handshape(sign.handshape)
    end = start if sign.end_handshape is None else handshape(sign.end_handshape)
    s = minimum_jerk(np.clip(tau * 1.25 - 0.1, 0, 1))[:, None, None]  # change in the middle of the sign
    f = start + (end - start) * s + jitter
    return np.clip(f, FINGER_RANGES[..., 0], FINGER_RANGES[..., 1])


def sign_segment(sign: Sign, signer: Signer, fps: float, rng: np.random.Generator):
    """Angles of both arms during one sign: ``(n, 2, 7)`` and ``(n, 2, 5, 4)``, sides (left, right)."""
    body = signer.body
    duration = float(np.clip(rng.uniform(0.6, 1.1) / signer.speed, 0.5, 1.2))
    sign = _paced(sign, duration)
    duration = max(duration, sign_duration_floor(sign))
    n = int(round(duration * fps)) + 1
    tau = np.linspace(0.0, 1.0, n)
    two = sign.pattern in ("symmetric", "alternating")
    obstacle = None
    jitter = rng.normal(0.0, 0.012, 3)
    dom_side = signer.dominant
    non_side = "left" if dom_side == "right" else "right"
    arm = {}
    fingers = {}

    def distal_track(palm: str, twist: np.ndarray) -> np.ndarray:
        d = np.array(PALMS[palm]) + rng.normal(0.0, 0.05, 3)
        d = np.broadcast_to(d, (n, 3)).copy()
        d[:, 0] += twist
        return np.clip(d, ARM_RANGES[4:, 0] + 0.02, ARM_RANGES[4:, 1] - 0.02)

    fj = rng.normal(0.0, 0.04, (5, 4))
    fingers[dom_side] = _finger_track(sign, tau, fj)
    if sign.pattern == "base_hand":
        base_ref = np.array([0.30, -0.07, -0.24]) * [(body.upper_arm + body.forearm) / 0.56, 1, 1] + jitter
        base_f = np.broadcast_to(handshape(sign.base_handshape), (n, 5, 4)).copy()
        base_d = distal_track("up", np.zeros(n))
        q_base = _solve_clear(body, np.broadcast_to(base_ref, (n, 3)).copy(), base_d, base_f, signer.elbow_out)
        arm[non_side], fingers[non_side] = q_base, base_f
        # The dominant hand works above the base hand's palm (both in the dominant's canonical frame).
        base_pose = arm_fk(body, q_base[:1], base_f[:1], "right")
        palm = 0.5 * (base_pose.wrist[0] + _knuckle_centre(base_pose)[0])
        palm = palm * [1.0, -1.0, 1.0]  # the other side, seen in the dominant's canonical frame
        anchor = palm + np.array([0.0, 0.0, 0.12])
        obstacle = base_pose.hand_points()[0] * [1.0, -1.0, 1.0]  # (26, 3) base hand, dominant's frame
    else:
        anchor = location_point(sign.location, body, bilateral=two) + jitter
    off, twist = movement_path(sign, tau)
    arm[dom_side] = _solve_clear(
        body, anchor + off, distal_track(sign.palm, twist), fingers[dom_side], signer.elbow_out, obstacle
    )
    if two:
        off2, twist2 = movement_path(sign, tau, alternate=sign.pattern == "alternating")
        fingers[non_side] = _finger_track(sign, tau, fj + rng.normal(0.0, 0.02, (5, 4)))
        anchor2 = anchor + rng.normal(0.0, 0.008, 3)
        arm[non_side] = _solve_clear(body, anchor2 + off2, distal_track(sign.palm, twist2), fingers[non_side], signer.elbow_out)
    elif sign.pattern == "one_handed":
        arm[non_side] = np.broadcast_to(signer.rest, (n, 7)).copy()
        fingers[non_side] = np.broadcast_to(RELAXED, (n, 5, 4)).copy()
    return np.stack([arm["left"], arm["right"]], axis=1), np.stack([fingers["left"], fingers["right"]], axis=1)

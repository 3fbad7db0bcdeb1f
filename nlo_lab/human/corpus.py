"""The embedded synthetic sign-language corpus: five scenarios of signed sentences.

Organised like the paper's data (the paper's data set): three training
scenarios and two test scenarios with the paper's sequence counts. Each scenario has its own
lexicon of glosses; a sequence is a sentence of 2-6 signs by one of ``N_SIGNERS`` synthetic
signers (:func:`nlo_lab.human.body.random_body`; one in four is left-handed), starting and
ending at the rest pose. Signs are solved with the analytic arm IK on the signer's body
(:mod:`nlo_lab.human.body`); transitions between signs (0.2-0.4 s, up to 0.6 s for the
longest moves) and to/from rest (0.4-0.9 s) are minimum-jerk in joint space, signs last 0.5-1.2 s. Test signs use
``(handshape, location, movement)`` combinations that no training sign uses
(:func:`nlo_lab.human.signs.is_test_combination`).

Every sequence is checked when generated and regenerated (with the next attempt's random
stream) until it is plausible: joint angles inside ``ARM_RANGES`` / ``FINGER_RANGES``, every
hand point at least ``CLEARANCE`` from torso, neck and head, the elbows ``ELBOW_CLEARANCE``
outside the torso, the two hands at least
``HAND_CLEARANCE`` apart, wrist speed and acceleration below ``WRIST_SPEED_LIMIT`` and
``WRIST_ACCEL_LIMIT``, fingertip acceleration below ``FINGERTIP_ACCEL_LIMIT``. Deterministic from
the seed; the corpus is cached per seed and callers get copies.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
from dataclasses import asdict, dataclass
from types import MappingProxyType
from typing import Mapping

import numpy as np

from nlo_lab.errors import DemonstrationError
from nlo_lab.human.body import (
    ARM_RANGES,
    FINGER_RANGES,
    BodyParams,
    arm_fk,
    arm_ik,
    body_gradient,
    body_signed_distance,
    knuckle_centre,
    random_body,
    torso_signed_distance,
    wrist_position,
)
from nlo_lab.human.demonstration import Demonstration
from nlo_lab.human.signs import PALMS, RELAXED, Sign, handshape, location_point, minimum_jerk, movement_path, random_sign

__all__ = [
    "Scenario",
    "SCENARIOS",
    "SPLITS",
    "N_SIGNERS",
    "CLEARANCE",
    "HAND_CLEARANCE",
    "ELBOW_CLEARANCE",
    "WRIST_ACCEL_LIMIT",
    "FINGERTIP_ACCEL_LIMIT",
    "WRIST_SPEED_LIMIT",
    "sign_corpus",
    "corpus_clip",
    "corpus_names",
    "corpus_angles",
    "corpus_lexicon",
]

SPLITS = ("train", "test")
N_SIGNERS = 8
CLEARANCE = 0.01  # [m] minimum distance of any hand point to torso, neck or head
HAND_CLEARANCE = 0.01  # [m] minimum distance between points of the two hands
WRIST_ACCEL_LIMIT = 25.0  # [m/s^2] generation bound on the finite-difference wrist acceleration
WRIST_SPEED_LIMIT = 2.2  # [m/s] generation bound on the wrist speed (fast signing peaks near 2 m/s)
FINGERTIP_ACCEL_LIMIT = 60.0  # [m/s^2] the same for fingertips (they also swing with wrist rotations)
_PUSH_CLEARANCE = 0.02  # [m] clearance from the body targeted while solving a sign (above CLEARANCE)
_HAND_PUSH_CLEARANCE = 0.06  # [m] the same from a base hand (room for the approach of the dominant hand)
_ELBOW_PUSH_CLEARANCE = 0.05  # [m] elbow joint centre from the torso while solving a sign
ELBOW_CLEARANCE = 0.03  # [m] minimum distance of the elbow joint centre from the torso (about the arm's radius)
_MAX_ATTEMPTS = 40
_FPS_CHOICES = (15, 20, 25, 30)
_MIN_FRAMES, _MAX_FRAMES = 60, 250


@dataclass(frozen=True)
class Scenario:
    """One scenario: its split, number of sequences and lexicon glosses."""

    split: str
    n_sequences: int
    glosses: tuple[str, ...]


# Sequence counts as in the paper (Business 23, Railway Station 13, West Lake 25 / Hospital 12, Introduction 13).
SCENARIOS: Mapping[str, Scenario] = MappingProxyType(
    {
        "business": Scenario(
            "train", 23,
            ("MEETING", "COMPANY", "MONEY", "CONTRACT", "PRICE", "SELL", "BUY", "MANAGER", "WORK", "TOMORROW",
             "AGREE", "PHONE", "EMAIL", "OFFICE", "PROFIT", "CUSTOMER"),
        ),
        "railway_station": Scenario(
            "train", 13,
            ("TICKET", "TRAIN", "PLATFORM", "WHEN", "LEAVE", "ARRIVE", "WAIT", "LATE", "LUGGAGE", "WHERE", "TIME",
             "GATE", "SEAT", "CHANGE"),
        ),
        "west_lake": Scenario(
            "train", 25,
            ("LAKE", "BOAT", "BRIDGE", "TREE", "BEAUTIFUL", "WALK", "PHOTO", "WATER", "SUN", "TEMPLE", "FISH",
             "FLOWER", "VIEW", "RAIN"),
        ),
        "hospital": Scenario(
            "test", 12,
            ("DOCTOR", "NURSE", "PAIN", "HEAD", "MEDICINE", "FEVER", "APPOINTMENT", "INJECTION", "SICK", "BED",
             "HELP", "EMERGENCY", "BLOOD", "HEART"),
        ),
        "introduction": Scenario(
            "test", 13,
            ("NAME", "I", "YOU", "HELLO", "AGE", "FAMILY", "DEAF", "HEARING", "LEARN", "SIGN", "TEACHER", "STUDENT",
             "FRIEND", "LIVE", "NICE-TO-MEET"),
        ),
    }
)
_SCENARIO_ORDER = tuple(SCENARIOS)
_ALL_NAMES = frozenset(f"{n}_{i:02d}" for n, sc in SCENARIOS.items() for i in range(1, sc.n_sequences + 1))


@dataclass(frozen=True)
class _Signer:
    name: str
    body: BodyParams
    dominant: str  # "left" or "right"
    elbow_out: float  # sideways part of the elbow swivel reference
    speed: float  # > 1 signs faster
    rest: np.ndarray  # (7,) rest-pose arm angles [rad]


@dataclass(frozen=True)
class _Clip:
    demo: Demonstration
    arm: np.ndarray  # (T, 2, 7) [rad], sides (left, right)
    fingers: np.ndarray  # (T, 2, 5, 4) [rad]


# ------------------------------------------------------------------ public API
def corpus_names(split: str | None = None) -> list[str]:
    """Names of the corpus sequences (e.g. ``"hospital_03"``), of one split or of all.

    Args:
        split: ``"train"``, ``"test"`` or ``None`` for both.
    """
    _check_split(split, allow_none=True)
    return [
        f"{name}_{i:02d}"
        for name, sc in SCENARIOS.items()
        if split is None or sc.split == split
        for i in range(1, sc.n_sequences + 1)
    ]


def sign_corpus(split: str, seed: int = 0) -> list[Demonstration]:
    """The sequences of the train (3 scenarios) or test (2 scenarios) split, as fresh copies.

    Args:
        split: ``"train"`` or ``"test"``.
        seed: the corpus seed (same seed, identical arrays).

    Returns:
        Demonstrations with ``meta`` keys ``scenario``, ``signer``, ``signs`` (glosses),
        ``sign_components``, ``sign_frames`` (``[start, stop)`` per sign), ``dominant``,
        ``body``, ``split``, ``seed``.
    """
    _check_split(split)
    seed = _check_seed(seed)
    return [_copy_demo(_generate(name, seed).demo) for name in corpus_names(split)]


def corpus_clip(name: str, seed: int = 0) -> Demonstration:
    """One corpus sequence by name (``demo:NAME`` on the command line), as a fresh copy."""
    return _copy_demo(_clip(name, seed).demo)


def corpus_angles(name: str, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The body-model angles that generated a sequence.

    Returns:
        ``(T, 2, 7)`` arm angles (``body.ARM_JOINT_NAMES``) and ``(T, 2, 5, 4)`` finger angles,
        sides (left, right), both [rad] and copies.
    """
    clip = _clip(name, seed)
    return clip.arm.copy(), clip.fingers.copy()


def corpus_lexicon(scenario: str, seed: int = 0) -> dict[str, Sign]:
    """The signs (gloss -> :class:`~nlo_lab.human.signs.Sign`) of one scenario."""
    if scenario not in SCENARIOS:
        raise DemonstrationError(f"unknown scenario {scenario!r}; expected one of {list(SCENARIOS)}", field="scenario")
    return dict(_lexicon(scenario, _check_seed(seed)))


# ------------------------------------------------------------------ helpers
def _check_split(split, allow_none: bool = False) -> None:
    if split is None and allow_none:
        return
    if split not in SPLITS:
        raise DemonstrationError(f"unknown corpus split {split!r}; expected one of {SPLITS}", field="split")


def _check_seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise DemonstrationError(f"the corpus seed must be an integer >= 0, got {seed!r}", field="seed")
    return int(seed)


def _clip(name: str, seed: int) -> _Clip:
    seed = _check_seed(seed)
    if name not in _ALL_NAMES:
        names = corpus_names()
        raise DemonstrationError(
            f"unknown corpus sequence {name!r}; valid names are e.g. {names[:2] + names[-2:]} "
            f"({len(names)} in all, see corpus_names())",
            field="name",
        )
    return _generate(name, seed)


def _copy_demo(demo: Demonstration) -> Demonstration:
    return Demonstration(
        demo.fps,
        demo.arm_positions.copy(),
        demo.arm_mask.copy(),
        demo.wrist_rotations.copy(),
        demo.wrist_mask.copy(),
        demo.finger_positions.copy(),
        demo.finger_mask.copy(),
        name=demo.name,
        meta=copy.deepcopy(demo.meta),
    )


@functools.lru_cache(maxsize=1024)
def _generate(name: str, seed: int) -> _Clip:
    """One sequence; each depends only on (seed, scenario, index), so clips are made on demand."""
    scenario, index = name.rsplit("_", 1)
    s_idx, i = _SCENARIO_ORDER.index(scenario), int(index)
    lexicon, signers = _lexicon(scenario, seed), _signers(seed)
    for attempt in range(_MAX_ATTEMPTS):
        clip = _sequence(name, scenario, lexicon, signers, np.random.default_rng([seed, s_idx, i, attempt]), seed)
        if clip is not None:
            return clip
    raise DemonstrationError(f"no plausible sequence after {_MAX_ATTEMPTS} attempts", field=name)  # pragma: no cover


@functools.lru_cache(maxsize=32)
def _lexicon(scenario: str, seed: int) -> MappingProxyType:
    sc = SCENARIOS[scenario]
    rng = np.random.default_rng([seed, _SCENARIO_ORDER.index(scenario), 10_000])
    return MappingProxyType({g: random_sign(g, sc.split, rng) for g in sc.glosses})


@functools.lru_cache(maxsize=4)
def _signers(seed: int) -> tuple[_Signer, ...]:
    rng = np.random.default_rng([seed, 20_000])
    signers = []
    for k in range(N_SIGNERS):
        rest = np.array([0.12, 0.10, 0.15, 0.40, 0.35, 0.15, 0.05]) + rng.uniform(-0.05, 0.05, 7)
        signers.append(
            _Signer(
                name=f"signer_{k + 1}",
                body=random_body(rng),
                dominant="left" if k % 4 == 3 else "right",
                elbow_out=float(rng.uniform(0.35, 0.8)),
                speed=float(rng.uniform(0.85, 1.15)),
                rest=rest,
            )
        )
    return tuple(signers)


# ------------------------------------------------------------------ one sign
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
    ``(m, 3)`` points such as the other hand) until its hand clears them by ``_PUSH_CLEARANCE``;
    an elbow that would sink into the belly is brought forward."""
    forward = 0.0
    for _ in range(6):
        q = _solve(body, ref, distal, elbow_out, forward)
        pose = arm_fk(body, q, fingers, "right")
        pts = pose.hand_points()  # (n, 26, 3)
        sd = body_signed_distance(body, pts)
        worst = np.unravel_index(np.argmin(sd), sd.shape)
        push = body_gradient(body, pts[worst]) * max(_PUSH_CLEARANCE - sd[worst] + 0.003, 0.0)
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


_PATH_ACCEL = 12.0  # [m/s^2] peak acceleration allowed for a sign's own movement path


def _path_accel(sign: Sign, duration: float) -> float:
    """Peak acceleration [m/s^2] of a sign's movement path (without the arm's own curvature)."""
    tau = np.linspace(0.0, 1.0, 201)
    off, twist = movement_path(sign, tau)
    off = off + 0.1 * np.stack([np.zeros_like(twist), np.sin(twist), 1 - np.cos(twist)], axis=-1)  # fingertips of a twist
    dt = duration / 200
    return float(np.linalg.norm(np.diff(off, n=2, axis=0), axis=-1).max() / dt**2)


def sign_duration_floor(sign: Sign) -> float:
    """Shortest duration [s] (at most 1.2) at which the sign's path stays below ``_PATH_ACCEL``."""
    return float(np.clip(np.sqrt(_path_accel(sign, 1.0) / _PATH_ACCEL), 0.5, 1.2))


def _paced(sign: Sign, duration: float) -> Sign:
    """The sign with its amplitude reduced if even 1.2 s is too short for its path."""
    peak = _path_accel(sign, max(duration, 1.2))
    if peak <= _PATH_ACCEL:
        return sign
    return dataclasses.replace(sign, amplitude=sign.amplitude * _PATH_ACCEL / peak)


def _finger_track(sign: Sign, tau: np.ndarray, jitter: np.ndarray) -> np.ndarray:
    start = handshape(sign.handshape)
    end = start if sign.end_handshape is None else handshape(sign.end_handshape)
    s = minimum_jerk(np.clip(tau * 1.25 - 0.1, 0, 1))[:, None, None]  # change in the middle of the sign
    f = start + (end - start) * s + jitter
    return np.clip(f, FINGER_RANGES[..., 0], FINGER_RANGES[..., 1])


def _sign_segment(sign: Sign, signer: _Signer, fps: float, rng: np.random.Generator):
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


# ------------------------------------------------------------------ one sequence
def _wrists(body: BodyParams, arm: np.ndarray, fingers=None) -> np.ndarray:
    """``(n, 2, 3)`` wrist positions (left, right)."""
    return np.stack([wrist_position(body, arm[:, s], side) for s, side in enumerate(("left", "right"))], 1)


_STAGGER = 0.3  # fraction of a transition by which one arm leads the other around a base hand


def _phases(tau: np.ndarray, lead: int | None) -> np.ndarray:
    """``(n, 2)`` minimum-jerk phases of the (left, right) arms; the ``lead`` arm moves first."""
    if lead is None:
        return np.repeat(minimum_jerk(tau)[:, None], 2, axis=1)
    early = minimum_jerk(tau / (1 - _STAGGER))
    late = minimum_jerk((tau - _STAGGER) / (1 - _STAGGER))
    return np.stack([early, late] if lead == 0 else [late, early], axis=1)


def _transition(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray], frames: int, lead: int | None = None):
    """``frames`` interior frames of a minimum-jerk joint-space move from the last frame of ``a`` to the first of ``b``."""
    s = _phases(np.arange(1, frames + 1) / (frames + 1), lead)  # (frames, 2)
    qa, qb = a[0][-1], b[0][0]
    fa, fb = a[1][-1], b[1][0]
    return qa + (qb - qa) * s[:, :, None], fa + (fb - fa) * s[:, :, None, None]


def _transition_frames(body, a, b, fps: float, rng: np.random.Generator, rest_move: bool, lead: int | None = None) -> int:
    """Interior frames of a transition, long enough for its path.

    The joint-space path's shape does not depend on the duration T, so its peak wrist speed
    and acceleration are ``k1 / T`` and ``k2 / T^2``; T is the shortest duration that keeps them
    near 2.0 m/s and 18 m/s^2, within 0.2-0.6 s between signs (0.2-0.4 s unless the move is
    long) and 0.4-0.9 s to or from the rest pose.
    """
    tau = np.linspace(0.0, 1.0, 41)
    s = _phases(tau, lead)
    qa, qb = a[0][-1], b[0][0]
    q = qa + (qb - qa) * s[:, :, None]  # (41, 2, 7)
    w = _wrists(body, q, None)  # (41, 2, 3)
    d1 = np.diff(w, axis=0) / (tau[1] - tau[0])
    k1 = np.linalg.norm(d1, axis=-1).max()
    k2 = np.linalg.norm(np.diff(d1, axis=0), axis=-1).max() / (tau[1] - tau[0])
    lo, hi = (0.4, 0.9) if rest_move else (0.2, 0.6)
    needed = max(k1 / 2.0, np.sqrt(k2 / 18.0))
    duration = float(np.clip(needed * rng.uniform(1.0, 1.15), lo, hi))
    return max(1, int(round(duration * fps)) - 1)


def _rest_segment(signer: _Signer, frames: int):
    arm = np.broadcast_to(signer.rest, (frames, 2, 7)).copy()
    return arm, np.broadcast_to(RELAXED, (frames, 2, 5, 4)).copy()


def _plausible(body: BodyParams, arm: np.ndarray, fingers: np.ndarray, fps: float) -> tuple[bool, list]:
    """The generator's checks; returns (ok, the two ArmPose objects)."""
    eps = 1e-9
    if np.any(arm < ARM_RANGES[:, 0] - eps) or np.any(arm > ARM_RANGES[:, 1] + eps):
        return False, []
    if np.any(fingers < FINGER_RANGES[..., 0] - eps) or np.any(fingers > FINGER_RANGES[..., 1] + eps):
        return False, []
    poses = [arm_fk(body, arm[:, s], fingers[:, s], side) for s, side in enumerate(("left", "right"))]
    pts = [p.hand_points() for p in poses]  # (T, 26, 3) each
    if min(body_signed_distance(body, p).min() for p in pts) < CLEARANCE:
        return False, poses
    if min(torso_signed_distance(body, p.elbow).min() for p in poses) < ELBOW_CLEARANCE:
        return False, poses
    near = np.linalg.norm(poses[0].wrist - poses[1].wrist, axis=-1) < 0.5  # two hands span < 0.25 m each
    if near.any():
        hand_gap = np.linalg.norm(pts[0][near][:, :, None, :] - pts[1][near][:, None, :, :], axis=-1).min()
        if hand_gap < HAND_CLEARANCE:
            return False, poses
    for p in poses:
        if np.linalg.norm(np.diff(p.wrist, axis=0), axis=-1).max() * fps > WRIST_SPEED_LIMIT:
            return False, poses
        if np.linalg.norm(np.diff(p.wrist, n=2, axis=0), axis=-1).max() * fps**2 > WRIST_ACCEL_LIMIT:
            return False, poses
        if np.linalg.norm(np.diff(p.finger_tip, n=2, axis=0), axis=-1).max() * fps**2 > FINGERTIP_ACCEL_LIMIT:
            return False, poses
    return True, poses


def _sequence(name, scenario, lexicon, signers, rng, seed) -> _Clip | None:
    """One sentence, built sign by sign: a sign whose transition or motion is implausible is redrawn."""
    signer = signers[int(rng.integers(len(signers)))]
    body = signer.body
    fps = float(rng.choice(_FPS_CHOICES))
    glosses = list(lexicon)
    k = int(rng.integers(2, 7))
    head = _rest_segment(signer, int(round(rng.uniform(0.2, 0.5) * fps)) + 1)
    tail_frames = int(round(rng.uniform(0.2, 0.5) * fps)) + 1
    budget = _MAX_FRAMES - tail_frames - int(0.7 * fps) - 1  # room left for the way back to rest
    arms, fings, ranges, signs = [head[0]], [head[1]], [[0, len(head[0])]], []
    frames = len(head[0])
    for _ in range(4 * k):
        if len(signs) == k:
            break
        gloss = glosses[int(rng.integers(len(glosses)))]
        if signs and gloss == signs[-1].gloss:
            continue
        if frames + int(1.6 * fps) + 2 > budget:  # the longest sign and transition would not fit
            break
        sign = lexicon[gloss]
        seg = _sign_segment(sign, signer, fps, rng)
        # around a base hand the base arrives first and the dominant hand leaves first
        dom = 0 if signer.dominant == "left" else 1
        lead = 1 - dom if sign.pattern == "base_hand" else (dom if signs and signs[-1].pattern == "base_hand" else None)
        prev = (arms[-1], fings[-1])
        qa, fa = _transition(prev, seg, _transition_frames(body, prev, seg, fps, rng, not signs, lead), lead)
        if frames + len(qa) + len(seg[0]) > budget:
            break
        window = (np.concatenate([arms[-1][-2:], qa, seg[0]]), np.concatenate([fings[-1][-2:], fa, seg[1]]))
        if not _plausible(body, window[0], window[1], fps)[0]:
            continue
        arms += [qa, seg[0]]
        fings += [fa, seg[1]]
        ranges.append([frames + len(qa), frames + len(qa) + len(seg[0])])
        frames += len(qa) + len(seg[0])
        signs.append(sign)
    if len(signs) < 2:
        return None
    tail = _rest_segment(signer, max(tail_frames, _MIN_FRAMES - frames - int(0.7 * fps)))
    lead = (0 if signer.dominant == "left" else 1) if signs[-1].pattern == "base_hand" else None
    prev = (arms[-1], fings[-1])
    qa, fa = _transition(prev, tail, _transition_frames(body, prev, tail, fps, rng, True, lead), lead)
    window = (np.concatenate([arms[-1][-2:], qa, tail[0]]), np.concatenate([fings[-1][-2:], fa, tail[1]]))
    if not _plausible(body, window[0], window[1], fps)[0]:
        return None
    arm = np.concatenate(arms + [qa, tail[0]])
    fingers = np.concatenate(fings + [fa, tail[1]])
    if not _MIN_FRAMES <= len(arm) <= _MAX_FRAMES:
        return None
    # every frame was checked in the overlapping windows above
    poses = [arm_fk(body, arm[:, s], fingers[:, s], side) for s, side in enumerate(("left", "right"))]
    T = len(arm)
    demo = Demonstration(
        fps=fps,
        arm_positions=np.stack([np.stack([p.shoulder, p.elbow, p.wrist], axis=1) for p in poses], axis=1),
        arm_mask=np.ones((T, 2, 3), dtype=bool),
        wrist_rotations=np.stack([p.wrist_rotation for p in poses], axis=1),
        wrist_mask=np.ones((T, 2), dtype=bool),
        finger_positions=np.stack([np.stack([p.finger_base, p.finger_tip], axis=2) for p in poses], axis=1),
        finger_mask=np.ones((T, 2, 5), dtype=bool),
        name=name,
        meta={
            "source": "nlo_lab synthetic sign corpus",
            "scenario": scenario,
            "split": SCENARIOS[scenario].split,
            "signer": signer.name,
            "dominant": signer.dominant,
            "body": asdict(signer.body),
            "signs": [s.gloss for s in signs],
            "sign_components": [s.as_dict() for s in signs],
            "sign_frames": ranges[1:],
            "seed": seed,
        },
    )
    return _Clip(demo, arm, fingers)

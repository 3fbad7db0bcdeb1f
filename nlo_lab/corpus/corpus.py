"""The embedded synthetic sign-language corpus: five scenarios of signed sentences.

Organised like the paper's data (the paper's data set): three training
scenarios and two test scenarios with the paper's sequence counts. Each scenario has its own
lexicon of glosses; a sequence is a sentence of 2-6 signs by one of ``N_SIGNERS`` synthetic
signers (:func:`nlo_lab.corpus.body.random_body`; one in four is left-handed), starting and
ending at the rest pose. Signs are solved with the analytic arm IK on the signer's body
(:mod:`nlo_lab.corpus.sign_motion`); transitions between signs (0.2-0.4 s, up to 0.6 s for the
longest moves) and to/from rest (0.4-0.9 s) are minimum-jerk in joint space, signs last 0.5-1.2 s
(:mod:`nlo_lab.corpus.generate`). Test signs use ``(handshape, location, movement)``
combinations that no training sign uses (:func:`nlo_lab.corpus.signs.is_test_combination`).

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
import functools
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from nlo_lab.corpus.body import random_body
from nlo_lab.corpus.generate import (
    CLEARANCE,
    ELBOW_CLEARANCE,
    FINGERTIP_ACCEL_LIMIT,
    HAND_CLEARANCE,
    WRIST_ACCEL_LIMIT,
    WRIST_SPEED_LIMIT,
    Clip,
    generate_sequence,
)
from nlo_lab.corpus.sign_motion import Signer
from nlo_lab.corpus.signs import Sign, random_sign
from nlo_lab.errors import DemonstrationError
from nlo_lab.human.demonstration import Demonstration

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
_MAX_ATTEMPTS = 40


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
    """The signs (gloss -> :class:`~nlo_lab.corpus.signs.Sign`) of one scenario."""
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


def _clip(name: str, seed: int) -> Clip:
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
def _generate(name: str, seed: int) -> Clip:
    """One sequence; each depends only on (seed, scenario, index), so clips are made on demand."""
    scenario, index = name.rsplit("_", 1)
    s_idx, i = _SCENARIO_ORDER.index(scenario), int(index)
    lexicon, signers = _lexicon(scenario, seed), _signers(seed)
    for attempt in range(_MAX_ATTEMPTS):
        rng = np.random.default_rng([seed, s_idx, i, attempt])
        clip = generate_sequence(name, scenario, SCENARIOS[scenario].split, lexicon, signers, rng, seed)
        if clip is not None:
            return clip
    raise DemonstrationError(f"no plausible sequence after {_MAX_ATTEMPTS} attempts", field=name)  # pragma: no cover


@functools.lru_cache(maxsize=32)
def _lexicon(scenario: str, seed: int) -> MappingProxyType:
    sc = SCENARIOS[scenario]
    rng = np.random.default_rng([seed, _SCENARIO_ORDER.index(scenario), 10_000])
    return MappingProxyType({g: random_sign(g, sc.split, rng) for g in sc.glosses})


@functools.lru_cache(maxsize=4)
def _signers(seed: int) -> tuple[Signer, ...]:
    rng = np.random.default_rng([seed, 20_000])
    signers = []
    for k in range(N_SIGNERS):
        rest = np.array([0.12, 0.10, 0.15, 0.40, 0.35, 0.15, 0.05]) + rng.uniform(-0.05, 0.05, 7)
        signers.append(
            Signer(
                name=f"signer_{k + 1}",
                body=random_body(rng),
                dominant="left" if k % 4 == 3 else "right",
                elbow_out=float(rng.uniform(0.35, 0.8)),
                speed=float(rng.uniform(0.85, 1.15)),
                rest=rest,
            )
        )
    return tuple(signers)



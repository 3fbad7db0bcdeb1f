"""The sign vocabulary of the synthetic corpus: handshapes, locations, palm orientations, movements, patterns.

A sign is ``(handshape(s), location, movement, two-handed pattern)`` plus a palm orientation
and a few size/timing parameters (:class:`Sign`). Positions are given in the *canonical*
frame of the dominant hand: the body frame of a right-handed signer (the dominant side is -Y).
A left-handed signer, and the non-dominant hand, use the mirror image (Y -> -Y); the angles of
:mod:`nlo_lab.corpus.arm_kinematics` mean the same on both sides, so mirrored targets give mirrored motion.

Held-out combinations: a ``(handshape, location, movement)`` triple belongs to the test split
when its ``(handshape, movement)`` pair is in ``HELD_OUT_PAIRS`` or a stable hash of the
triple says so (about one in five); the train scenarios use only train triples and the test
scenarios only test triples, so every test sign is a combination never seen in training.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from nlo_lab.corpus.body import BodyParams
from nlo_lab.errors import SettingsError

__all__ = [
    "HANDSHAPES",
    "LOCATIONS",
    "CONTACT_LOCATIONS",
    "PALMS",
    "MOVEMENTS",
    "PATTERNS",
    "HELD_OUT_PAIRS",
    "Sign",
    "minimum_jerk",
    "handshape",
    "location_point",
    "location_normal",
    "movement_path",
    "is_test_combination",
    "random_sign",
]

_D = np.pi / 180.0


def _shape(thumb, index, middle, ring, pinky) -> np.ndarray:
    """``(5, 4)`` [rad] from per-finger ``[flexion_1, spread_1, flexion_2, flexion_3]`` in degrees."""
    a = np.array([thumb, index, middle, ring, pinky], dtype=np.float64) * _D
    a.setflags(write=False)
    return a


_EXT = [0, 0, 0, 0]  # straight finger
_CURL = [85, 0, 100, 70]  # finger curled into the fist
_THUMB_OVER = [15, 20, 40, 80]  # thumb closed over the curled fingers (tuned on the body model)
_THUMB_OUT = [-15, 25, 0, 0]  # thumb stretched away from the hand
_THUMB_SIDE = [-5, 5, 5, 5]  # thumb alongside the index

# Finger angles of every handshape (thumb..pinky). The thumb angles of "O" and "pinch" were
# tuned on the body model so that the thumb tip meets the index tip (about 1.4 cm apart).
HANDSHAPES: dict[str, np.ndarray] = {
    "fist": _shape(_THUMB_OVER, _CURL, _CURL, _CURL, _CURL),
    "flat": _shape(_THUMB_SIDE, [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]),
    "spread": _shape(_THUMB_OUT, [0, 15, 0, 0], [0, 3, 0, 0], [0, 12, 0, 0], [0, 18, 0, 0]),
    "index": _shape(_THUMB_OVER, _EXT, _CURL, _CURL, _CURL),
    "V": _shape(_THUMB_OVER, [0, 12, 0, 0], [0, 8, 0, 0], _CURL, _CURL),
    "Y": _shape(_THUMB_OUT, _CURL, _CURL, _CURL, [0, 15, 0, 0]),
    "C": _shape([5, 45, 15, 15], [35, 0, 40, 25], [35, 0, 40, 25], [35, 0, 40, 25], [35, 0, 40, 25]),
    "O": _shape([25, 50, 35, 30], [45, 0, 50, 30], [45, 0, 50, 30], [45, 0, 50, 30], [45, 0, 50, 30]),
    "thumb_up": _shape([-10, 10, 0, 0], _CURL, _CURL, _CURL, _CURL),
    "pinch": _shape([20, 40, 20, 60], [50, 0, 55, 35], [0, 5, 0, 0], [0, 5, 0, 0], [0, 10, 0, 0]),
    "L": _shape(_THUMB_OUT, _EXT, _CURL, _CURL, _CURL),
    "I": _shape(_THUMB_OVER, _CURL, _CURL, _CURL, _EXT),
    "W": _shape([30, 50, 40, 60], [0, 12, 0, 0], [0, 3, 0, 0], [0, 10, 0, 0], _CURL),
    "claw": _shape([5, 45, 30, 40], [15, 15, 80, 60], [15, 3, 80, 60], [15, 12, 80, 60], [15, 18, 80, 60]),
    "bent": _shape(_THUMB_SIDE, [80, 0, 0, 0], [80, 0, 0, 0], [80, 0, 0, 0], [80, 0, 0, 0]),
}
RELAXED = _shape([10, 20, 10, 10], [20, 3, 25, 15], [22, 0, 28, 15], [25, -3, 30, 18], [28, -6, 32, 20])

LOCATIONS = ("neutral", "chest", "chin", "forehead", "shoulder", "side", "other_hand")
CONTACT_LOCATIONS = ("chest", "chin", "forehead", "shoulder")  # the hand touches the body there
PATTERNS = ("one_handed", "symmetric", "alternating", "base_hand")
MOVEMENTS = ("straight", "arc", "circle", "tap", "zigzag", "twist")

# Palm orientation presets: forearm pronation, wrist flexion, wrist deviation [rad].
PALMS: dict[str, tuple[float, float, float]] = {
    "medial": (0.05, 0.10, 0.05),  # thumb up, palm towards the midline
    "down": (1.15, 0.05, 0.10),
    "up": (-1.10, -0.10, 0.0),
    "oblique": (0.60, 0.25, 0.10),
}

# (handshape, movement) pairs that never occur in training: the test scenarios' novel signs.
HELD_OUT_PAIRS = frozenset(
    {("Y", "circle"), ("V", "zigzag"), ("O", "tap"), ("index", "twist"), ("C", "arc"), ("claw", "straight"), ("L", "tap")}
)


def minimum_jerk(tau: np.ndarray) -> np.ndarray:
    """The minimum-jerk time law ``10 t^3 - 15 t^4 + 6 t^5`` on ``[0, 1]`` (zero velocity and acceleration at both ends)."""
    t = np.clip(np.asarray(tau, dtype=np.float64), 0.0, 1.0)
    return t**3 * (10.0 + t * (-15.0 + 6.0 * t))


def handshape(name: str) -> np.ndarray:
    """``(5, 4)`` [rad] finger angles of a handshape (a copy)."""
    if name not in HANDSHAPES:
        raise SettingsError(f"unknown handshape {name!r}; expected one of {sorted(HANDSHAPES)}")
    return HANDSHAPES[name].copy()


@dataclass(frozen=True)
class Sign:
    """One lexical sign.

    Attributes:
        gloss: the word it means (upper case, e.g. ``"TICKET"``).
        handshape: start handshape (a key of ``HANDSHAPES``).
        location: a key of ``LOCATIONS``.
        movement: a key of ``MOVEMENTS``.
        pattern: a key of ``PATTERNS``.
        palm: a key of ``PALMS``.
        end_handshape: handshape at the end of the sign (``None`` = unchanged).
        base_handshape: handshape of the non-dominant hand for ``base_hand``.
        direction: ``(3,)`` unit direction of straight/arc/zigzag movements (canonical frame).
        amplitude: movement size [m] (radius of a circle, tap height, path length) or [rad] for twist.
        repetitions: number of taps, circles, zig-zags or twists.
    """

    gloss: str
    handshape: str
    location: str
    movement: str
    pattern: str
    palm: str = "medial"
    end_handshape: str | None = None
    base_handshape: str = "flat"
    direction: tuple[float, float, float] = (0.0, 0.0, -1.0)
    amplitude: float = 0.08
    repetitions: int = 1

    def __post_init__(self) -> None:
        checks = (
            ("handshape", self.handshape, HANDSHAPES),
            ("location", self.location, LOCATIONS),
            ("movement", self.movement, MOVEMENTS),
            ("pattern", self.pattern, PATTERNS),
            ("palm", self.palm, PALMS),
            ("base_handshape", self.base_handshape, HANDSHAPES),
        )
        for field, value, allowed in checks:
            if value not in allowed:
                raise SettingsError(f"Sign {self.gloss!r}: unknown {field} {value!r}; expected one of {sorted(allowed)}")
        if self.end_handshape is not None and self.end_handshape not in HANDSHAPES:
            raise SettingsError(f"Sign {self.gloss!r}: unknown end_handshape {self.end_handshape!r}")
        if (self.location == "other_hand") != (self.pattern == "base_hand"):
            raise SettingsError(f"Sign {self.gloss!r}: location 'other_hand' goes with pattern 'base_hand' and only with it")
        if not (0.0 < self.amplitude <= 1.0) or self.repetitions < 1:
            raise SettingsError(f"Sign {self.gloss!r}: amplitude must be in (0, 1] and repetitions >= 1")

    @property
    def combination(self) -> tuple[str, str, str]:
        """The ``(handshape, location, movement)`` triple that the train/test split is made on."""
        return (self.handshape, self.location, self.movement)

    def as_dict(self) -> dict:
        """JSON-friendly description (for ``Demonstration.meta``)."""
        return {
            "gloss": self.gloss,
            "handshape": self.handshape,
            "end_handshape": self.end_handshape,
            "location": self.location,
            "movement": self.movement,
            "pattern": self.pattern,
            "palm": self.palm,
        }


def location_point(name: str, body: BodyParams, bilateral: bool = False) -> np.ndarray:
    """``(3,)`` [m] target of the hand's knuckle centre at a location, canonical (right-hand) frame.

    Contact locations are placed a hand's thickness in front of the body; the corpus then
    pushes the hand further out if any finger point comes closer than its clearance.
    ``bilateral`` moves the point to the dominant side so that two mirrored hands do not meet.
    ``"other_hand"`` has no fixed point (it follows the base hand) and is rejected here.
    """
    reach = (body.upper_arm + body.forearm) / 0.56  # 1 for a mid-sized signer
    front = body.chest_depth / 2 + body.torso_center[0]
    head, r = body.head_center, body.head_radius
    lateral = -0.12 if bilateral else 0.0
    points = {
        "neutral": (0.31 * reach, -0.10 if not bilateral else -0.14, -0.20),
        "chest": (front + 0.07, -0.04 if not bilateral else -0.12, -0.15),
        "chin": (head[0] + 0.55 * r + 0.08, -0.02 + lateral, head[2] - 0.85 * r - 0.02),
        "forehead": (head[0] + 0.85 * r + 0.08, -0.02 + lateral, head[2] + 0.40 * r),
        "shoulder": (front + 0.06, (0.8 if not bilateral else -0.8) * body.shoulder_width / 2, -0.04),
        "side": (0.22 * reach, -0.30, -0.12),
    }
    if name not in points:
        raise SettingsError(f"location {name!r} has no fixed point; expected one of {sorted(points)}")
    return np.array(points[name], dtype=np.float64)


def location_normal(name: str) -> np.ndarray:
    """``(3,)`` unit direction pointing away from the body at a location (canonical frame)."""
    normals = {"chin": (1.0, 0.0, -0.3), "forehead": (1.0, 0.0, 0.2), "chest": (1.0, 0.0, 0.0), "shoulder": (1.0, 0.0, 0.2)}
    n = np.array(normals.get(name, (0.0, 0.0, 1.0)), dtype=np.float64)
    return n / np.linalg.norm(n)


def _perpendicular(d: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to ``d``, preferring up, then forward."""
    for c in (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])):
        p = c - c.dot(d) * d
        if np.linalg.norm(p) > 0.3:
            return p / np.linalg.norm(p)
    raise AssertionError("unreachable")  # pragma: no cover


def movement_path(sign: Sign, tau: np.ndarray, alternate: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Hand offsets of a sign's movement, canonical frame.

    Every path runs on the minimum-jerk phase ``s(tau)``, so it starts and ends at rest
    (zero velocity and acceleration) and joins the minimum-jerk transitions smoothly.

    Args:
        sign: the sign.
        tau: ``(n,)`` normalised time in ``[0, 1]``.
        alternate: the non-dominant hand of an ``alternating`` sign (half a cycle out of phase,
            or the opposite direction for straight/arc movements).

    Returns:
        ``(n, 3)`` [m] offsets of the knuckle centre from the location, ``(n,)`` [rad] extra pronation.
    """
    s = minimum_jerk(tau)[:, None]  # (n, 1)
    d = np.asarray(sign.direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    a, k = sign.amplitude, sign.repetitions
    phase = np.pi if alternate else 0.0
    twist = np.zeros(len(tau))
    away = location_normal(sign.location)
    if sign.movement == "straight":
        off = (-1.0 if alternate else 1.0) * d * a * s
    elif sign.movement == "arc":
        off = (-1.0 if alternate else 1.0) * d * a * s + _perpendicular(d) * 0.35 * a * np.sin(np.pi * s)
    elif sign.movement == "circle":
        u = _perpendicular(away)  # the circle lies in the plane facing away from the body
        v = np.cross(away, u)
        ang = 2 * np.pi * k * s + phase
        off = a * (u * (np.cos(ang) - np.cos(phase)) + v * (np.sin(ang) - np.sin(phase)))
    elif sign.movement == "tap":
        off = away * a * np.sin(np.pi * k * s + phase / 2) ** 2
    elif sign.movement == "zigzag":
        side = np.cross(d, _perpendicular(d))
        off = d * a * s + side * 0.25 * a * np.sin(2 * np.pi * k * s + phase)
    else:  # twist: the forearm turns, the hand stays
        off = np.zeros((len(tau), 3))
        twist = a * np.sin(2 * np.pi * k * s[:, 0] + phase)
    return off, twist


def is_test_combination(handshape_name: str, location: str, movement: str) -> bool:
    """True when the ``(handshape, location, movement)`` triple is reserved for the test split."""
    if (handshape_name, movement) in HELD_OUT_PAIRS:
        return True
    return zlib.crc32(f"{handshape_name}|{location}|{movement}".encode()) % 5 == 0


_DIRECTIONS = {
    "down": (0.0, 0.0, -1.0),
    "up": (0.0, 0.0, 1.0),
    "forward": (1.0, 0.0, 0.0),
    "out": (0.0, -1.0, 0.0),
    "in": (0.0, 1.0, 0.0),
    "forward_down": (0.7, 0.0, -0.7),
}
# Movement directions that keep a hand at a contact location off the body, and off the base hand.
_CONTACT_DIRECTIONS = ("down", "forward", "out", "forward_down")
_BASE_DIRECTIONS = ("forward", "out", "in", "up")


def random_sign(gloss: str, split: str, rng: np.random.Generator) -> Sign:
    """A random sign whose combination belongs to ``split`` (``"train"`` or ``"test"``)."""
    if split not in ("train", "test"):
        raise SettingsError(f"split must be 'train' or 'test', got {split!r}")
    names = sorted(HANDSHAPES)
    for _ in range(10000):
        pattern = str(rng.choice(PATTERNS, p=[0.4, 0.22, 0.16, 0.22]))
        if pattern == "base_hand":
            location = "other_hand"
        elif pattern == "one_handed":
            location = str(rng.choice([l for l in LOCATIONS if l != "other_hand"]))
        else:  # two mirrored hands: places where they do not meet
            location = str(rng.choice(["neutral", "chest", "shoulder", "side"]))
        movement = str(rng.choice(MOVEMENTS))
        shape = names[int(rng.integers(len(names)))]
        if is_test_combination(shape, location, movement) != (split == "test"):
            continue
        if location in CONTACT_LOCATIONS:
            choices = _CONTACT_DIRECTIONS
        elif pattern == "base_hand":
            choices = _BASE_DIRECTIONS
        else:
            choices = tuple(_DIRECTIONS)
        direction = _DIRECTIONS[str(rng.choice(choices))]
        if movement in ("straight", "arc"):
            amplitude = rng.uniform(0.06, 0.14)
        elif movement == "zigzag":
            amplitude = rng.uniform(0.06, 0.10)
        elif movement == "circle":
            amplitude = rng.uniform(0.03, 0.06)
        elif movement == "tap":
            amplitude = rng.uniform(0.02, 0.04)
        else:
            amplitude = rng.uniform(0.3, 0.6)
        repetitions = {"tap": int(rng.integers(2, 4)), "twist": int(rng.integers(1, 3)), "zigzag": 2}.get(movement, 1)
        end = str(rng.choice(names)) if rng.uniform() < 0.25 else None
        palm = str(rng.choice(["down", "oblique"])) if pattern == "base_hand" else str(rng.choice(list(PALMS)))
        base = str(rng.choice(["flat", "fist", "bent"]))
        return Sign(gloss, shape, location, movement, pattern, palm, end, base, direction, float(amplitude), repetitions)
    raise AssertionError("no sign combination found")  # pragma: no cover

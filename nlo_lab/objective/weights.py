"""The weights of the objective's terms, and the constants of the smoothness term."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields

from nlo_lab.errors import SettingsError
from nlo_lab.settings import HANDSHAPE_WEIGHTS, WEIGHT_RANGE, check_range, validate_fields

__all__ = [
    "LossWeights",
    "TERMS",
    "COLLISION_FORMS",
    "CONTACT_SCALE",
    "SMOOTH_SPEED_CAP",
    "SMOOTH_MAX_STEP",
    "SMOOTH_STEP_WIDTH",
    "HAND_TERMS",
    "HAND_STAGE_TERMS",
    "PINCH_ON",
    "PINCH_OFF",
]

TERMS = ("ee", "ori", "elbow", "finger", "collision", "tip", "thumb", "pinch", "tip_dir", "finger_dir", "thumb_gap")  # the per-frame terms, in the order Objective returns them
HAND_TERMS = ("tip", "thumb", "pinch", "tip_dir", "finger_dir", "thumb_gap")  # the handshape terms (issue 27): zero on a robot without fingers
# The direction terms and the thumb gap weigh the pipeline's hand stage (nlo_lab.inference.hand_stage), not its latent
# optimisation: the direction terms pulled through the decoder (whose hands move with the whole latent) gave up the
# thumb and the pinch (benchmarks/hands.py on the shipped yumi.pt, 2026-11-26: thumb 26.5 -> 31.9 deg, pinch r
# 0.787 -> 0.763).
HAND_STAGE_TERMS = ("tip_dir", "finger_dir", "thumb_gap")
COLLISION_FORMS = ("hinge", "paper")  # see nlo_lab.objective.terms.collision_loss
# [m] the hinge's length unit for a capsule pair with margin 0 (contact allowed, penetration costs):
# 1 mm of penetration costs what 1 mm inside a YuMi pair's 5 mm margin does
CONTACT_SCALE = 0.005
# A joint faster than this [rad/s] is smoothed as if its limit were this: NAO's wrist
# (24.6 rad/s) could otherwise jump 0.85 rad between two frames at little cost, though
# a jump is jitter whatever the motor (measured: docs/RESULTS.md, "Robot-ready motion").
SMOOTH_SPEED_CAP = math.pi
SMOOTH_MAX_STEP = 0.35  # [rad] a joint step beyond this between two frames costs steeply ...
SMOOTH_STEP_WIDTH = 0.02  # [rad] ... (one more width: one more unit, squared)
# The pinch term acts while the human's thumb tip and a fingertip are closer than PINCH_OFF hand
# lengths (fully below PINCH_ON, fading in between); MediaPipe's tip landmarks of a thumb and a
# finger that touch are 0.15-0.3 hand lengths apart (the fingers' thickness).
PINCH_ON = 0.3
PINCH_OFF = 0.6


@dataclass(frozen=True)
class LossWeights:
    """Weights of the objective's terms (defaults: the paper's; the hand terms ``tip``, ``thumb``, ``pinch``
    are ours, measured by ``benchmarks/hands.py``).

    Attributes:
        ee: end-effector position term.
        ori: wrist orientation term.
        elbow: elbow -> wrist direction term.
        finger: finger base -> tip direction term.
        collision: self-collision term.
        tip: wrist -> fingertip vectors in the wrist frame, scaled from the human's hand to the robot's
            (:func:`~nlo_lab.objective.terms.fingertip_loss`; not in the paper).
        thumb: thumb tip -> other fingertip directions in the wrist frame (:func:`~nlo_lab.objective.terms.thumb_loss`).
        pinch: a human pinch (thumb and fingertip touching) draws the robot's tips together
            (:func:`~nlo_lab.objective.terms.pinch_loss`).
        tip_dir: wrist -> fingertip directions in the wrist frame (:func:`~nlo_lab.objective.terms.fingertip_direction_loss`).
        finger_dir: finger base -> tip directions in the wrist frame (:func:`~nlo_lab.objective.terms.finger_direction_loss`).
        thumb_gap: thumb tip -> fingertip distances matched both ways in every frame (:func:`~nlo_lab.objective.terms.thumb_gap_loss`).
            ``tip_dir``, ``finger_dir`` and ``thumb_gap`` (``HAND_STAGE_TERMS``) weigh the pipeline's hand stage; its latent
            optimisation runs :meth:`latent_stage` (them at 0). Called directly, ``Objective`` counts them.
        latent: weight of ``||z||²`` (``1/σ²``, σ = 1 in the paper).
        smooth: weight of the joint-speed term over consecutive frames
            (:func:`~nlo_lab.objective.terms.smoothness_loss`; not in the paper; 0 = frames independent).
    """

    ee: float = 1000.0
    ori: float = 100.0
    elbow: float = 100.0
    finger: float = 100.0
    collision: float = 1000.0
    latent: float = 1.0
    smooth: float = 10.0
    # the hand terms' weights, measured by benchmarks/hands.py (2026-11-26, shipped yumi.pt): tip/thumb/pinch
    # 2000/500/300 against 1000/300/100 lowered all four hand errors (wrist->tip 18.6 -> 18.3 deg, thumb 26.6 ->
    # 25.2 deg, pinch r 0.78 -> 0.79, base->tip 37.9 -> 37.6 deg) with Table I's robot-ready mean at 0.0972 m (0.0975)
    tip: float = 2000.0
    thumb: float = 500.0
    pinch: float = 300.0
    # the hand stage's weights, measured on benchmarks/hands.py's recordings (2026-11-26, shipped yumi.pt, 30 stage steps
    # after the latent optimisation, before the stage's speed clamp; wrist->tip / thumb / base->tip [deg] / pinch r): none of the three 18.4 / 26.6 /
    # 37.8 / 0.787; tip_dir 4000, finger_dir 1000: 17.4 / 26.3 / 33.1 / 0.785; + thumb_gap 1000: 17.4 / 26.3 / 33.2 /
    # 0.804 (3000: 17.5 / 26.8 / 33.5 / 0.834); tip_dir 8000: 17.3 / 26.0 / 35.1 / 0.804.
    # Again with tip_dir's chord form and the stage of 60 steps of 0.03 rad, speed clamp included (same recordings and
    # order): these defaults 17.05 / 25.34 / 33.79 / 0.813; tip_dir 6000: 16.95 / 24.91 / 35.34 / 0.812 (+ finger_dir
    # 1500: 16.97 / 26.11 / 33.66 / 0.813); thumb_gap 2000: 17.11 / 25.39 / 33.89 / 0.817; tip 0 in the stage: 17.07 /
    # 25.48 / 33.70 / 0.814. No set of these weights gets wrist->tip below dex-retargeting's 16.57 (docs/RESULTS.md,
    # "Handshapes"; nlo_lab.inference.hand_stage says where the stage stops): the start's basin holds the one-motor
    # fingers. With the stage's default finger search (OptimizeSettings.hand_search: middle, ring, little) tip_dir acts;
    # on the eight recordings of benchmarks/hands.py (2026-11-28, benchmarks/hands_levers.py; wrist->tip / thumb /
    # base->tip [deg] / pinch r, the clips retimed [s]; dex-retargeting's best 15.84 / 30.16 / 32.41 / 0.771):
    # tip_dir 4000 16.08 / 27.24 / 30.84 / 0.815, 39.83 s; 6000 (finger_dir 2000) 16.00 / 28.66 / 30.57 / 0.773;
    # 6500 15.54 / 29.66 / 31.54 / 0.786; 7000 15.47 / 29.85 / 31.63 / 0.782, 39.57 s; 7500 15.44 / 30.00 / 31.72 /
    # 0.780; 8000 15.52 / 30.48 / 31.23 / 0.776 (the thumb behind); 7000 without the search 15.83 / 27.88 / 32.50 / 0.781.
    tip_dir: float = 7000.0
    finger_dir: float = 1000.0
    thumb_gap: float = 1000.0

    def __post_init__(self) -> None:
        validate_fields(self, lambda name, v: check_range(name, v, *WEIGHT_RANGE), prefix="loss weight ")

    @classmethod
    def paper(cls) -> LossWeights:
        """The paper's objective: its five terms and the latent prior, frames independent (``smooth=0``) and
        without our hand terms (``HAND_TERMS`` = 0). Table I's paper mode, Table II, III, the
        departures and the headroom benchmark optimise and train on it."""
        return cls(smooth=0.0, **{name: 0.0 for name in HAND_TERMS})

    @classmethod
    def handshape(cls) -> LossWeights:
        """The handshape preset's weights: the defaults with the wrist->fingertip directions (``tip_dir``) at 8000, the
        thumb->fingertip directions (``thumb``) at 800 and the finger base->tip directions (``finger_dir``) at 2000, for
        a hand stage that searches its one-actuator fingers (:meth:`OptimizeSettings.handshape
        <nlo_lab.inference.OptimizeSettings.handshape>`; ``nlo-lab retarget --handshape``). Without the search the
        descent stays where the latent optimisation leaves those fingers and these weights change little
        (``benchmarks/hands.py`` measures both: docs/RESULTS.md, "Handshapes")."""
        return cls(**HANDSHAPE_WEIGHTS)

    @classmethod
    def from_string(cls, text: str, base: LossWeights | None = None) -> LossWeights:
        """Parse ``"ee=1000,ori=100"``; unnamed weights keep ``base``'s (default: the defaults).

        Raises:
            SettingsError: naming the bad key or value.
        """
        names = {f.name for f in fields(cls)}
        values: dict[str, float] = {}
        for item in (part.strip() for part in text.split(",")):
            if not item:
                continue
            key, sep, raw = item.partition("=")
            key = key.strip()
            if not sep:
                raise SettingsError(f"weight {item!r} is not KEY=VALUE (keys: {', '.join(sorted(names))})")
            if key not in names:
                raise SettingsError(f"unknown weight {key!r}; expected one of {', '.join(sorted(names))}")
            if key in values:
                raise SettingsError(f"weight {key!r} given twice")
            try:
                values[key] = float(raw)
            except ValueError:
                raise SettingsError(f"weight {key}={raw.strip()!r} is not a number") from None
        return dataclasses.replace(base, **values) if base is not None else cls(**values)

    def latent_stage(self) -> LossWeights:
        """These weights without the hand stage's terms (``HAND_STAGE_TERMS`` at 0): what the pipeline's latent optimisation runs."""
        return dataclasses.replace(self, **{name: 0.0 for name in HAND_STAGE_TERMS})

    def as_dict(self) -> dict[str, float]:
        """``{name: weight}``."""
        return dataclasses.asdict(self)

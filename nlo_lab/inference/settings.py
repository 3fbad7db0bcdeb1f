"""What the optimisers are told: start, budget, step rule, step size, collision form.

Step rule and budget. A recording, its frames coupled by the smoothness term (the pipeline's
default), is optimised by 40 steps of Rprop (:class:`~nlo_lab.inference.descent.Rprop`: each latent
coordinate's step grows by 1.2 while its gradient's sign holds, halves where it flips, first step
0.005, at most 0.1); frames optimised independently (a frame alone, the paper's objective) by Adam,
at most ``iterations`` steps with the patience stop (the paper's: 100 steps of 0.01, patience 5,
:meth:`OptimizeSettings.paper`). The paper's Adam moves every latent coordinate by about ``lr`` per
step; an arm that must travel out of a self-collision then takes the whole budget (the 170-frame
recording ``mediapipe_right_hand_170f``: YuMi's right upper arm in its forearm over 107 frames,
still paying at step 100). Rprop's steps grow geometrically where the way is long. Measured
(2026-11-26, shipped yumi.pt, ``LossWeights()``; mean latent loss of ``holistic_both_hands_47f`` /
``holistic_world_97f`` / ``mediapipe_right_hand_170f``): Adam 0.005, 100 steps 9798 / 2452 / 2863; Rprop
30 steps 9491 / 2404 / 2789, 40 steps 8746 / 2338 / 2768. Table I, robot-ready mode (YuMi, 25 test
sequences; mean Fréchet, sequences with a self-collision, largest slowdown): Adam 100 steps, patience
5: 0.0863 m, 2, 1.31; Rprop 40: 0.0885 m, 0, 1.29 (30: 0.0911 m, 1; 50: 0.0868 m, 0; 100: 0.0846 m, 0);
NAO 0.0456 m with either, Pepper 0.0708 -> 0.0693 m. ``benchmarks/motion.py``, YuMi: self-collision frames
56 -> 0, largest joint step 0.834 -> 0.596 rad. The hand measures of ``benchmarks/hands.py`` (wrist->tip,
thumb, base->tip [deg], pinch r) after the hand stage: Adam 17.03 / 25.42 / 33.83 / 0.813 (at lr 0.0045 or
0.0055: 17.08 / 25.32 / 33.89 / 0.812, 17.05 / 25.07 / 33.90 / 0.808); Rprop 40: 17.16 / 25.24 / 34.13 /
0.807 (the stage's patience ends it after 10 steps on ``holistic_both_hands_47f``). Rprop's loss rises
for up to ~20 evaluations once its steps have grown, before it falls below its earlier best: a
patience stop would end it there, so Rprop runs its whole budget (the best point is kept).

Adam's step size: ``lr = 0.01`` on ``z`` (:data:`PAPER_LR`). Measured on 4 clips of the
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
from nlo_lab.human.demonstration import FINGERS
from nlo_lab.inference.descent import STEPPERS
from nlo_lab.objective import COLLISION_FORMS
from nlo_lab.settings import (
    HAND_SEARCH,
    HANDSHAPE_SEARCH,
    HANDSHAPE_SLOWDOWN,
    ITERATIONS_RANGE,
    LATENT_ITERATIONS,
    PATIENCE_RANGE,
    RATE_RANGE,
    SEARCH_GRID,
    SEED_RANGE,
    SLOWDOWN_RANGE,
    check_bool,
    check_choice,
    check_int,
    check_range,
)

__all__ = [
    "INITS",
    "PAPER_LR",
    "SMOOTH_LR",
    "RPROP_LR",
    "PAPER_ITERATIONS",
    "PAPER_PATIENCE",
    "JOINT_INITS",
    "JOINT_LIMITS",
    "OptimizeSettings",
    "JointOptimizeSettings",
    "HAND_SEARCH",
    "HANDSHAPE_SEARCH",
    "HANDSHAPE_SLOWDOWN",
]

INITS = ("encoder", "random", "train-stats", "zeros")
PAPER_LR = 0.01  # Adam step on z, frames independent (module docstring)
SMOOTH_LR = 0.005  # the same with the smoothness term coupling the frames
RPROP_LR = 0.005  # Rprop's first step on z (it then adapts per coordinate)
PAPER_ITERATIONS, PAPER_PATIENCE = 100, 5  # the paper's budget and early stop (Adam)
JOINT_INITS = ("neutral", "midpoint", "zeros")
JOINT_LIMITS = ("clamp", "penalty")


@dataclass(frozen=True)
class OptimizeSettings:
    """Settings of latent optimisation.

    Attributes:
        init: initial latent: ``"encoder"`` (neural initialisation), ``"random"``
            (N(0, latent_sigma²)), ``"train-stats"`` (N(mean, std²) of the
            training latents) or ``"zeros"``.
        iterations: the budget: steps of the step rule (>= 0; 0 = the start point); default
            40 (``nlo_lab.settings.LATENT_ITERATIONS``), the paper's 100 in :meth:`paper`.
        patience: Adam's early stop: after this many evaluations without improvement (the hand
            stage's too); Rprop runs its whole budget (module docstring).
        lr: the first step on ``z``; None: Adam :data:`PAPER_LR` (0.01) when the frames are
            independent, :data:`SMOOTH_LR` (0.005) with the smoothness term; Rprop :data:`RPROP_LR` (0.005).
        latent_sigma: σ of the random initialisation.
        warm_start: in :func:`~nlo_lab.inference.optimize_stream`, frame t starts from frame
            t-1's best z; in :func:`~nlo_lab.inference.optimize_latent` with smoothing on, the
            start latents are chosen along the sequence (:func:`~nlo_lab.inference.sequence_start`).
        warm_window: how many neighbours on each side a frame may borrow its start
            latent from in :func:`~nlo_lab.inference.sequence_start` (0 = its own only).
        seed: seed of the random initialisations.
        collision_form: ``"hinge"`` or ``"paper"`` (see :func:`nlo_lab.objective.collision_loss`).
        stepper: the step rule, ``"rprop"`` or ``"adam"`` (:data:`~nlo_lab.inference.descent.STEPPERS`);
            None: Rprop when the smoothness term couples the frames (a recording through the pipeline),
            Adam otherwise (a frame alone, the paper's objective); see :meth:`step_rule`.
        hand_iterations: Adam steps of the hand stage after the latent optimisation of a recording
            (:func:`~nlo_lab.inference.hand_stage.refine_hands`: the hand joints alone on the same
            objective, of the hands the recording shows: a hand never seen keeps the latent optimisation's
            joints; 0 = none; robots without hand joints skip it).
        hand_lr: its step [rad].
        hand_search: fingers (names of :data:`~nlo_lab.human.FINGERS`) whose own joints the hand stage first
            searches along the whole clip (``hand_grid`` values of each, every step within the speed clamp's caps,
            by the objective), before its Adam steps: a finger of one actuator (the Inspire hand's) has two basins,
            curled and half open, and the descent stays in the one it starts in (``nlo_lab.inference.hand_stage``).
            None (the default): the fingers of :data:`HAND_SEARCH` (middle, ring, little) that the robot's hands
            move alone, none on a robot without hand joints; ``()``: no search. With the default ``tip_dir`` weight
            this is what puts the hands ahead of dex-retargeting on all four handshape measures (``docs/RESULTS.md``,
            "Handshapes"); the index is left out, searched it opens and the thumb-index distance loses the human's
            course (the pinch). :data:`HANDSHAPE_SEARCH` (with :data:`HANDSHAPE_SLOWDOWN`: :meth:`handshape`) and
            :meth:`LossWeights.handshape <nlo_lab.objective.LossWeights.handshape>` are the handshape preset.
        hand_grid: values per searched joint.
        hand_slowdown: how much longer than the latent optimisation's the hand stage may make each segment of the
            retimed trajectory (its speed clamp's caps times this; :func:`~nlo_lab.inference.hand_stage.step_caps`).
            1 (the default): the hands never make the robot slower than the latent optimisation's output; the
            handshape preset (:meth:`handshape`) takes :data:`HANDSHAPE_SLOWDOWN`.
    """

    init: str = "encoder"
    iterations: int = LATENT_ITERATIONS
    patience: int = PAPER_PATIENCE
    lr: float | None = None
    latent_sigma: float = 1.0
    warm_start: bool = True
    warm_window: int = 2
    seed: int = 0
    collision_form: str = "hinge"
    stepper: str | None = None
    # the hand stage's steps, measured by benchmarks/hands.py (2026-11-26, shipped yumi.pt, the chord tip_dir): 30 of
    # 0.05 rad left wrist->tip / thumb / base->tip [deg] / pinch r at 17.26 / 27.06 / 34.30 / 0.790, 60 of 0.03 at
    # 17.05 / 25.33 / 33.79 / 0.813 (100 of 0.03: 17.01 / 25.14 / 33.73 / 0.815; 0.05 rad oscillates around its best).
    # Fewer steps cost every measure (replayed on the latent optimisation's outputs, then 100 Adam steps, 2026-11-26 14:05
    # UTC): 40 of 0.04 17.20 / 26.75 / 34.16 / 0.798, 45 of 0.035 17.18 / 26.29 / 34.12 / 0.802; Rprop (first step 0.02
    # rad, at most 0.05) 30 steps 17.12 / 26.12 / 34.28 / 0.830, 60 steps 16.98 / 25.50 / 34.05 / 0.816 with one
    # hand-frame into self-collision; scipy's L-BFGS-B, the limits as bounds, 15 iterations 17.59 / 24.69 / 36.14 / 0.839,
    # slower per call. From the 40 Rprop steps' latents (14:30 UTC): 60 of 0.03 17.16 / 25.24 / 34.13 / 0.807, 40 of 0.03
    # 17.23 / 25.41 / 34.33 / 0.805, 30 of 0.03 17.33 / 25.54 / 34.69 / 0.807, 60 of 0.02 17.15 / 24.83 / 34.02 / 0.808,
    # 80 of 0.02 17.12 / 24.66 / 33.89 / 0.810 (0.02 runs every step on the 47-frame clip, where 0.03's patience stops
    # after 10).
    hand_iterations: int = 60
    hand_lr: float = 0.03
    hand_search: tuple[str, ...] | None = None
    hand_grid: int = SEARCH_GRID
    hand_slowdown: float = 1.0

    def __post_init__(self) -> None:
        if self.init not in INITS:
            raise SettingsError(f"unknown init {self.init!r}; expected one of {', '.join(INITS)}")
        check_int("iterations", self.iterations, *ITERATIONS_RANGE)
        check_int("patience", self.patience, *PATIENCE_RANGE)
        check_int("seed", self.seed, *SEED_RANGE)
        check_int("warm_window", self.warm_window, 0, 1000)
        check_int("hand_iterations", self.hand_iterations, *ITERATIONS_RANGE)
        object.__setattr__(self, "hand_lr", check_range("hand_lr", self.hand_lr, *RATE_RANGE))
        if self.hand_search is not None:  # None: the robot's default (HAND_SEARCH), resolved by the pipeline
            if not isinstance(self.hand_search, (tuple, list)) or not all(isinstance(f, str) for f in self.hand_search):
                raise SettingsError(f"hand_search must be a sequence of finger names or None, got {self.hand_search!r}")
            object.__setattr__(self, "hand_search", tuple(self.hand_search))
            for finger in self.hand_search:
                check_choice("hand_search finger", finger, FINGERS)
            twice = sorted({f for f in self.hand_search if self.hand_search.count(f) > 1})
            if twice:  # a second pass over a finger only repeats the first's search
                raise SettingsError(f"hand_search names {', '.join(twice)} more than once")
        check_int("hand_grid", self.hand_grid, 2, 256)
        object.__setattr__(self, "hand_slowdown", check_range("hand_slowdown", self.hand_slowdown, *SLOWDOWN_RANGE))
        if self.lr is not None:
            object.__setattr__(self, "lr", check_range("lr", self.lr, *RATE_RANGE))
        object.__setattr__(self, "latent_sigma", check_range("latent_sigma", self.latent_sigma, *RATE_RANGE))
        object.__setattr__(self, "warm_start", check_bool("warm_start", self.warm_start))
        check_choice("collision_form", self.collision_form, COLLISION_FORMS)
        if self.stepper is not None:
            check_choice("stepper", self.stepper, STEPPERS)

    @classmethod
    def paper(cls, **overrides) -> OptimizeSettings:
        """The paper's optimisation: 100 Adam steps with patience 5 (lr 0.01 on the paper's objective,
        whose frames are independent); ``overrides`` as the fields."""
        return cls(**{"iterations": PAPER_ITERATIONS, "patience": PAPER_PATIENCE, "stepper": "adam", **overrides})

    @classmethod
    def handshape(cls, **overrides) -> OptimizeSettings:
        """The handshape preset's settings (with :meth:`LossWeights.handshape <nlo_lab.objective.LossWeights.handshape>`,
        ``nlo-lab retarget --handshape``): the hand stage first searches :data:`HANDSHAPE_SEARCH` and may stretch each
        retimed segment :data:`HANDSHAPE_SLOWDOWN` times; ``overrides`` as the fields."""
        return cls(**{"hand_search": HANDSHAPE_SEARCH, "hand_slowdown": HANDSHAPE_SLOWDOWN, **overrides})

    def step_rule(self, coupled: bool) -> tuple[str, float, int]:
        """``(stepper, first step, patience)`` for frames ``coupled`` by the smoothness term or not."""
        stepper = self.stepper or ("rprop" if coupled else "adam")
        if stepper == "rprop":
            return stepper, self.lr if self.lr is not None else RPROP_LR, ITERATIONS_RANGE[1] + 1
        return stepper, self.lr if self.lr is not None else (SMOOTH_LR if coupled else PAPER_LR), self.patience


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

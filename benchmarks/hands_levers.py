"""What-if levers of the hand stage on ``benchmarks/hands.py``'s recordings: the handshape measures after one change.

    python benchmarks/hands_levers.py [--no-video] [--corpus N] [--dex] [RUN ...]

A diagnostic for issue 27, not a method: ``nlo_lab.inference.hand_stage``'s docstring quotes its runs. Each RUN is a
string of levers separated by spaces ("" or none at all: the pipeline as it is); each retargets every recording with
the pipeline (shipped ``yumi.pt``, default weights and settings but for the levers) and prints one row: wrist->tip,
thumb->tips, base->tip [deg], pinch r (``nlo_lab.evaluation.hands``), the wrist->tip error of each finger (thumb ..
little), and the retimed duration summed over the clips (the speed clamp's price). The levers:

* ``weight:NAME=V``: a :class:`~nlo_lab.objective.LossWeights` field; ``setting:NAME=V``: an
  :class:`~nlo_lab.inference.OptimizeSettings` field;
* ``finger:KIND=t,i,m,r,l``: the hand term KIND (``tip``, ``tip_dir``, ``finger_dir``) weighed per finger, five factors
  on its weight; ``pair:KIND=i,m,r,l``: a thumb pair term (``thumb``, ``pinch``, ``thumb_gap``) per other finger;
* ``pinch-scale=C``: the pinch and the thumb gap draw each thumb-finger distance to C times the human's (never below
  the pair's floor) instead of the human's (the robot's thumb opens less far from its fingers than a human's);
* ``search=JOINTS``: before the hand stage, each named hand joint (``thumb_yaw``, ``thumb_pitch``, ``index``,
  ``middle``, ``ring``, ``pinky``; of every hand the clip shows, in the order given) set frame by frame to the best of
  ``grid=G`` values (default 16) by the objective (all terms, the others joints as they are);
  ``path=JOINTS``: the same along the whole clip, each step within the speed clamp's cap (dynamic programming,
  ``nlo_lab.inference.hand_stage.path_within_caps``; the library's own search, ``setting:hand_search=FINGERS``, keeps a
  column's start where the path costs more and leaves the smoothness term out of its table);
* ``thumb-gate=F``: a handshape-dependent thumb: the thumb's wrist->tip direction item (``tip_dir``) masked in the frames
  where its hand pinches (the largest pinch activation of its thumb pairs at least ``thumb-gate-on=A``, default 0.5),
  F times its weight elsewhere (pinching frames ask the pinch, open frames the direction);
* ``caps=X``: the hand stage's speed clamp with X times its caps. The caps stay the latent optimisation's (a
  searched start does not loosen them).

The data: ``benchmarks/hands.py``'s recordings (and the video unless ``--no-video``; with ``--recordings chosen`` only those
the handshape preset was chosen on, ``added`` only the four added after that choice), or with ``--corpus N`` the first N
clips of the synthetic corpus's test split that show a hand (``nlo_lab.corpus.sign_corpus("test")``: held out from the
checkpoints' training and from the levers' tuning, a check that a lever does not fit the recordings alone). ``--dex``
adds dex-retargeting's two variants on the same data (``benchmarks/hands.py``'s configs and runner, ``.venv-bench``).

It swaps nlo_lab internals for the run (``HandTerms``' constructor and ``build``, the pipeline's ``refine_hands``,
the hand stage's ``step_caps``) and puts them back. Prints a table; writes nothing.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import warnings
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from hands import DEX_PYTHON, added_after_choice, corpus_items, dex_scores, recordings  # noqa: E402

import nlo_lab.inference.hand_stage as hand_stage  # noqa: E402
import nlo_lab.pipeline as pipeline  # noqa: E402
from nlo_lab.evaluation.hands import HandScores, hand_frames_mask, hand_scores  # noqa: E402
from nlo_lab.inference import FastPaths, OptimizeSettings  # noqa: E402
from nlo_lab.inference.hand_stage import path_within_caps  # noqa: E402
from nlo_lab.model import load_pretrained  # noqa: E402
from nlo_lab.objective import LossWeights, Objective, point_plan  # noqa: E402
from nlo_lab.objective.numpy_backend import HandTerms  # noqa: E402
from nlo_lab.robot import load_robot  # noqa: E402

FINGER_KINDS = {"tip": 0, "tip_dir": 2, "finger_dir": 3}  # HandTerms' kind of each per-finger term
PAIR_KINDS = ("thumb", "pinch", "thumb_gap")
JOINTS = {"thumb_yaw": "thumb_proximal_yaw", "thumb_pitch": "thumb_proximal_pitch", "index": "index_proximal",
          "middle": "middle_proximal", "ring": "ring_proximal", "pinky": "pinky_proximal"}


class Levers:
    """One run's levers (the module's docstring); all neutral by default."""

    def __init__(self) -> None:  # a plain class: tests load this script by its path, where dataclasses cannot
        self.weights: dict = {}
        self.settings: dict = {}
        self.finger: dict = {}  # kind -> (5,) factors, thumb..little
        self.pair: dict = {}  # kind -> (4,) factors, index..little
        self.pinch_scale = 1.0
        self.search: tuple = ()
        self.path: tuple = ()
        self.grid = 16
        self.caps = 1.0
        self.thumb_gate = 0.0  # 0: off
        self.thumb_gate_on = 0.5

    @classmethod
    def parse(cls, text: str) -> Levers:
        out = cls()
        for lever in text.split():
            key, _, value = lever.partition("=")
            kind, _, name = key.partition(":")
            if kind == "weight":
                out.weights[name] = float(value)
            elif kind == "setting":
                kind_of = tuple if name == "hand_search" else type(getattr(OptimizeSettings(), name))  # None: the default
                out.settings[name] = tuple(x for x in value.split(",") if x) if kind_of is tuple else kind_of(value)
            elif kind == "finger" and name in FINGER_KINDS:
                out.finger[name] = np.array([float(x) for x in value.split(",")])
            elif kind == "pair" and name in PAIR_KINDS:
                out.pair[name] = np.array([float(x) for x in value.split(",")])
            elif key == "pinch-scale":
                out.pinch_scale = float(value)
            elif key in ("search", "path"):
                setattr(out, key, tuple(value.split(",")))
            elif key in ("thumb-gate", "thumb-gate-on"):
                setattr(out, key.replace("-", "_"), float(value))
            elif key in ("grid", "caps"):
                setattr(out, key, type(getattr(out, key))(value))
            else:
                raise SystemExit(f"unknown lever {lever!r} (see the docstring: python benchmarks/hands_levers.py --help)")
        for name, factors in (*out.finger.items(), *out.pair.items()):
            if len(factors) != (5 if name in FINGER_KINDS else 4) or (factors <= 0).any():
                raise SystemExit(f"{name}: {len(factors)} factors; give one positive factor per finger")
        if out.thumb_gate < 0 or not 0 < out.thumb_gate_on <= 1:
            raise SystemExit("thumb-gate: a factor >= 0 (0: off); thumb-gate-on: an activation in (0, 1]")
        if out.thumb_gate and "pinch" in out.pair:
            raise SystemExit("thumb-gate reads the pinch's activation, which pair:pinch scales: use one of them")
        unknown = [j for j in (*out.search, *out.path) if j not in JOINTS]
        if unknown:
            raise SystemExit(f"unknown hand joints {unknown}; known: {', '.join(JOINTS)}")
        return out


@contextlib.contextmanager
def applied(robot, levers: Levers):
    """The levers swapped into nlo_lab for the duration (see the module's docstring); the originals back after."""
    plan = point_plan(robot, robot.lower_limits.dtype)
    side, finger = plan.finger_side.numpy(), plan.finger_index.numpy()
    one_side = finger[side == side[0]]
    if not all(np.array_equal(finger[side == s], one_side) for s in np.unique(side)):
        raise SystemExit("the per-finger levers need both hands' fingers in one order")
    pair_finger = finger[plan.thumb_pairs[:, 1].numpy()] - 1  # 0 index .. 3 little
    floor = plan.pinch_floor().numpy()
    tips = np.arange(*plan.rows["finger_tip"].indices(plan.vectors.shape[0]))
    thumb_tips = tips[finger == 0]  # the thumbs' tip points (HandTerms' plus point of their items)
    init, build, refine, caps = HandTerms.__init__, HandTerms.build.__func__, pipeline.refine_hands, hand_stage.step_caps

    def order(n, full, half):  # the items of one kind: every finger (both hands) or one hand's (a hand never seen)
        return full if n == len(full) else half[:n]

    def new_init(self, *args, **kwargs):  # every construction (build, observed, compact_terms) from unscaled inputs
        init(self, *args, **kwargs)
        kinds = self.kind.argmax(1)
        for name, factors in levers.finger.items():
            items = np.flatnonzero(kinds == FINGER_KINDS[name])
            self.kind[items, FINGER_KINDS[name]] *= factors[order(len(items), finger, one_side)]
        pairs = np.flatnonzero(kinds == 1)
        if levers.thumb_gate:  # the thumb's tip_dir items: masked where its hand pinches, x thumb_gate elsewhere
            thumbs = np.flatnonzero((kinds == 2) & np.isin(self.plus, thumb_tips))  # by point: a masked-out item is dropped
            self.mask = self.mask.copy()  # the caller's array stays as it was
            for i in thumbs:
                own = self.side[pairs] == self.side[i]  # the thumb pairs of this thumb's hand
                pinching = self.pinch_weight[:, pairs[own] - pairs[0]].max(1) if own.any() else np.zeros(len(self.mask))
                self.mask[:, i, 0] = self.mask[:, i, 0] * (pinching < levers.thumb_gate_on)
            self.mask_planes = np.ascontiguousarray(self.mask[:, None, :, 0])
            self.kind[thumbs, 2] *= levers.thumb_gate
        if "thumb" in levers.pair:
            self.kind[pairs, 1] *= levers.pair["thumb"][order(len(pairs), pair_finger, pair_finger[: len(pair_finger) // 2])]
        if "thumb_gap" in levers.pair:
            J = self.pair_mask.shape[1]
            factors = levers.pair["thumb_gap"][order(J, pair_finger, pair_finger[: len(pair_finger) // 2])]
            self.pair_mask = self.pair_mask * factors.astype(self.pair_mask.dtype)  # the terms' own dtype

    def new_build(cls, *args, **kwargs):  # once per objective: what the later constructions copy as it is
        out = build(cls, *args, **kwargs)
        J = out.pinch_goal.shape[1]
        which = order(J, np.arange(len(pair_finger)), np.arange(len(pair_finger) // 2))
        if "pinch" in levers.pair:
            out.pinch_weight = out.pinch_weight * levers.pair["pinch"][pair_finger[which]].astype(out.pinch_weight.dtype)
        if levers.pinch_scale != 1.0:  # the goal is max(human, floor): C x that, never below the floor
            f = floor[which].astype(out.pinch_goal.dtype)
            out.pinch_goal = np.maximum(levers.pinch_scale * out.pinch_goal, f)
            out.gap_below = out.pinch_goal <= f
        return out

    start = {}

    def new_refine(robot, q, targets, weights=None, **kwargs):
        start["q"] = q.detach().to(robot.lower_limits.dtype).clone()
        if levers.search or levers.path:
            q = searched(robot, start["q"], targets, weights or LossWeights(), levers, lambda: caps(start["q"], robot.velocity_limits, float(targets.fps)))
        return refine(robot, q, targets, weights, **kwargs)

    HandTerms.__init__ = new_init
    HandTerms.build = classmethod(new_build)
    pipeline.refine_hands = new_refine
    hand_stage.step_caps = lambda q0, limits, fps: levers.caps * caps(start.get("q", q0), limits, fps)
    try:
        yield
    finally:
        HandTerms.__init__, HandTerms.build = init, classmethod(build)
        pipeline.refine_hands, hand_stage.step_caps = refine, caps


def searched(robot, q: torch.Tensor, targets, weights: LossWeights, levers: Levers, start_caps) -> torch.Tensor:
    """``q`` with the ``search`` joints set frame by frame, then the ``path`` joints along the clip, to the best of
    ``levers.grid`` values by the objective (one joint at a time, the others as they are)."""
    q = q.clone()
    t = targets.to(dtype=q.dtype)
    objective = Objective(robot, t, weights, **FastPaths.for_frames(len(t)).objective_options())
    for name, along in [(n, False) for n in levers.search] + [(n, True) for n in levers.path]:
        for k, c in enumerate(("l", "r")):
            if not bool(t.finger_mask[:, k].any()):
                continue
            j = robot.joint_names.index(f"yumi_hand_{c}_{JOINTS[name]}_joint")
            values = torch.linspace(float(robot.lower_limits[j]), float(robot.upper_limits[j]), levers.grid, dtype=q.dtype)
            cost = []
            with torch.no_grad():
                for v in values:
                    trial = q.clone()
                    trial[:, j] = v
                    cost.append(objective(trial)[0])
                now = objective(q)[0]
            cost = torch.stack(cost)  # (G, T)
            if along and len(q) > 1:
                cap = (levers.caps * start_caps())[:, j].double().numpy()
                q[:, j] = values[torch.as_tensor(path_within_caps(cost.double().numpy(), values.double().numpy(), cap)[0])]
            else:
                q[:, j] = torch.where(cost.min(0).values < now, values[cost.argmin(0)], q[:, j])
    return q


def run(robot, model, items, levers: Levers) -> dict:
    """The measures of one run over ``items`` (``(label, demonstration)``)."""
    config = pipeline.RetargetConfig(robot, OptimizeSettings(**levers.settings), model=model, weights=LossWeights(**levers.weights))
    scores, duration = [], 0.0
    with applied(robot, levers), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        retarget = config.build()
        for _, demo in items:
            result = retarget(demo)
            q = np.asarray(result.trajectory.angles, dtype=np.float64)
            scores.append(hand_scores(robot, q, demo))
            duration += result.trajectory.duration
    pooled = HandScores.cat(scores)
    return pooled.summary() | {"fingers": pooled.tip_per_finger(), "duration": duration}


def run_dex_variants(robot, items) -> dict[str, dict]:
    """dex-retargeting's measures on ``items``, per variant (``benchmarks/hands.py``'s runner, one pass)."""
    return {method: pooled.summary() | {"fingers": pooled.tip_per_finger(), "duration": float("nan")}
            for method, pooled in dex_scores(DEX_PYTHON, robot, items).items()}


def row(label: str, m: dict) -> str:
    duration = "—" if np.isnan(m["duration"]) else f"{m['duration']:.2f}"
    return (f"| {label} | {m['tip_deg']:.2f}° | {m['thumb_deg']:.2f}° | {m['finger_deg']:.2f}° | {m['pinch_r']:.3f} | "
            f"{' / '.join(f'{x:.2f}' for x in m['fingers'])} | {duration} |")


GROUPS = ("all", "chosen", "added")  # --recordings


def recording_group(items: list, which: str) -> list:
    """``items`` (``(label, demonstration)``) of the group ``which``: ``all``, ``chosen`` (those the handshape preset was
    chosen on) or ``added`` (``benchmarks/data/recordings/``, added after that choice)."""
    if which not in GROUPS:
        raise ValueError(f"unknown group {which!r}; expected all, chosen or added")
    return items if which == "all" else [(label, d) for label, d in items if added_after_choice(label) == (which == "added")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], epilog=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="*", default=[""], help="levers of one run, separated by spaces (none: the pipeline as it is)")
    ap.add_argument("--no-video", action="store_true", help="leave out the video (no MediaPipe)")
    ap.add_argument("--corpus", type=int, metavar="N", help="the first N clips of the synthetic corpus's test split instead")
    ap.add_argument("--dex", action="store_true", help="dex-retargeting's rows on the same data too (needs .venv-bench)")
    ap.add_argument("--recordings", choices=GROUPS, default="all",
                    help="all real recordings; those the handshape preset was chosen on; or those added after its choice "
                         "(benchmarks/data/recordings/, tuned on by nothing)")
    args = ap.parse_args()
    levers = [Levers.parse(text) for text in args.runs or [""]]  # all refused before any work
    if args.corpus is not None and args.corpus < 1:
        raise SystemExit(f"--corpus {args.corpus}: give at least one clip")
    if args.corpus is not None and args.recordings != "all":
        raise SystemExit(f"--recordings {args.recordings} picks among the real recordings; --corpus runs synthetic clips instead")
    if args.dex and not DEX_PYTHON.is_file():
        raise SystemExit(f"--dex: {DEX_PYTHON} is missing (make bench-venv builds it)")
    torch.set_num_threads(1)
    robot = load_robot("yumi")
    model = load_pretrained(robot)
    items = corpus_items(args.corpus) if args.corpus is not None else recordings(video=not args.no_video)
    items = recording_group(items, args.recordings)
    frames = sum(int(hand_frames_mask(d).sum()) for _, d in items)
    print(f"data: {', '.join(label for label, _ in items)} ({frames} hand-frames)")
    print("| levers | wrist→tip | thumb→tips | base→tip | pinch r | wrist→tip per finger (thumb, index, middle, ring, little) | retimed [s] |")
    print("|---|---|---|---|---|---|---|")
    for text, lever in zip(args.runs or [""], levers, strict=True):
        print(row(text or "(none)", run(robot, model, items, lever)), flush=True)
    if args.dex:
        for method, m in run_dex_variants(robot, items).items():
            print(row(method, m), flush=True)


if __name__ == "__main__":
    main()

"""Handshapes: nlo_lab against dex-retargeting on YuMi's Inspire hands, side by side in one run.

    python benchmarks/hands.py [--dex-python .venv-bench/bin/python] [--no-video] [--no-write] [--passes 3] [--no-held-out] [--no-arms]

Data: every real recording we have (``../shared/data/pose/*.pose`` when that folder is present,
``assets/recordings/*.pose``; a file in both counted once), the sample video
``assets/recordings/signer_webcam_58f.mp4`` through MediaPipe Holistic (the ``video`` extra), and the four
recordings of ``benchmarks/data/recordings/`` (pose-format's test data, MIT; its README). Those four came after the
handshape preset was chosen on the others: besides the pooled tables, the four measures are printed for each group
("The preset's choice, and recordings added after it").

Methods, on every hand-frame (one hand in one frame with its wrist frame and five fingers seen):

* **nlo_lab**: ``nlo_lab.pipeline.retarget`` with the shipped YuMi checkpoint and the default
  weights and settings (both arms and both hands together, smoothness, the latent optimisation,
  then the hand stage: a search of the middle, ring and little fingers' joints along the clip within the latent
  optimisation's speed, then the hand joints alone on the same objective, ``nlo_lab.inference.hand_stage``;
  retiming);
* **nlo_lab, handshape preset** (``nlo-lab retarget --handshape``): the same pipeline with
  ``LossWeights.handshape()`` and ``OptimizeSettings.handshape()``: the same search
  (``nlo_lab.inference.hand_stage.searched_start``) and descent, other weights, and a speed clamp that lets each
  retimed segment take up to ``HANDSHAPE_SLOWDOWN`` times the latent optimisation's; timed and held to the targets as
  nlo_lab's defaults are;
* **dex, filtered** and **dex, unfiltered**: dex-retargeting 0.5 vector retargeting with our
  configs and hand-only URDFs (``benchmarks/hands/``), with and without its low-pass filter. It
  needs numpy >= 2, which mediapipe (and so this environment) cannot have: it runs in
  ``.venv-bench`` (``make bench-venv``) as a subprocess (``benchmarks/hands/dex_runner.py``) that
  reads the landmarks from a file and writes the joint angles back. Its input: the human's wrist ->
  fingertip vectors in the robot's wrist-link frame, scaled by robot hand length / human hand length
  (the scale nlo_lab's terms use); mimic joints are expanded as the URDF says (both tools agree).
* **open hand, not moving**: the hands at their neutral (open) pose, for scale.
* **nlo_lab without the hand stage** (a diagnostic): ``OptimizeSettings(hand_iterations=0)``, the
  latent optimisation's hands (what the stage adds);
* **nlo_lab without the collision term** (a diagnostic, not a robot-safe method): what the
  self-collision pairs cost the handshape (YuMi's spec pairs the thumb with the fingers of its
  own hand at a 1 mm margin: a pinch may touch, the thumb may not go through a finger).
* **nlo_lab, then its hand joints alone optimised** (a diagnostic): nlo_lab's output with the hand
  joints moved by 100 more Adam steps in joint space on the same objective (collision and smoothness
  included, the arms kept, the limits by clamping): what the objective asks of the hands, against
  where the pipeline's hand stage (30 steps) leaves them.

One scorer for all: ``nlo_lab.evaluation.hands.hand_scores`` (our FK of YuMi; the measures and
their definitions are in its docstring and in docs/RESULTS.md). Also: joint-limit violations of
the hand joints (an angle outside its limits by more than 1e-6 rad; and the deepest), the hand-frames where the hand
overlaps itself by the URDF's own collision geometry (``nlo_lab.robot.geometry_collision``: pairs of
two links below one wrist, deeper than 0.1 mm; dex-retargeting does not avoid self-collision), nlo_lab's velocity
violations after retiming, and time: nlo_lab's wall time per frame (both arms and both hands,
``summary["seconds"]``, after one untimed call that builds what is kept per robot; the hand stage's share
from ``optimization.extra["hand_seconds"]``), dex-retargeting's
per hand-frame (each ``retarget`` call, its setup not counted). Each method's timing runs every recording in a
row, ``--passes`` times (default 3), and the median pass (by its total) is quoted: both alike, so that a busy
moment of the shared machine counts once and neither method's calls are interleaved with other work (before,
nlo_lab's calls alternated with the diagnostics'). Robot time: how long the robot takes to play the clips, each
method's output retimed to the joint velocity limits (``nlo_lab.inference.retime``; dex-retargeting's hand joints on
the arms of nlo_lab's default output, held from a hand's last hand-frame while it is not seen): what a method's hands
cost in time on the robot (the hand stage's speed clamp keeps nlo_lab's within the latent optimisation's, times
``hand_slowdown``). The four measures again on the
hand-frames where no method's hand goes through itself (like for like: dex-retargeting does not avoid it).
Then the targets of issue 27, with (unless ``--no-arms``) Table I's arms under the preset's weights against the defaults'
(:func:`arms_table1`; the issue bounds a changed objective at 5 % worse). Then, unless ``--no-held-out``, the four measures and each finger's wrist->tip error of
nlo_lab and dex-retargeting on data apart from the recordings: every clip of the synthetic corpus's test split that shows a
hand (held out from the checkpoint's training; hands synthesised from nlo_lab's own hand model). Unless ``--no-write``, the tables replace the ``hands`` section of
``docs/RESULTS.md``. What the hands could do at best, per frame and within the hand stage's speed clamp:
``benchmarks/hands_frontier.py``; what one change to the stage would give: ``benchmarks/hands_levers.py``.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_doc import stamp, update_section  # noqa: E402

from nlo_lab.corpus import sign_corpus  # noqa: E402
from nlo_lab.evaluation import BaselineSettings, evaluate  # noqa: E402
from nlo_lab.evaluation.hands import HandScores, hand_frames_mask, hand_joint_indices, hand_scores  # noqa: E402
from nlo_lab.human import load_demonstration  # noqa: E402
from nlo_lab.inference import (  # noqa: E402
    HANDSHAPE_SEARCH,
    HANDSHAPE_SLOWDOWN,
    FastPaths,
    OptimizeSettings,  # noqa: E402
    descend,
    retime_times,
    smoothness_term,
)
from nlo_lab.model import load_pretrained  # noqa: E402
from nlo_lab.objective import HAND_STAGE_TERMS, LossWeights, Objective, point_plan, targets_from_demonstration  # noqa: E402
from nlo_lab.pipeline import RetargetConfig, hand_search  # noqa: E402
from nlo_lab.robot import load_robot  # noqa: E402
from nlo_lab.robot.geometry_collision import DEPTH_TOLERANCE, GeometryCollision  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SHARED_POSE = ROOT.parent / "shared" / "data" / "pose"
RECORDINGS = ROOT / "assets" / "recordings"
ADDED = Path(__file__).resolve().parent / "data" / "recordings"  # real recordings added after the preset's choice
VIDEO = RECORDINGS / "signer_webcam_58f.mp4"
RUNNER = Path(__file__).resolve().parent / "hands" / "dex_runner.py"
DEX_PYTHON = ROOT / ".venv-bench" / "bin" / "python"
TIPS = (4, 8, 12, 16, 20)  # MediaPipe hand landmarks of the fingertips (0: the wrist)
NO_STAGE = "nlo_lab without the hand stage (diagnostic)"
NO_COLLISION = "nlo_lab without the collision term (diagnostic)"
REFINED = "nlo_lab, then its hand joints alone optimised on the same objective (diagnostic)"
PRESET = "nlo_lab, handshape preset (`--handshape`)"
METHODS = ("nlo_lab", PRESET, "dex, filtered", "dex, unfiltered", "open hand, not moving", NO_STAGE, NO_COLLISION, REFINED)
TIMED = ("nlo_lab", PRESET)  # the pipelines timed and held to the targets
REFINE_STEPS, REFINE_LR = 100, 0.02  # [rad] Adam on the hand joints of REFINED (patience 5, as the pipeline's)
DEX = {"dex, filtered": "filtered", "dex, unfiltered": "unfiltered"}
PER_FINGER = "wrist→fingertip direction error per finger (thumb / index / middle / ring / little)"  # a table row's name
ROBOT_TIME = "robot time: the clips retimed to the joint velocity limits"  # a table row's name
TABLE1_BOUND = 0.05  # issue 27: a changed objective may make Table I (the arms' Fréchet distance) at most 5 % worse


def quiet_load(path: Path):
    """The demonstration of ``path``, its readers' warnings (hands not seen in some frames) silenced."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_demonstration(path)


def recordings(video: bool) -> list[tuple[str, object]]:
    """``(label, demonstration)`` of every real recording (each file once), the video, then the recordings added after
    the preset's choice (:func:`added_after_choice` tells them by their label)."""
    paths = sorted(SHARED_POSE.glob("*.pose")) if SHARED_POSE.is_dir() else []
    if not paths:
        print(f"note: {SHARED_POSE} is absent: only the recordings in {RECORDINGS} are used", file=sys.stderr)
    seen, out = set(), []
    for path in paths + sorted(RECORDINGS.glob("*.pose")):
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        if digest in seen:
            continue
        seen.add(digest)
        out.append((path.stem, quiet_load(path)))
    if video:
        start = time.perf_counter()
        out.append((VIDEO.stem + " (MediaPipe)", quiet_load(VIDEO)))
        print(f"video through MediaPipe Holistic: {time.perf_counter() - start:.1f} s", file=sys.stderr)
    out += [(path.stem, quiet_load(path)) for path in sorted(ADDED.glob("*.pose"))]
    return out


def added_after_choice(label: str) -> bool:
    """Whether the recording ``label`` (of :func:`recordings`) is one of ``benchmarks/data/recordings/``: added after the
    handshape preset was chosen on the others, used to tune nothing."""
    return (ADDED / f"{label}.pose").is_file()


def hand_joints(robot) -> dict[int, list[int]]:
    """Per side, the indices of the actuated hand joints in the order of our dex configs."""
    order = ("thumb_proximal_yaw", "thumb_proximal_pitch", "index_proximal", "middle_proximal", "ring_proximal", "pinky_proximal")
    return {s: [robot.joint_names.index(f"yumi_hand_{c}_{j}_joint") for j in order] for s, c in ((0, "l"), (1, "r"))}


def dex_input(robot, items) -> dict[str, np.ndarray]:
    """The dex runner's input: every hand-frame's landmarks in the wrist-link frame, side, run, scaling."""
    plan = point_plan(robot, torch.float64)
    align = [robot.arm(side).wrist_alignment.double().numpy() for side in ("left", "right")]  # R_link_handframe
    points, side, segment, scaling = [], [], [], []
    for r, (_, demo) in enumerate(items):
        h_len = targets_from_demonstration(demo, dtype=torch.float64).hand_length[0].numpy()
        frames, sides = np.nonzero(hand_frames_mask(demo))
        order = np.lexsort((frames, sides))  # one hand's frames in a row
        for t, s in zip(frames[order], sides[order], strict=True):
            p = np.full((21, 3), np.nan)
            rel = np.concatenate([demo.arm_positions[t, s, 2][None], demo.finger_positions[t, s, :, 1]]) - demo.arm_positions[t, s, 2]
            p[(0, *TIPS),] = rel @ demo.wrist_rotations[t, s] @ align[s].T  # body -> human wrist frame -> wrist link
            points.append(p)
            side.append(s)
            segment.append(2 * r + s)
            scaling.append(float(plan.hand_length[s]) / float(h_len[s]))
    return {"points": np.array(points), "side": np.array(side), "segment": np.array(segment), "scaling": np.array(scaling)}


def run_dex(python: Path, data: dict[str, np.ndarray], passes: int = 1) -> dict[str, np.ndarray]:
    with tempfile.TemporaryDirectory(prefix="nlo_lab-hands-") as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(src, **data)
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # dex's own environment only
        proc = subprocess.run([str(python), str(RUNNER), str(src), str(dst), str(passes)], env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise SystemExit(f"dex-retargeting runner failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
        with np.load(dst) as f:
            return {k: f[k] for k in f.files}


def full_angles(robot, demo, dex_q: np.ndarray, rows: np.ndarray, data) -> np.ndarray:
    """YuMi's ``(T, n)`` angles: the neutral pose with each hand-frame's hand joints from dex."""
    q = np.tile(robot.neutral_q.double().numpy(), (len(demo), 1))
    joints = hand_joints(robot)
    frames, sides = np.nonzero(hand_frames_mask(demo))
    order = np.lexsort((frames, sides))
    for i, (t, s) in zip(rows, zip(frames[order], sides[order], strict=True), strict=True):
        assert data["side"][i] == s
        q[t, joints[s]] = dex_q[i]
    return q


def on_arms(robot, demo, arms: np.ndarray, hands: np.ndarray) -> np.ndarray:
    """``arms (T, n)`` with the hand joints of ``hands (T, n)`` (dex-retargeting's, :func:`full_angles`) in each
    hand's hand-frames, held from its last one while the hand is not seen (before its first: ``arms``' own)."""
    q = np.array(arms, dtype=np.float64)
    seen = hand_frames_mask(demo)
    for side, joints in hand_joints(robot).items():
        frames = np.flatnonzero(seen[:, side])
        if len(frames):
            last = frames[np.clip(np.searchsorted(frames, np.arange(len(q)), side="right") - 1, 0, None)]  # (T,)
            later = np.arange(len(q)) >= frames[0]
            q[np.ix_(later, joints)] = np.asarray(hands, dtype=np.float64)[np.ix_(last[later], joints)]
    return q


def robot_seconds(robot, q: np.ndarray, fps: float) -> float:
    """How long the robot takes to play ``q (T, n)`` retimed to its joint velocity limits [s]: the last sample's time
    plus one frame period (``RobotTrajectory.duration``)."""
    return float(retime_times(q, fps, robot.velocity_limits.double().numpy())[-1]) + 1.0 / fps


def corpus_items(n: int | None = None) -> list[tuple[str, object]]:
    """``(name, demonstration)`` of the synthetic corpus's test split clips that show a hand (the first ``n``; all when
    None): held out from the checkpoints' training, hands synthesised from nlo_lab's own hand model."""
    return [(d.name, d) for d in sign_corpus("test") if hand_frames_mask(d).any()][:n]


def dex_angles(python: Path, robot, items, passes: int = 1) -> tuple[dict[str, list[np.ndarray]], dict[str, np.ndarray]]:
    """dex-retargeting on ``items``: per variant (``DEX``'s names) YuMi's ``(T, n)`` angles of each item (the neutral
    pose with each hand-frame's hand joints from dex), and the runner's output (its timings)."""
    data = dex_input(robot, items)
    out = run_dex(python, data, passes)
    angles = {method: [full_angles(robot, demo, out[f"q_{variant}"], np.flatnonzero(data["segment"] // 2 == r), data)
                       for r, (_, demo) in enumerate(items)] for method, variant in DEX.items()}
    return angles, out


def dex_scores(python: Path, robot, items) -> dict[str, HandScores]:
    """dex-retargeting's hands on ``items`` scored by ``hand_scores``, pooled, per variant (one untimed pass)."""
    angles, _ = dex_angles(python, robot, items)
    return {method: HandScores.cat([hand_scores(robot, q, demo) for q, (_, demo) in zip(qs, items, strict=True)])
            for method, qs in angles.items()}


def finger_cell(per_finger: np.ndarray) -> str:
    """Each finger's wrist->tip error, thumb .. little, as one table cell."""
    return " / ".join(f"{x:.1f}" for x in per_finger) + "°"


def limit_violations(robot, q: np.ndarray, rows_mask: np.ndarray) -> tuple[int, float]:
    """Hand-joint entries of the hand-frames outside their limits by more than 1e-6 rad, and the deepest excess [rad]
    (dex-retargeting's optimiser widens every bound by 1e-3 rad: how far out its violations go tells them apart
    from a hand the robot could not take)."""
    lo, hi = robot.lower_limits.double().numpy(), robot.upper_limits.double().numpy()
    count, deepest = 0, 0.0
    for s, joints in hand_joints(robot).items():
        x = q[rows_mask[:, s]][:, joints]
        excess = np.maximum(lo[joints] - x, x - hi[joints])
        count += int((excess > 1e-6).sum())
        deepest = max(deepest, float(excess.max(initial=0.0)))
    return count, deepest


def added(total: tuple[int, float], more: tuple[int, float]) -> tuple[int, float]:
    """Two ``limit_violations`` counts and depths together."""
    return total[0] + more[0], max(total[1], more[1])


def refine_hands(robot, q: np.ndarray, demo, weights: LossWeights) -> np.ndarray:
    """``q (T, n)`` with its hand joints optimised on the whole objective (collision and smoothness included), the
    arms kept: Adam in joint space, clamped to the limits. What the objective asks of the hands, where the latent
    optimisation's 100 steps leave them."""
    dtype = robot.lower_limits.dtype
    targets = targets_from_demonstration(demo, dtype=dtype)
    loss = Objective(robot, targets, weights, **FastPaths.for_frames(len(demo)).objective_options())
    smooth = smoothness_term(robot, targets, weights)
    start = torch.as_tensor(np.array(q), dtype=dtype)
    hand = torch.zeros(robot.n_joints, dtype=torch.bool)
    hand[[i for side in ("left", "right") for i in hand_joint_indices(robot, side)]] = True

    def evaluate(x):
        total, terms = loss(x)
        return (total + smooth(x) if smooth is not None else total), x, terms

    def project(x):  # the hand joints inside their limits, the others back where the retargeting left them
        x.copy_(torch.where(hand, torch.maximum(torch.minimum(x, robot.upper_limits), robot.lower_limits), start))

    best = descend(start, evaluate, project, REFINE_STEPS, 5, REFINE_LR, None, per_sample=smooth is None)[1]
    return best.detach().double().numpy()


def own_hand_pairs(robot, geometry: GeometryCollision) -> dict[int, np.ndarray]:
    """Per side, which of the geometry's checked element pairs join two links of that hand (below its wrist link)."""
    out = {}
    for s, side in enumerate(("left", "right")):
        hand = set(robot.model.subtree(robot.arm(side).wrist))
        out[s] = np.array([geometry.pieces[i].link in hand and geometry.pieces[j].link in hand for i, j in geometry.pairs], dtype=bool)
    return out


def hand_frame_depths(geometry: GeometryCollision, pairs: dict[int, np.ndarray], q: np.ndarray, rows_mask: np.ndarray) -> np.ndarray:
    """``(N,)`` per hand-frame (``np.nonzero(rows_mask)`` order, as ``hand_scores``'s rows) the deepest overlap of two
    links of that hand by the URDF's collision geometry [m] (<= 0: apart)."""
    depths = geometry.depths(q)  # (T, P)
    frames, sides = np.nonzero(rows_mask)
    out = np.full(len(frames), -np.inf)
    for s, own in pairs.items():
        rows = sides == s
        if rows.any() and own.any():
            out[rows] = depths[frames[rows]][:, own].max(1)
    return out


def hand_collisions(geometry: GeometryCollision, pairs: dict[int, np.ndarray], q: np.ndarray, rows_mask: np.ndarray) -> tuple[int, float]:
    """Hand-frames whose hand overlaps itself by the URDF's collision geometry (deeper than DEPTH_TOLERANCE), and the deepest [m]."""
    depth = hand_frame_depths(geometry, pairs, q, rows_mask)
    return int((depth > DEPTH_TOLERANCE).sum()), max(0.0, float(depth.max(initial=0.0)))


def fmt(v, unit="", digits=1) -> str:
    return "—" if v is None or (isinstance(v, float) and not np.isfinite(v)) else f"{v:.{digits}f}{unit}"


def measure_table(title: str, pooled: dict[str, dict], per_finger: dict[str, np.ndarray] | None = None,
                  robot_time: dict[str, float] | None = None) -> str:
    """A markdown table of the four measures (``HandScores.summary`` of each method in ``pooled``), each finger's
    wrist->tip error when ``per_finger`` is given, and the robot time [s] of the methods ``robot_time`` has."""
    methods = list(pooled)
    rows = [f"| {title} | " + " | ".join(methods) + " |", "|---|" + "---|" * len(methods)]
    for key, name, unit in (("tip_deg", "wrist→fingertip direction error", "°"), ("thumb_deg", "thumb tip→other fingertips direction error", "°"),
                            ("pinch_r", "pinch correlation", ""), ("finger_deg", "finger base→tip direction error", "°")):
        rows.append(f"| {name} | " + " | ".join(fmt(pooled[m][key], unit, 2 if key == "pinch_r" else 1) for m in methods) + " |")
    if per_finger is not None:
        rows.append(f"| {PER_FINGER} | " + " | ".join(finger_cell(per_finger[m]) for m in methods) + " |")
    if robot_time is not None:
        rows.append(f"| {ROBOT_TIME} | " + " | ".join(fmt(robot_time.get(m), " s", 2) for m in methods) + " |")
    return "\n".join(rows)


def choice_groups(items: list, scores: dict[str, list[HandScores]], methods: list[str],
                  robot_time: dict[str, list[float]]) -> list[str]:
    """The four measures of ``methods`` on the recordings the handshape preset was first chosen on and on those added
    after (``scores[m][i]``: method ``m`` on ``items[i]``), with their robot time (``robot_time[m][i]`` [s]). Markdown
    lines, ending with a blank one; none without added ones."""
    added = [added_after_choice(label) for label, _ in items]
    if not any(added) or all(added):
        return []
    lines = ["### The preset's choice, and recordings added after it", "",
             "The handshape preset's searched fingers and its `tip_dir` and `thumb` weights were chosen "
             "(`benchmarks/hands_levers.py`) on the first group; the second, `benchmarks/data/recordings/`, came afterwards. "
             "Its `finger_dir` weight and `hand_slowdown` were then chosen on both groups (2026-11-28): no real recording is "
             "held out from the preset now (the synthetic test split below is). The defaults' `tip_dir` weight (7000) and "
             "their finger search (the preset's fingers, without its slowdown) were chosen on both groups too (2026-11-28). "
             "The targets above pool both.", ""]
    for flag, title in ((False, "the preset chosen on"), (True, "added after the choice")):
        chosen = [i for i, a in enumerate(added) if a == flag]
        pooled = {m: HandScores.cat([scores[m][i] for i in chosen]) for m in methods}
        frames = len(pooled[methods[0]])
        names = ", ".join(items[i][0] for i in chosen)
        seconds = {m: sum(robot_time[m][i] for i in chosen) for m in methods if m in robot_time}
        lines += [measure_table(f"{title}: {len(chosen)} recordings ({names}), {frames} hand-frames",
                                {m: v.summary() for m, v in pooled.items()}, {m: v.tip_per_finger() for m, v in pooled.items()},
                                seconds), ""]
    return lines


BETTER_HIGH = ("pinch_r",)  # the measures where higher is better (the others are errors)
MEASURE_NAMES = {"tip_deg": "wrist→fingertip [deg]", "thumb_deg": "thumb tip→other fingertips [deg]", "pinch_r": "pinch r",
                 "finger_deg": "finger base→tip [deg]"}


def dex_best(dex: list[dict]) -> dict[str, float]:
    """Per measure, the best of dex-retargeting's variants ``dex`` (their ``HandScores.summary``)."""
    return {k: max(d[k] for d in dex) if k in BETTER_HIGH else min(d[k] for d in dex) for k in MEASURE_NAMES}


def margins(ours: dict, dex: list[dict]) -> dict[str, float]:
    """Per measure, how far ``ours`` is ahead of the best of ``dex``'s variants (positive: ours better). The targets'
    comparison as a number."""
    best = dex_best(dex)
    return {k: (ours[k] - best[k]) if k in BETTER_HIGH else (best[k] - ours[k]) for k in MEASURE_NAMES}


def recording_bootstrap(scores: dict[str, list[HandScores]], methods: list[str], draws: int = 2000,
                        seed: int = 0) -> dict[str, dict[str, np.ndarray]]:
    """How sure the margins over dex-retargeting are, given so few recordings: ``draws`` resamples of the recordings
    (whole recordings with replacement, the frames of one recording move together), each method's :func:`margins`
    over the dex variants on each resample. ``scores[m][i]``: method ``m`` on recording ``i``. Returns method ->
    measure -> ``(draws,)`` margins."""
    rng = np.random.default_rng(seed)
    n = len(scores[methods[0]])
    out: dict[str, dict[str, list]] = {m: {k: [] for k in MEASURE_NAMES} for m in methods}
    for _ in range(draws):
        pick = rng.integers(0, n, n)
        dex = [HandScores.cat([scores[m][i] for i in pick]).summary() for m in DEX]
        for m in methods:
            for k, v in margins(HandScores.cat([scores[m][i] for i in pick]).summary(), dex).items():
                out[m][k].append(v)
    return {m: {k: np.asarray(v) for k, v in per.items()} for m, per in out.items()}


def bootstrap_table(pooled: dict[str, dict], boot: dict[str, dict[str, np.ndarray]], n_recordings: int) -> list[str]:
    """Markdown: each method's margin over dex-retargeting's best per measure, its 95 % interval over the resamples
    of :func:`recording_bootstrap` and the share of resamples where it is ahead."""
    dex = [pooled[m] for m in DEX]
    methods = list(boot)
    draws = len(next(iter(boot[methods[0]].values())))
    lines = ["### How sure: the margins over dex-retargeting, recordings resampled", "",
             f"Margin: how far ahead of dex-retargeting's best variant (positive: ahead; degrees, or r for the pinch). "
             f"Interval and share: over {draws} resamples of the {n_recordings} recordings with replacement (each recording's "
             "hand-frames together: the recordings differ more than their frames), each method and dex-retargeting "
             "scored on the same resample.", "",
             "| measure | " + " | ".join(f"{m}: margin [95 % interval], ahead in" for m in methods) + " |",
             "|---|" + "---|" * len(methods)]
    for k, name in MEASURE_NAMES.items():
        cells = []
        for m in methods:
            margin = margins(pooled[m], dex)[k]
            lo, hi = np.percentile(boot[m][k], [2.5, 97.5])
            digits = 3 if k in BETTER_HIGH else 2
            cells.append(f"{margin:+.{digits}f} [{lo:+.{digits}f}, {hi:+.{digits}f}], {100 * np.mean(boot[m][k] > 0):.0f} %")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    every = {m: np.mean(np.all([boot[m][k] > 0 for k in MEASURE_NAMES], axis=0)) for m in methods}
    lines.append("| all four at once (the target) | " + " | ".join(f"ahead in {100 * every[m]:.0f} %" for m in methods) + " |")
    return [*lines, ""]


def held_out(robot, pipelines: dict, dex_python: Path | None) -> str:
    """The measures on the synthetic corpus's test split (:func:`corpus_items`): each of nlo_lab's ``pipelines`` (name ->
    retarget) and, with ``dex_python``, dex-retargeting's two variants, scored alike. Markdown."""
    items = corpus_items()
    scores = {name: HandScores.cat([hand_scores(robot, retarget(demo).trajectory.angles, demo) for _, demo in items])
              for name, retarget in pipelines.items()}
    if dex_python is not None:
        scores |= dex_scores(dex_python, robot, items)
    table = measure_table("measure (mean over hand-frames)", {m: v.summary() for m, v in scores.items()},
                          {m: v.tip_per_finger() for m, v in scores.items()})
    return "\n".join([
        "### Held out: the synthetic corpus's test split", "",
        f"{len(items)} clips ({items[0][0]} .. {items[-1][0]}), {len(scores['nlo_lab'])} hand-frames, every test clip that "
        "shows a hand (`nlo_lab.corpus.sign_corpus(\"test\")`): held out from the checkpoint's training; their hands are "
        "synthesised from joint angles of nlo_lab's own hand model, not a person's. The same pipeline, dex-retargeting "
        "configs and scorer as above: whether the comparison above holds beyond the real recordings; "
        "not a target of issue 27.", "", table])


def arms_table1(robot, limit: int | None = None) -> dict[str, float]:
    """Table I's score of the arms (robot-ready mode, ``latent_encoder``: the mean over the synthetic test split's
    sequences of the wrist and elbow Fréchet distance [m]) with the default weights (``"nlo_lab"``) and with the handshape
    preset's (:data:`PRESET`). The preset's ``thumb`` weight acts in the latent optimisation, which moves the arms; its
    finger search and slowdown move only hand joints, which Table I does not score. ``limit``: the first sequences only."""
    demos = sign_corpus("test")[:limit]
    out = {}
    for name, weights in (("nlo_lab", None), (PRESET, LossWeights.handshape())):
        ev = evaluate(robot, demos, BaselineSettings(mode="robot-ready", weights=weights), methods=("latent_encoder",), progress=False)
        out[name] = ev.mean("latent_encoder")
    return out


def table1_row(arms: dict[str, float], sequences: int) -> str:
    """Issue 27's bound on the arms for the preset: Table I no more than :data:`TABLE1_BOUND` worse. A Markdown row."""
    ours, preset = arms["nlo_lab"], arms[PRESET]
    change = preset / ours - 1.0
    return (f"| handshape preset: Table I (robot-ready, `latent_encoder`, mean Fréchet of the {sequences} test sequences) "
            f"at most {100 * TABLE1_BOUND:.0f} % above the defaults' | {preset:.4f} m vs {ours:.4f} m ({100 * change:+.1f} %) | "
            + ("yes |" if change <= TABLE1_BOUND else "**no** |"))


def target_rows(label: str, ours: dict, dex: list[dict], dex_time: float | None, per_frame: float, limits: int,
                velocity: int) -> list[str]:
    """Issue 27's targets for one of nlo_lab's pipelines (``label``): its pooled measures ``ours`` against dex-retargeting's
    variants ``dex`` (empty: not run), its seconds ``per_frame`` against ``dex_time`` per hand-frame. Markdown rows."""
    rows = []
    if dex:
        better = {k: margin > 0 for k, margin in margins(ours, dex).items()}
        best_dex = dex_best(dex)
        digits = {k: 3 if k in BETTER_HIGH else 2 for k in better}
        measured = ", ".join(f"{k}: {fmt(ours[k], digits=digits[k])} vs {fmt(best_dex[k], digits=digits[k])}" for k in better)
        missed = [k for k, b in better.items() if not b]
        rows.append(f"| {label} better than both dex variants on all four measures (ours vs dex's best) | {measured} | "
                    + ("yes |" if not missed else f"**no** ({', '.join(missed)}) |"))
        for key in ("tip_deg", "thumb_deg"):
            best = min(d[key] for d in dex)
            rows.append(f"| {label}, stretch: {key} at most half of dex-retargeting's best ({best:.1f}° / 2 = {best / 2:.1f}°) | "
                        f"{ours[key]:.1f}° | {'yes' if ours[key] <= best / 2 else '**no**'} |")
    rows.append(f"| {label}: 0 joint-limit violations (all joints, all frames) | {limits} | {'yes' if limits == 0 else '**no**'} |")
    rows.append(f"| {label}: 0 velocity violations after retiming | {velocity} | {'yes' if velocity == 0 else '**no**'} |")
    if dex_time is not None:
        ratio = per_frame / dex_time
        rows.append(f"| {label}: time per frame (arms and hands) ≤ 2× dex-retargeting's per hand-frame | {1000 * per_frame:.2f} ms vs "
                    f"2 × {1000 * dex_time:.2f} ms (ratio {ratio:.2f}) | {'yes' if ratio <= 2 else '**no**'} |")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dex-python", type=Path, default=DEX_PYTHON, help="python of the environment with dex-retargeting")
    ap.add_argument("--no-video", action="store_true", help="leave out the video (no MediaPipe)")
    ap.add_argument("--no-write", action="store_true", help="print only; leave docs/RESULTS.md alone")
    ap.add_argument("--no-held-out", action="store_true", help="leave out the synthetic corpus's test split (held out)")
    ap.add_argument("--no-arms", action="store_true", help="leave out Table I of the preset's arms (about 45 s)")
    ap.add_argument("--passes", type=int, default=3,
                    help="timed passes over all recordings, back to back, for nlo_lab and for dex-retargeting; the median pass is quoted")
    ap.add_argument("--threads", type=int, default=1,
                    help="torch threads (1: no oversubscription on the shared 2-core machine, as the other benchmarks)")
    args = ap.parse_args()
    if args.passes < 1:
        ap.error(f"--passes must be at least 1 (got {args.passes})")
    torch.set_num_threads(max(1, args.threads))
    robot = load_robot("yumi")
    model = load_pretrained(robot)
    items = recordings(video=not args.no_video)
    weights = LossWeights()
    scores = {m: [] for m in METHODS}
    per_recording, nlo_frames = [], 0
    seconds = dict.fromkeys(TIMED, 0.0)
    stage_seconds = dict.fromkeys(TIMED, 0.0)  # of seconds: the hand stage's
    velocity, all_limits = dict.fromkeys(TIMED, 0), dict.fromkeys(TIMED, 0)
    hand_limits = dict.fromkeys(TIMED, (0, 0.0))
    geometry = GeometryCollision(robot)  # the independent check: the URDF's own collision geometry
    own = own_hand_pairs(robot, geometry)
    collided = {m: [0, 0.0] for m in METHODS}
    colliding: dict[str, list[np.ndarray]] = {m: [] for m in METHODS}  # per hand-frame, in the scores' order
    robot_time: dict[str, list[float]] = {m: [] for m in (*TIMED, *DEX)}  # per recording [s]

    def count(method: str, q: np.ndarray, demo) -> None:
        depth = hand_frame_depths(geometry, own, np.asarray(q, dtype=np.float64), hand_frames_mask(demo))
        collided[method][0] += int((depth > DEPTH_TOLERANCE).sum())
        collided[method][1] = max(collided[method][1], float(depth.max(initial=0.0)))
        colliding[method].append(depth > DEPTH_TOLERANCE)

    retarget = RetargetConfig(robot, model=model, weights=weights).build()
    pipelines = {"nlo_lab": retarget,
                 PRESET: RetargetConfig(robot, OptimizeSettings.handshape(), model=model,
                                        weights=LossWeights.handshape()).build()}
    # what the collision pairs between one hand's fingers cost the handshape (not robot-safe: no collision term)
    diagnostic = RetargetConfig(robot, model=model, weights=dataclasses.replace(weights, collision=0.0)).build()
    no_stage = RetargetConfig(robot, OptimizeSettings(hand_iterations=0), model=model, weights=weights).build()
    retarget(items[0][1].slice(0, min(5, len(items[0][1]))))  # once untimed: the robot's point plan and pinch floor
    # the timing: every recording in a row, --passes times, as dex-retargeting's; the median pass (by its total) counts
    results, timed = {}, {}
    for name in TIMED:
        passes = [[pipelines[name](demo) for _, demo in items] for _ in range(args.passes)]
        results[name] = passes[0]
        timed[name] = sorted(passes, key=lambda p: sum(r.summary["seconds"] for r in p))[(args.passes - 1) // 2]
    for i, (label, demo) in enumerate(items):
        for name in TIMED:
            result, timing = results[name][i], timed[name][i]
            q = result.trajectory.angles
            scores[name].append(hand_scores(robot, q, demo))
            count(name, q, demo)
            seconds[name] += timing.summary["seconds"]
            stage_seconds[name] += timing.optimization.extra.get("hand_seconds", 0.0)
            velocity[name] += result.summary["velocity_violations"]
            robot_time[name].append(result.trajectory.duration)
            all_limits[name] += result.summary["limit_violations"]
            hand_limits[name] = added(hand_limits[name], limit_violations(robot, np.asarray(q, dtype=np.float64), hand_frames_mask(demo)))
        q = results["nlo_lab"][i].trajectory.angles
        q_no_stage = no_stage(demo).trajectory.angles
        scores[NO_STAGE].append(hand_scores(robot, q_no_stage, demo))
        count(NO_STAGE, q_no_stage, demo)
        q_diagnostic = diagnostic(demo).trajectory.angles
        scores[NO_COLLISION].append(hand_scores(robot, q_diagnostic, demo))
        count(NO_COLLISION, q_diagnostic, demo)
        q_refined = refine_hands(robot, q, demo, weights)
        scores[REFINED].append(hand_scores(robot, q_refined, demo))
        count(REFINED, q_refined, demo)
        q_open = np.tile(robot.neutral_q.double().numpy(), (len(demo), 1))
        scores["open hand, not moving"].append(hand_scores(robot, q_open, demo))
        count("open hand, not moving", q_open, demo)
        nlo_frames += len(demo)
        per_recording.append((label, len(demo), int(hand_frames_mask(demo).sum()), *(timed[name][i].summary["seconds"] for name in TIMED)))
    dex_seconds, dex_limits, have_dex = {}, {}, args.dex_python.is_file()
    if have_dex:
        angles, out = dex_angles(args.dex_python, robot, items, args.passes)
        for method, variant in DEX.items():
            qs, limits = [], (0, 0.0)
            for i, (q, (_, demo)) in enumerate(zip(angles[method], items, strict=True)):
                arms = results["nlo_lab"][i].trajectory.angles
                robot_time[method].append(robot_seconds(robot, on_arms(robot, demo, arms, q), float(demo.fps)))
                qs.append(hand_scores(robot, q, demo))
                limits = added(limits, limit_violations(robot, q, hand_frames_mask(demo)))
                count(method, q, demo)
            scores[method], dex_limits[method] = qs, limits
            dex_seconds[method] = out[f"seconds_{variant}"]
    else:
        print(f"note: {args.dex_python} is missing: dex-retargeting left out (make bench-venv builds it)", file=sys.stderr)
    every = {m: HandScores.cat(s) for m, s in scores.items() if s}  # each method's hand-frames, pooled once
    pooled = {m: v.summary() for m, v in every.items()}
    # the same measures on the hand-frames where no method's hand goes through itself (a like-for-like comparison:
    # dex-retargeting does not avoid self-collision, nlo_lab does)
    compared = [*TIMED, *[m for m in DEX if scores[m]]]
    clean = ~np.any([np.concatenate(colliding[m]) for m in compared], axis=0)
    pooled_clean = {m: HandScores(**{f.name: getattr(every[m], f.name)[clean] for f in dataclasses.fields(HandScores)}).summary()
                    for m in compared}

    # ------------------------------------------------------------------ tables
    hand_frames = pooled["nlo_lab"]["hand_frames"]
    preset_weights = ", ".join(f"{k} {v:g}" for k, v in LossWeights.handshape().as_dict().items() if v != weights.as_dict()[k])
    lines = [f"- data: {len(items)} recordings ({', '.join(label for label, _ in items)}), {hand_frames} hand-frames",
             f"- nlo_lab: shipped checkpoint `assets/checkpoints/yumi.pt`, default weights ({weights.as_dict()}; the latent "
             f"optimisation without {', '.join(f'`{n}`' for n in HAND_STAGE_TERMS)}), then the hand stage (its finger search first: `hand_search={hand_search(robot, OptimizeSettings())}`, "
             f"{OptimizeSettings().hand_grid} values of each searched joint, every step within the latent optimisation's speed; "
             f"then {OptimizeSettings().hand_iterations} Adam steps of {OptimizeSettings().hand_lr} rad on the hand joints, same weights)",
             f"- nlo_lab, handshape preset: the same with `LossWeights.handshape()` ({preset_weights}) "
             f"and `OptimizeSettings.handshape()` (`hand_search={HANDSHAPE_SEARCH}`, {OptimizeSettings().hand_grid} values of each "
             f"searched joint; `hand_slowdown={HANDSHAPE_SLOWDOWN:g}`: each retimed segment up to {HANDSHAPE_SLOWDOWN:g} times the "
             "latent optimisation's)",
             "- dex-retargeting 0.5, vector retargeting, our configs `benchmarks/hands/inspire_{left,right}.yml` on "
             "`benchmarks/hands/yumi_hand_{left,right}.urdf`, run in `.venv-bench`" if have_dex else "- dex-retargeting: not run",
             f"- time: each method over every recording in a row, {args.passes} passes; the median pass (by its total) is quoted "
             "(nlo_lab: `summary[\"seconds\"]` of each `retarget`, both arms and both hands; dex-retargeting: each `retarget` "
             "call on one hand-frame)",
             ""]
    shown = [m for m in METHODS if m in pooled]
    head = "| measure (mean over hand-frames) | " + " | ".join(shown) + " |\n|---|" + "---|" * len(shown)
    rows = [head]
    for key, name, unit in (("tip_deg", "wrist→fingertip direction error", "°"), ("thumb_deg", "thumb tip→other fingertips direction error", "°"),
                            ("pinch_r", "pinch: correlation of thumb–index tip distance, human vs robot", ""),
                            ("finger_deg", "finger base→tip direction error", "°")):
        digits = 2 if key == "pinch_r" else 1
        vals = [("—" if key == "pinch_r" and m.startswith("open") else fmt(pooled[m][key], unit, digits)) for m in shown]
        rows.append(f"| {name} | " + " | ".join(vals) + " |")
    # where the wrist->tip gap sits
    rows.append(f"| {PER_FINGER} | " + " | ".join(finger_cell(every[m].tip_per_finger()) for m in shown) + " |")
    limits = {**hand_limits, **dex_limits}
    rows.append("| joint-limit violations (hand joints; deepest) | " + " | ".join(
        f"{limits[m][0]} ({1000 * limits[m][1]:.1f} mrad)" if m in limits else "—" for m in shown) + " |")
    rows.append("| hand-frames with the hand in self-collision by the URDF's geometry (deepest) | " + " | ".join(
        f"{collided[m][0]} ({1000 * collided[m][1]:.1f} mm)" for m in shown) + " |")
    times = {name: f"{1000 * seconds[name] / nlo_frames:.2f} ms per frame, arms and hands (of which the hand stage "
                   f"{1000 * stage_seconds[name] / nlo_frames:.2f} ms)" for name in TIMED}
    for m, sec in dex_seconds.items():
        times[m] = f"{1000 * sec.mean():.2f} ms per hand-frame (median {1000 * np.median(sec):.2f})"
    rows.append("| time | " + " | ".join(times.get(m, "") for m in shown) + " |")
    rows.append(f"| {ROBOT_TIME} (dex-retargeting's hands on nlo_lab's arms) | "
                + " | ".join(fmt(sum(robot_time[m]), " s", 2) if robot_time.get(m) else "" for m in shown) + " |")
    table = "\n".join(rows)
    clean_table = measure_table(f"measure, on the {int(clean.sum())} of {len(clean)} hand-frames where no method's hand goes through itself",
                                pooled_clean)
    recs = ("| recording | frames | hand-frames | nlo_lab [s] | handshape preset [s] | added after the preset's choice | "
            "wrist→tip: " + " / ".join(compared) + " |\n|---|---|---|---|---|---|---|\n") + "\n".join(
        f"| {label} | {n} | {h} | {s:.2f} | {p:.2f} | {'yes' if added_after_choice(label) else 'no'} | "
        + " / ".join(fmt(scores[m][i].summary()["tip_deg"], "°", 2) for m in compared) + " |"
        for i, (label, n, h, s, p) in enumerate(per_recording))
    groups = choice_groups(items, scores, compared, robot_time)
    sure = bootstrap_table(pooled, recording_bootstrap(scores, list(TIMED)), len(items)) if have_dex else []

    targets = ["| target | measured | met |", "|---|---|---|"]
    dex = [pooled[m] for m in DEX] if have_dex else []
    dex_time = min(float(sec.mean()) for sec in dex_seconds.values()) if have_dex else None
    for name, label in (("nlo_lab", "nlo_lab"), (PRESET, "handshape preset")):
        targets += target_rows(label, pooled[name], dex, dex_time, seconds[name] / nlo_frames, all_limits[name], velocity[name])
    if not args.no_arms:
        targets.append(table1_row(arms_table1(robot), len(sign_corpus("test"))))
    body = "\n".join(["## Handshapes on yumi: nlo_lab against dex-retargeting (issue 27)", "", stamp(), *lines,
                      "Measures (`nlo_lab.evaluation.hands`): in the wrist frame (the human's `R_body_wrist`, the robot's wrist "
                      "link turned by `wrist_alignment`), over the hand-frames (one hand in one frame with its wrist frame and all five "
                      "fingers seen); directions are unit vectors, an angle is averaged over the fingers (wrist→tip: five; thumb tip→tip: "
                      "the four others; base→tip: five, base = knuckle, thumb: its MCP joint), then over the hand-frames. Pinch: Pearson's "
                      "r of the thumb–index tip distance of human and robot, each in its own hand lengths (mean wrist→knuckle distance of "
                      "the four fingers). One FK (nlo_lab's, of `yumi.urdf`) scores every method. Self-collision: the hand-frames where "
                      "two links of that hand (below its wrist link) overlap by `yumi.urdf`'s collision geometry "
                      f"(`nlo_lab.robot.geometry_collision`, deeper than {1000 * DEPTH_TOLERANCE:.1f} mm), whatever the method. Joint-limit "
                      "violations: hand-joint angles of the hand-frames outside the URDF's limits by more than 1e-6 rad, and the "
                      "deepest (dex-retargeting's optimiser widens every bound by 1e-3 rad, `set_joint_limit`'s `epsilon`).", "",
                      "Diagnostics, not methods: nlo_lab without its hand stage (the latent optimisation's hands); nlo_lab with "
                      "the collision weight 0 (what the self-collision pairs cost the handshape); nlo_lab's output with its hand "
                      f"joints alone then optimised further in joint space ({REFINE_STEPS} Adam steps of {REFINE_LR} rad, patience 5, "
                      "the arms kept, the limits by clamping) on the same objective, collision and smoothness included (what the "
                      "objective asks of the hands, against where the pipeline leaves them).", "",
                      table, "", "The same measures where every method's hand is free of self-collision (dex-retargeting does not avoid "
                      "it; the targets below are on all hand-frames):", "", clean_table, "",
                      "### Targets against the measurement", "", "\n".join(targets), "", *sure, *groups, "### Recordings", "", recs,
                      *(["", held_out(robot, pipelines, args.dex_python if have_dex else None)] if not args.no_held_out else [])])
    print(body)
    if not args.no_write:
        print(f"wrote {update_section('hands', body)}", file=sys.stderr)


if __name__ == "__main__":
    main()

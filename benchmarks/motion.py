"""Robot-ready motion: joint speed, retiming, smoothness and tracking on real and synthetic input.

    python benchmarks/motion.py [--robots yumi,nao,pepper] [--smooth W] [--clips N] [--no-write]

For every recording in ``../shared/data/pose/`` (skipped with a note when that folder is
absent) and every clip of the synthetic test split, and for every robot, it retargets
with the shipped model (``nlo_lab.pipeline.retarget``: smoothness term, warm start,
retiming) and prints per input: Fréchet distance (of the samples, so before any
retiming), the joint speed over the limit had the frames played at the recording's rate,
the slowdown retiming needed, velocity violations on the output's own time base, joint
limit violations, self-collision frames and the largest joint step between consecutive
samples. Then the targets of issue 14 against the measurement, and the time to retarget
a 170-frame YuMi clip (median of 3). ``--smooth 0`` shows the method without the
smoothness term (the paper's), for comparison. Unless ``--no-write``, the tables replace
the ``motion`` section of ``docs/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_doc import default_budget, stamp, update_section  # noqa: E402

from nlo_lab.corpus import sign_corpus  # noqa: E402
from nlo_lab.human import load_demonstration  # noqa: E402
from nlo_lab.model import load_pretrained  # noqa: E402
from nlo_lab.objective import LossWeights  # noqa: E402
from nlo_lab.pipeline import retarget  # noqa: E402
from nlo_lab.robot import load_robot  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SHARED_POSE = ROOT.parent / "shared" / "data" / "pose"
TARGETS = {"slowdown": 3.0, "step_rad": 0.5, "frechet_rel": 0.05, "seconds_170": 1.5}
FRECHET_BEFORE = {"yumi": 0.0582}  # mean Fréchet of latent_encoder on the test split before issue 14 (docs/RESULTS.md, Table I)


def inputs(clips: int | None):
    """``(label, demonstration, kind)`` for every real recording and synthetic test clip."""
    out = []
    if SHARED_POSE.is_dir():
        for path in sorted(SHARED_POSE.glob("*.pose")):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                demo = load_demonstration(path)
            out.append((path.stem, demo, "real", [str(w.message) for w in caught]))
    else:
        print(f"note: {SHARED_POSE} is absent: real recordings skipped", file=sys.stderr)
    test = sign_corpus("test")
    for demo in test[: clips or len(test)]:
        out.append((demo.name, demo, "synthetic", []))
    return out


def run(robot_name: str, items, weights: LossWeights) -> list[dict]:
    robot = load_robot(robot_name)
    model = load_pretrained(robot)
    rows = []
    for label, demo, kind, notes in items:
        r = retarget(demo, robot, model=model, weights=weights)
        s = dict(r.summary)
        s.update(label=label, kind=kind, notes=notes)
        rows.append(s)
    return rows


def time_170(weights: LossWeights) -> tuple[float, float, float]:
    """Median of 3 retargetings of a 170-frame YuMi clip [s] (the real 170-frame recording when present),
    the same for the paper's method (``smooth=0``, lr 0.01) in the same run, and the 1-minute load average
    (the machine is shared: the ratio of the two says what smoothing costs)."""
    import os

    from nlo_lab.inference import OptimizeSettings

    path = SHARED_POSE / "mediapipe_right_hand_170f.pose"
    if path.is_file():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            demo = load_demonstration(path)
    else:
        demo = sign_corpus("test")[2].slice(0, 170)
    robot = load_robot("yumi")
    model = load_pretrained(robot)
    load = os.getloadavg()[0]
    retarget(demo, robot, model=model, weights=weights)  # warm-up
    times: dict[str, list[float]] = {"ours": [], "paper": []}
    for _ in range(3):  # interleaved, so that both see the same load
        for key, w, st in (("ours", weights, None), ("paper", LossWeights(smooth=0.0), OptimizeSettings.paper())):
            t0 = time.perf_counter()
            retarget(demo, robot, model=model, weights=w, settings=st)
            times[key].append(time.perf_counter() - t0)
    return statistics.median(times["ours"]), statistics.median(times["paper"]), load


def table(robot: str, rows: list[dict]) -> str:
    head = ("| input | frames | depth | Fréchet [m] | speed / limit at recorded rate | slowdown | speed / limit (output) "
            "| velocity viol. | limit viol. | collision frames | max step [rad] | seconds |")
    lines = [head, "|" + "---|" * 12]
    for s in rows:
        lines.append(
            f"| {s['label']} | {s['frames']} | {s['depth']} | {s['frechet_m']:.4f} | {s['recording_speed_ratio']:.2f} "
            f"| {s['slowdown']:.2f} | {s['max_joint_speed_ratio']:.3f} | {s['velocity_violations']} | {s['limit_violations']} | {s['self_collision_frames']} "
            f"| {s['max_joint_step_rad']:.3f} | {s['seconds']:.2f} |"
        )
    return f"### {robot}\n\n" + "\n".join(lines)


def targets_table(results: dict[str, list[dict]], timing: tuple[float, float, float] | None) -> tuple[str, bool]:
    lines = ["| target | measured | met |", "|---|---|---|"]
    ok_all = True

    def add(name: str, measured: str, ok: bool) -> None:
        nonlocal ok_all
        ok_all &= ok
        lines.append(f"| {name} | {measured} | {'yes' if ok else '**no**'} |")

    rows = [s for rs in results.values() for s in rs]
    add("0 velocity violations on the file's own time base (all inputs, all robots)",
        str(sum(s["velocity_violations"] for s in rows)), all(s["velocity_violations"] == 0 for s in rows))
    worst = max(rows, key=lambda s: s["slowdown"])
    add(f"output duration ≤ {TARGETS['slowdown']:g}× the recording's",
        f"largest {worst['slowdown']:.2f}× ({worst['robot']}, {worst['label']})", worst["slowdown"] <= TARGETS["slowdown"])
    add("0 joint-limit violations", str(sum(s["limit_violations"] for s in rows)), all(s["limit_violations"] == 0 for s in rows))
    add("0 self-collision frames", str(sum(s["self_collision_frames"] for s in rows)), all(s["self_collision_frames"] == 0 for s in rows))
    step = max(rows, key=lambda s: s["max_joint_step_rad"])
    add(f"no joint step over {TARGETS['step_rad']} rad between consecutive samples",
        f"largest {step['max_joint_step_rad']:.3f} rad ({step['robot']}, {step['label']})", step["max_joint_step_rad"] <= TARGETS["step_rad"])
    for robot, rs in results.items():
        syn = [s["frechet_m"] for s in rs if s["kind"] == "synthetic"]
        if robot in FRECHET_BEFORE and syn:
            before = FRECHET_BEFORE[robot]
            mean = float(np.mean(syn))
            add(f"{robot} synthetic test split: mean Fréchet within +{TARGETS['frechet_rel']:.0%} of {before} m (before retiming)",
                f"{mean:.4f} m ({(mean / before - 1):+.1%}, {len(syn)} clips)", mean <= before * (1 + TARGETS["frechet_rel"]))
    if timing is not None:
        ours, paper, load = timing
        add(f"a 170-frame YuMi clip retargets in ≤ {TARGETS['seconds_170']} s",
            f"{ours:.2f} s (median of 3; the paper's method {paper:.2f} s in the same run, ratio {ours / paper:.2f}; "
            f"load average {load:.1f} on {os.cpu_count()} cores)", ours <= TARGETS["seconds_170"])
    return "\n".join(lines), ok_all


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", default="yumi,nao,pepper")
    ap.add_argument("--smooth", type=float, default=None, help="weight of the smoothness term (default: LossWeights' default)")
    ap.add_argument("--clips", type=int, default=None, help="only the first N synthetic test clips")
    ap.add_argument("--no-write", action="store_true", help="print only; leave docs/RESULTS.md alone")
    args = ap.parse_args(argv)
    weights = LossWeights() if args.smooth is None else LossWeights(smooth=args.smooth)
    items = inputs(args.clips)
    results = {}
    parts = []
    for robot in args.robots.split(","):
        results[robot] = run(robot, items, weights)
        parts.append(table(robot, results[robot]))
        print(parts[-1] + "\n", flush=True)
    timing = time_170(weights) if "yumi" in results else None
    targets, ok = targets_table(results, timing)
    print(targets)
    notes = sorted({f"{s['label']}: {n}" for rs in results.values() for s in rs for n in s["notes"]})
    body = "\n\n".join([
        "## Robot-ready motion (issue 14)",
        stamp().strip(),
        f"- smoothness weight {weights.smooth:g}; shipped checkpoints; the pipeline's default optimisation ({default_budget()}); "
        "retiming to the published joint velocity limits (`nlo_lab.inference.retime`)",
        "Per input: Fréchet distance of the samples (retiming moves samples in time, not in space); "
        "'speed / limit at recorded rate' = largest joint speed over its limit had the frames played 1/fps apart; "
        "slowdown = output duration over the recording's; violations counted on the output file's own time base.",
        *parts,
        "### Targets against the measurement",
        targets,
        *(["Reader warnings: " + "; ".join(notes)] if notes else []),
    ])
    if not args.no_write:
        update_section("motion", body)
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

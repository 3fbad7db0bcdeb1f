"""Speed of video -> MediaPipe Holistic -> robot on the sample video (prints a table).

    python benchmarks/video.py [--robot yumi] [--repeats 3] [--workers 1,2] [--no-cli] [--no-write]

1. Pose estimation (``nlo_lab.human.estimate_pose``: decoding, Holistic
   with the bundled model, pose-format's container) for each number of workers, the
   runs interleaved (1, 2, 1, 2, ...) so that a shared machine's load falls on both alike:
   frames per second, the CPU time over the wall time (the cores the estimation actually
   kept busy), the load average beside each, the speed-up over one worker, and whether
   the landmarks are byte-identical to one worker's (they must be).
2. Retargeting the sample's demonstration (``nlo_lab.pipeline.retarget``, the default settings, as the command line).
3. End to end per second of video: pose estimation (default workers: every core) +
   retargeting, over the video's duration; and the whole command
   ``nlo-lab retarget VIDEO --json`` as a user runs it (interpreter start and imports included).
4. The cost of the segments that let workers share a video: the sample estimated as one
   segment (pure tracking, ``estimate_pose(..., segment_frames=<its frame count>)``) against the
   default segments, both retargeted with the default settings (``--no-segments`` skips it).

Medians of ``--repeats`` runs; rewrites the ``video`` section of docs/RESULTS.md
unless ``--no-write``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
import warnings

import numpy as np
from results_doc import ROOT, default_budget, stamp, update_section

import nlo_lab.human.readers.video as video_reader
from nlo_lab.human import estimate_pose, pose_to_demonstration, video_info
from nlo_lab.inference import OptimizeSettings
from nlo_lab.model import load_pretrained
from nlo_lab.pipeline import retarget
from nlo_lab.robot import load_robot

SAMPLE = ROOT / "assets" / "recordings" / "signer_webcam_58f.mp4"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="yumi")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workers", default="1,2", help="comma-separated numbers of Holistic instances")
    ap.add_argument("--no-cli", action="store_true", help="skip timing the command line")
    ap.add_argument("--no-segments", action="store_true", help="skip measuring the cost of the 30-frame segments")
    ap.add_argument("--no-write", action="store_true", help="print only; leave docs/RESULTS.md alone")
    args = ap.parse_args()
    info = video_info(SAMPLE)
    duration = info["frames"] / info["fps"]
    cores = len(os.sched_getaffinity(0))
    load = os.getloadavg()[0]  # the machine may be shared: say how busy it was
    print(f"{SAMPLE.name}: {info['frames']} frames, {info['width']}x{info['height']}, {info['fps']:.2f} fps, "
          f"{duration:.2f} s of video; {cores} cores available, load average {load:.1f}")

    t0 = time.perf_counter()
    import pose_format.utils.holistic  # noqa: F401  (mediapipe's import, paid once per process)
    import_seconds = time.perf_counter() - t0
    print(f"importing mediapipe through pose-format: {import_seconds:.2f} s (once per process)")

    rows, video = [], None
    counts = [int(w) for w in args.workers.split(",")]
    walls = {w: [] for w in counts}
    ratios = {w: [] for w in counts}
    loads = {w: [] for w in counts}
    used, landmarks = {}, {}
    for _ in range(args.repeats):
        for workers in counts:  # interleaved: the same background load for every count
            c0 = time.process_time()
            video = estimate_pose(SAMPLE, threads=workers)
            walls[workers].append(video.seconds)
            ratios[workers].append((time.process_time() - c0) / video.seconds)
            loads[workers].append(os.getloadavg()[0])
            used[workers] = video.workers
            landmarks.setdefault(workers, video.to_bytes())
    base = statistics.median(walls[counts[0]])
    identical = len({landmarks[w] for w in counts}) == 1
    for workers in counts:
        wall = statistics.median(walls[workers])
        row = (workers, used[workers], wall, info["frames"] / wall, statistics.median(ratios[workers]), base / wall,
               statistics.median(loads[workers]))
        rows.append(row)
        print(f"pose estimation, {workers} worker(s) asked, {row[1]} used: {wall:.2f} s median of {args.repeats}, "
              f"{row[3]:.1f} frames/s, CPU time / wall {row[4]:.2f}, speed-up over {counts[0]} worker(s) {row[5]:.2f}x, "
              f"load average {row[6]:.1f}")
    print(f"landmarks identical for {', '.join(map(str, counts))} workers: {'yes' if identical else 'NO'}")

    default_video = estimate_pose(SAMPLE)  # the default: every core available
    print(f"pose estimation, default ({default_video.workers} workers): {default_video.seconds:.2f} s, "
          f"load average {os.getloadavg()[0]:.1f}")

    video = default_video
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the sample's left hand is never seen: known
        demo = pose_to_demonstration(video)
    robot = load_robot(args.robot)
    model = load_pretrained(robot)
    settings = OptimizeSettings()  # the defaults, as `nlo-lab retarget VIDEO` runs (results_doc.default_budget())
    retarget(demo, robot, settings=settings, model=model)  # warm-up
    runs = [retarget(demo, robot, settings=settings, model=model) for _ in range(args.repeats)]
    retarget_s = statistics.median(r.seconds for r in runs)
    s = runs[-1].summary
    print(f"retarget to {robot.name} ({default_budget()}): {retarget_s:.3f} s median of {args.repeats}; "
          f"Fréchet {s['frechet_m']:.4f} m, limit violations {s['limit_violations']}, collision frames {s['self_collision_frames']}")

    pose_default = default_video.seconds
    per_second = (pose_default + retarget_s) / duration
    print(f"end to end (library, default {default_video.workers} workers): {pose_default + retarget_s:.2f} s for "
          f"{duration:.2f} s of video = {per_second:.2f} s per second of video")

    cli = None
    if not args.no_cli:
        cmd = [sys.executable, "-m", "nlo_lab.cli", "retarget", str(SAMPLE), "--robot", robot.name, "--json"]
        walls, pose_in_cli = [], []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
            walls.append(time.perf_counter() - t0)
            pose_in_cli.append(json.loads(out)["pose_seconds"])
        cli = statistics.median(walls)
        print(f"command line `nlo-lab retarget {SAMPLE.name} --robot {robot.name} --json`: {cli:.2f} s median of "
              f"{args.repeats} ({cli / duration:.2f} s per second of video; pose_seconds {statistics.median(pose_in_cli):.2f})")

    segments = None if args.no_segments else segment_cost(default_video, robot, model)

    if args.no_write:
        return
    lines = [
        "## Video to robot",
        "",
        stamp(),
        f"- video: `assets/recordings/{SAMPLE.name}` ({info['frames']} frames, {info['width']}x{info['height']}, "
        f"{info['fps']:.2f} fps, {duration:.2f} s); MediaPipe Holistic 0.10.21 through pose-format, model complexity 1",
        f"- importing mediapipe: {import_seconds:.2f} s, once per process (not in the figures below)",
        f"- load average (1 min) at the start: {load:.1f} on {cores} cores (other work shares this machine)",
        "",
        f"### Pose estimation (median of {args.repeats})",
        "",
        "| workers asked | workers used | seconds | frames/s | CPU time / wall | speed-up | load average |",
        "|---|---|---|---|---|---|---|",
        *[f"| {a} | {u} | {w:.2f} | {f:.1f} | {r:.2f} | {x:.2f}x | {ld:.1f} |" for a, u, w, f, r, x, ld in rows],
        "",
        "Runs interleaved (1, 2, 1, 2, ...). CPU time / wall is the number of cores the estimation kept busy on "
        "average (decoding included); speed-up is over the first row; load average (1 min) is the median over "
        "that row's runs, taken right after each.",
        f"- landmarks byte-identical for every number of workers: **{'yes' if identical else 'no'}** "
        "(segments of 30 frames, each tracked by its own Holistic instance, whoever runs it)",
        f"- the default (every core available: {default_video.workers} workers here): {default_video.seconds:.2f} s",
        "",
        "### Retargeting and end to end",
        "",
        f"- retarget to {robot.name}, the defaults ({default_budget()}): {retarget_s:.3f} s (median of {args.repeats}); "
        f"Fréchet {s['frechet_m']:.4f} m, {s['limit_violations']} limit violations, {s['self_collision_frames']} collision frames",
        f"- library, pose estimation (default, {default_video.workers} workers) + retargeting: {pose_default + retarget_s:.2f} s, "
        f"**{per_second:.2f} s per second of video**",
    ]
    if cli is not None:
        lines.append(f"- the command `nlo-lab retarget {SAMPLE.name} --robot {robot.name} --json` "
                     f"(start, imports, estimation, retargeting): {cli:.2f} s, {cli / duration:.2f} s per second of video")
    lines += reading(rows, identical)
    if segments is not None:
        lines += segments
    update_section("video", "\n".join(lines))
    print("updated docs/RESULTS.md (section video)")


def reading(rows, identical: bool) -> list[str]:
    """What the pose-estimation table says, in words made from its own figures."""
    if len(rows) < 2:
        return []
    first, last = rows[0], rows[-1]
    speedup, busy, load = last[5], last[4], last[6]
    verdict = ("a core was free for the extra worker" if speedup >= 1.2 else
               "the extra worker found no idle core (a second worker helps only where a core is idle)")
    return [
        "",
        f"Reading the table: {last[0]} workers against {first[0]}: {speedup:.2f}x "
        f"({last[3]:.1f} against {first[3]:.1f} frames/s; CPU time / wall {busy:.2f}) at load average {load:.1f}: "
        f"{verdict}. Whatever the load, the landmarks {'are' if identical else 'are NOT'} byte-identical for every "
        "number of workers (also tested: "
        "`tests/human/test_video.py::test_the_result_does_not_depend_on_the_number_of_workers`).",
    ]


def segment_cost(segmented, robot, model) -> list[str]:
    """Retarget the sample from its default segments and from one segment (pure tracking); compare."""
    cut = video_reader.SEGMENT_FRAMES
    whole = estimate_pose(SAMPLE, threads=1, segment_frames=video_info(SAMPLE)["frames"])  # one segment: Holistic tracks it all
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the sample's left hand is never seen: known
        demos = {"segments": pose_to_demonstration(segmented), "one segment": pose_to_demonstration(whole)}
    runs = {name: retarget(demo, robot, model=model) for name, demo in demos.items()}  # the default settings
    a, b = demos["segments"], demos["one segment"]
    both = a.arm_mask & b.arm_mask
    apart = np.where(both, np.linalg.norm(a.arm_positions - b.arm_positions, axis=-1), -1.0)  # (T, 2, 3)
    where = int(np.unravel_index(np.argmax(apart), apart.shape)[0])
    gap = float(apart.max())
    sa, sb = runs["segments"].summary, runs["one segment"].summary
    restarts = ", ".join(str(first) for first, _ in video_reader.segment_bounds(SAMPLE)[1:]) or "none"
    print(f"segments vs one segment: Fréchet {sa['frechet_m']:.4f} vs {sb['frechet_m']:.4f} m; largest arm-point gap {gap:.3f} m")

    def violations(s):
        return f"{s['limit_violations']} limit, {s['self_collision_frames']} collision, {s['velocity_violations']} velocity"

    return [
        "",
        f"### Cost of the {cut}-frame segments",
        "",
        f"Tracking restarts at frame(s) {restarts}. The sample estimated as one segment (pure tracking) and as the "
        "default segments, each retargeted with the default settings:",
        "",
        "| landmarks | Fréchet [m] | slowdown | violations |",
        "|---|---|---|---|",
        f"| {cut}-frame segments (default) | {sa['frechet_m']:.4f} | {sa['slowdown']:.3f} | {violations(sa)} |",
        f"| one segment | {sb['frechet_m']:.4f} | {sb['slowdown']:.3f} | {violations(sb)} |",
        "",
        f"- Fréchet with segments over one segment: {sa['frechet_m'] / sb['frechet_m'] - 1:+.1%}",
        f"- largest distance between an arm point of the two demonstrations: {gap:.3f} m (frame {where})",
    ]


if __name__ == "__main__":
    main()

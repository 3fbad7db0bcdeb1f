"""``nlo-lab retarget INPUT --robot R``: one recording (a file, a video or ``demo:NAME``) to a robot.

The outputs of ``--out`` (:data:`OUTPUT_FILES`) appear as a whole set or not at all
(:func:`nlo_lab.batch.write_output_folder`, which ``nlo-lab batch`` writes each input's folder with);
every flag is checked before any work starts.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from nlo_lab.batch.output_folder import OUTPUT_FILES, finite_or_null, write_output_folder
from nlo_lab.cli.flags import (
    MAX_SEED,
    THREADS_RANGE,
    WEIGHT_RANGE,
    UsageError,
    add_hand_flags,
    add_optimisation_flags,
    check_hand_flags,
    hand_settings,
    positive_float,
    ranged_int,
)
from nlo_lab.cli.run_guard import raise_pending_signal
from nlo_lab.errors import escape

__all__ = ["OUTPUT_FILES", "add_parser", "run"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("retarget", help="retarget a recording (.pose, .h5, .npz, a video or demo:NAME) to a robot")
    p.add_argument("input", metavar="INPUT",
                   help="a .pose/.h5/.npz file, a video (.mp4/.mov/.webm/.avi), or demo:NAME for a clip of the embedded corpus")
    p.add_argument("--robot", required=True, help="yumi, nao, pepper, or a robot spec .json")
    p.add_argument("--checkpoint", default=None, metavar="CKPT.pt",
                   help="a trained checkpoint of this robot (nlo-lab train --out); default: the shipped one")
    add_optimisation_flags(p, "ee=1000,ori=100,elbow=100,finger=100,collision=1000")
    add_hand_flags(p)
    p.add_argument("--out", default=None, help="folder for trajectory.npz, trajectory.csv and viewer.html")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.add_argument("--seed", type=ranged_int(0, MAX_SEED), default=0,
                   help="seed of the random initialisation, 0..2^32-1 (default: 0)")
    p.add_argument("--sigma", type=positive_float, default=1.0,
                   help="σ of --init random, a standard deviation: z0 ~ N(0, σ²) (default: 1, the paper's; its ablation's "
                        "variances 0.1 and 0.2 are σ 0.32 and 0.45)")
    p.add_argument("--quiet", action="store_true", help="no progress bar (shown only when stderr is a terminal), no warnings")
    p.add_argument("--save-pose", metavar="FILE", default=None,
                   help="video input: also keep MediaPipe Holistic's landmarks as this .pose file")
    p.add_argument("--threads", type=ranged_int(*THREADS_RANGE), default=None,
                   help=f"video input: the most cores the pose estimation may use, {THREADS_RANGE[0]}..{THREADS_RANGE[1]} "
                        "(default: NLO_LAB_THREADS, else every core available; the result is the same for any N)")
    return p


def _check_weights(weights) -> None:
    """Each loss weight within :data:`WEIGHT_RANGE` (refused before any work)."""
    lo, hi = WEIGHT_RANGE
    for name, value in weights.as_dict().items():
        if not lo <= value <= hi:  # NaN fails this too
            raise UsageError(f"nlo-lab retarget: --weights: weight {name}={value!r} must be in [{lo:g}, {hi:g}]")


def _load_input(text: str):
    from nlo_lab.sources import load_demonstration  # the corpus and the readers: not for --help

    return load_demonstration(text)


def _is_video(text: str) -> bool:
    from nlo_lab.human import VIDEO_SUFFIXES

    return not text.startswith("demo:") and Path(text).suffix.lower() in VIDEO_SUFFIXES


def _check_save_pose(args) -> Path | None:
    """``--save-pose`` is checked before any input is read, written after everything else."""
    from nlo_lab.atomic_files import check_output_file

    if args.save_pose is None:
        return None
    if not _is_video(args.input):
        raise UsageError("nlo-lab retarget: --save-pose needs a video INPUT (.mp4, .mov, .webm or .avi)")
    return check_output_file(args.save_pose, what="--save-pose", suffix=".pose")


def _load_video(args, progress: bool):
    """A video's demonstration and its landmarks (warnings go to the one channel of :func:`nlo_lab.cli.main`)."""
    from nlo_lab.human import estimate_pose, pose_to_demonstration

    video = estimate_pose(args.input, threads=args.threads, progress=progress)
    return pose_to_demonstration(video), video


def _print_summary(summary: dict) -> None:
    width = max(len(k) for k in summary)
    for key, value in summary.items():
        if isinstance(value, float):
            value = f"{value:.4f}"
        print(f"  {key:<{width}}  {value}")


def run(args) -> int:
    from nlo_lab.atomic_files import check_output_place
    from nlo_lab.inference import OptimizeSettings
    from nlo_lab.metrics import HAND_KEYS
    from nlo_lab.model import load_pretrained
    from nlo_lab.objective import LossWeights
    from nlo_lab.pipeline import RetargetConfig
    from nlo_lab.robot import load_robot

    if args.out is not None:
        check_output_place(args.out, OUTPUT_FILES)  # refused before any input is read (--out '' too)
    save_pose = _check_save_pose(args)
    base = LossWeights.handshape() if args.handshape else LossWeights()
    weights = LossWeights.from_string(args.weights, base) if args.weights else base
    _check_weights(weights)
    settings = OptimizeSettings(init=args.init, iterations=args.iters, seed=args.seed, latent_sigma=args.sigma,
                                **hand_settings(args))
    robot = load_robot(args.robot)
    check_hand_flags(args, robot, "retarget")
    model = load_pretrained(robot, args.checkpoint)  # before any work: a missing checkpoint is refused at once
    progress = not args.quiet and sys.stderr.isatty()
    video = None
    if _is_video(args.input):
        demo, video = _load_video(args, progress)
    else:
        demo = _load_input(args.input)
    result = RetargetConfig(robot, settings, weights, model=model, progress=progress).build()(demo)
    if video is not None:
        result.summary["pose_seconds"] = round(video.seconds, 4)
    if args.out is not None:
        # a signal an import swallowed still ends the run, before the swap
        write_output_folder(Path(args.out), result, demo, robot, before_swap=raise_pending_signal)
    if save_pose is not None:
        from nlo_lab.atomic_files import atomic_write_bytes

        atomic_write_bytes(save_pose, video.to_bytes())
    if args.json:
        print(json.dumps(finite_or_null(result.summary), allow_nan=False))  # valid JSON: no NaN
    else:
        print(f"retargeted {escape(demo.name or args.input)} ({len(demo)} frames) to {escape(robot.name)}:")
        shown = {k: v for k, v in result.summary.items() if not (k in HAND_KEYS and result.summary["hand_frames"] is None)}
        _print_summary({k: escape(v) if isinstance(v, str) else v for k, v in shown.items()})  # no hands to score: no lines of None
        if args.out is not None:
            print(f"wrote {escape(args.out)}/trajectory.npz, trajectory.csv, viewer.html")
        if save_pose is not None:
            print(f"wrote {escape(save_pose)}")
    return 0

"""The ``nlo-lab`` command (README.md, "Command line": a contract).

One error path: every failure the command meets (input files, flags, output
places, disk, permissions, memory) ends with exit status 2 and one line on stderr
that names what is wrong and where, with names taken from files escaped
(:func:`nlo_lab.errors.escape`). Only a bug of nlo_lab itself gives a traceback
(exit 1). Warnings, ours and the libraries', go through one channel: one line
each (``nlo-lab: warning: ...``), silenced by ``--quiet``. SIGTERM, SIGHUP and
SIGINT end the run with exit 128+signal after the clean-up ran: the outputs of
``retarget --out`` appear as a whole set or not at all (:func:`nlo_lab.atomic_files.output_set`).
:mod:`nlo_lab.run_guard` holds that machinery, :mod:`nlo_lab.flag_types` the flags' types; this
module the parser (the only one of nlo_lab) and the commands.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
from pathlib import Path

from nlo_lab.errors import Interrupted, NloLabError, escape
from nlo_lab.flag_types import LazyChoices, positive_float, ranged_int
from nlo_lab.paths import BUNDLED_ROBOTS
from nlo_lab.run_guard import error_line, one_warning_channel, os_error_text, raise_pending_signal, signals_raise

__all__ = ["main", "build_parser"]

DEMO_CLIP = "demo:introduction_06"  # "HELLO, NAME, STUDENT" (133 frames at 20 fps)
OUTPUT_FILES = ("trajectory.npz", "trajectory.csv", "viewer.html")  # the set `retarget --out` writes
MAX_SEED = 2**32 - 1  # numpy's and torch's generators both take it
# Stated ranges of the numeric flags: a value outside is refused (exit 2, one line) before any work.
ITERS_RANGE = (0, 10_000)  # Adam steps; 0 = the start point. The paper's longest budget is 600
EPOCHS_RANGE = (1, 10_000)  # passes over the training frames (30 by default)
LIMIT_RANGE = (1, 1_000_000)  # sequences of a split to evaluate
THREADS_RANGE = (1, 256)  # Holistic instances of the pose estimation, at most; torch threads of train/evaluate
BATCH_RANGE = (1, 1_000_000)  # training frames per step
LATENT_RANGE = (1, 64)  # latent size per robot node
WEIGHT_RANGE = (0.0, 1e6)  # each loss weight: 1000x the largest default; beyond it float32 losses overflow to NaN


class UsageError(NloLabError):
    """A bad flag or argument on the command line."""


class _Parser(argparse.ArgumentParser):
    # argparse prints usage plus a message and exits; we want one line and status 2.
    def error(self, message: str):  # type: ignore[override]
        raise UsageError(f"{self.prog}: {message}")


def _check_weights(weights) -> None:
    """Each loss weight within :data:`WEIGHT_RANGE` (refused before any work)."""
    lo, hi = WEIGHT_RANGE
    for name, value in weights.as_dict().items():
        if not lo <= value <= hi:  # NaN fails this too
            raise UsageError(f"nlo-lab retarget: --weights: weight {name}={value!r} must be in [{lo:g}, {hi:g}]")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``nlo-lab`` (exposed for the docs and the tests); the only one of nlo_lab."""
    parser = _Parser(prog="nlo-lab", description="Kinematic motion retargeting by neural latent optimisation.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser("retarget", help="retarget a recording (.pose, .h5, .npz, a video or demo:NAME) to a robot")
    p.add_argument("input", metavar="INPUT",
                   help="a .pose/.h5/.npz file, a video (.mp4/.mov/.webm/.avi), or demo:NAME for a clip of the embedded corpus")
    p.add_argument("--robot", required=True, help="yumi, nao, pepper, or a robot spec .json")
    p.add_argument("--init", default="encoder", choices=LazyChoices("nlo_lab.inference", "INITS"), metavar="INIT",
                   help="initialisation of the latent code: %(choices)s (default: encoder)")
    p.add_argument("--iters", type=ranged_int(*ITERS_RANGE), default=100,
                   help=f"latent optimisation budget, {ITERS_RANGE[0]}..{ITERS_RANGE[1]} (default: 100)")
    p.add_argument("--weights", default=None,
                   help=f"loss weights, each {WEIGHT_RANGE[0]:g}..{WEIGHT_RANGE[1]:g}, "
                        "e.g. ee=1000,ori=100,elbow=100,finger=100,collision=1000")
    p.add_argument("--out", default=None, help="folder for trajectory.npz, trajectory.csv and viewer.html")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.add_argument("--seed", type=ranged_int(0, MAX_SEED), default=0, help="seed of the random initialisation")
    p.add_argument("--quiet", action="store_true", help="no progress bar (shown only when stderr is a terminal), no warnings")
    p.add_argument("--save-pose", metavar="FILE", default=None,
                   help="video input: also keep MediaPipe Holistic's landmarks as this .pose file")
    p.add_argument("--threads", type=ranged_int(*THREADS_RANGE), default=None,
                   help=f"video input: the most cores the pose estimation may use, {THREADS_RANGE[0]}..{THREADS_RANGE[1]} "
                        "(default: NLO_LAB_THREADS, else every core available; the result is the same for any N)")

    p = sub.add_parser("train", help="train the encoder and decoder of a robot on the synthetic corpus")
    p.add_argument("--robot", required=True, help="yumi, nao, pepper, or a robot spec .json")
    p.add_argument("--epochs", type=ranged_int(*EPOCHS_RANGE), default=None,
                   help=f"passes over the training frames, {EPOCHS_RANGE[0]}..{EPOCHS_RANGE[1]} (default: 30)")
    p.add_argument("--max-seconds", type=positive_float, default=None,
                   help="wall-clock budget [s]; training stops after the step that exceeds it (default: 500)")
    p.add_argument("--batch-size", type=ranged_int(*BATCH_RANGE), default=None, help="frames per step (default: 64)")
    p.add_argument("--lr", type=positive_float, default=None, help="Adam learning rate (default: 0.001)")
    p.add_argument("--kind", default=None, choices=LazyChoices("nlo_lab.model", "MODEL_KINDS"), metavar="KIND",
                   help="%(choices)s: graph is the paper's (default: graph)")
    p.add_argument("--latent-per-node", type=ranged_int(*LATENT_RANGE), default=None,
                   help=f"latent size per robot node, {LATENT_RANGE[0]}..{LATENT_RANGE[1]} (default: 4)")
    p.add_argument("--out", default=None, help="checkpoint path (default: assets/checkpoints/NAME.pt in a checkout, ./NAME.pt in an installed package)")
    p.add_argument("--seed", type=ranged_int(0, MAX_SEED), default=0)
    p.add_argument("--threads", type=ranged_int(*THREADS_RANGE), default=None,
                   help="torch threads (default: NLO_LAB_THREADS, else 1)")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no warnings")

    p = sub.add_parser("evaluate", help="compare the method with the baselines on a corpus split")
    p.add_argument("--robot", required=True)
    p.add_argument("--split", default="test", choices=("train", "test"))
    p.add_argument("--json", action="store_true", help="print the results as one JSON object on the last line")
    p.add_argument("--limit", type=ranged_int(*LIMIT_RANGE), default=None,
                   help=f"evaluate only the first N sequences, {LIMIT_RANGE[0]}..{LIMIT_RANGE[1]}")
    p.add_argument("--iters", type=ranged_int(*ITERS_RANGE), default=None,
                   help=f"iterations of the latent and joint-space methods, {ITERS_RANGE[0]}..{ITERS_RANGE[1]} (default: 100)")
    p.add_argument("--methods", default=None,
                   help="comma-separated subset of the methods (nlo_lab.evaluation.METHODS; default: all)")
    p.add_argument("--threads", type=ranged_int(*THREADS_RANGE), default=None,
                   help="torch threads (default: NLO_LAB_THREADS, else 1)")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no warnings")

    sub.add_parser("demo", help="retarget a clip of the embedded test split to YuMi and print the summary")

    p = sub.add_parser("lab", help="copy the notebooks to a folder of yours and open JupyterLab there")
    p.add_argument("--port", type=ranged_int(1, 65535), default=8888)
    p.add_argument("--dir", default=None, help="your notebook folder (default: $NLO_LAB_NOTEBOOKS or ~/nlo_lab_notebooks)")
    p.add_argument("--copy-only", action="store_true", help="copy the notebooks and print the folder; do not start JupyterLab")
    return parser


# ----------------------------------------------------------------------------- commands
def _load_input(text: str):
    from nlo_lab.corpus import corpus_clip
    from nlo_lab.human import load_demonstration

    if text.startswith("demo:"):
        return corpus_clip(text[len("demo:"):])
    return load_demonstration(text)


def _is_video(text: str) -> bool:
    from nlo_lab.human.io_video import VIDEO_SUFFIXES

    return not text.startswith("demo:") and Path(text).suffix.lower() in VIDEO_SUFFIXES


def _check_save_pose(args) -> Path | None:
    """``--save-pose`` is checked before the (slow) pose estimation, written after everything else."""
    if args.save_pose is None:
        return None
    if not _is_video(args.input):
        raise UsageError("nlo-lab retarget: --save-pose needs a video INPUT (.mp4, .mov, .webm or .avi)")
    path = Path(args.save_pose)
    if path.suffix.lower() != ".pose":
        raise UsageError(f"nlo-lab retarget: --save-pose FILE must end in .pose, got {args.save_pose!r}")
    if path.is_dir():
        raise UsageError(f"nlo-lab retarget: --save-pose {args.save_pose!r} is a folder")
    if not path.resolve().parent.is_dir():
        raise UsageError(f"nlo-lab retarget: --save-pose: the folder {str(path.parent)!r} does not exist")
    return path


def _load_video(args, progress: bool):
    """A video's demonstration and its landmarks (warnings go to the one channel of :func:`main`)."""
    from nlo_lab.human.io_video import estimate_pose, pose_to_demonstration

    video = estimate_pose(args.input, threads=args.threads, progress=progress)
    return pose_to_demonstration(video), video


def _write_outputs(out_dir: Path, result, demo, robot) -> None:
    """Write the set into a temporary folder beside ``out_dir``, then swap it in (all or nothing)."""
    from nlo_lab.atomic_files import output_set
    from nlo_lab.viz import export_html

    with output_set(out_dir, OUTPUT_FILES) as tmp:
        result.trajectory.save_npz(tmp / "trajectory.npz")
        result.trajectory.save_csv(tmp / "trajectory.csv")
        # the page plays the trajectory on its own (retimed) time base: what the robot would play
        export_html(tmp / "viewer.html", robot, result.trajectory.angles, demo=demo, fps=demo.fps, single_precision=True,
                    times=result.trajectory.times)
        raise_pending_signal()  # a signal an import swallowed still ends the run, before the swap


def _finite_or_null(summary: dict) -> dict:
    """NaN and infinity are not JSON: a figure that is not finite is reported as null."""
    return {k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in summary.items()}


def _print_summary(summary: dict) -> None:
    width = max(len(k) for k in summary)
    for key, value in summary.items():
        if isinstance(value, float):
            value = f"{value:.4f}"
        print(f"  {key:<{width}}  {value}")


def cmd_retarget(args) -> int:
    from nlo_lab.atomic_files import check_output_place
    from nlo_lab.inference import OptimizeSettings, RetargetConfig
    from nlo_lab.objective import LossWeights
    from nlo_lab.robot import load_robot

    if args.out:
        check_output_place(args.out, OUTPUT_FILES)  # refused before any work starts
    weights = LossWeights.from_string(args.weights) if args.weights else LossWeights()
    _check_weights(weights)
    settings = OptimizeSettings(init=args.init, iterations=args.iters, seed=args.seed)
    robot = load_robot(args.robot)
    save_pose = _check_save_pose(args)
    progress = not args.quiet and sys.stderr.isatty()
    video = None
    if _is_video(args.input):
        demo, video = _load_video(args, progress)
    else:
        demo = _load_input(args.input)
    result = RetargetConfig(robot, settings, weights, progress=progress).build()(demo)
    if video is not None:
        result.summary["pose_seconds"] = round(video.seconds, 4)
    if args.out:
        _write_outputs(Path(args.out), result, demo, robot)
    if save_pose is not None:
        from nlo_lab.atomic_files import atomic_write_bytes

        atomic_write_bytes(save_pose, video.to_bytes())
    if args.json:
        print(json.dumps(_finite_or_null(result.summary), allow_nan=False))  # valid JSON: no NaN
    else:
        print(f"retargeted {escape(demo.name or args.input)} ({len(demo)} frames) to {escape(robot.name)}:")
        _print_summary({k: escape(v) if isinstance(v, str) else v for k, v in result.summary.items()})
        if args.out:
            print(f"wrote {escape(args.out)}/trajectory.npz, trajectory.csv, viewer.html")
        if save_pose is not None:
            print(f"wrote {escape(save_pose)}")
    return 0


def cmd_train(args) -> int:
    import dataclasses

    import torch

    from nlo_lab.model import checkpoint_path, save_checkpoint
    from nlo_lab.paths import is_editable_checkout
    from nlo_lab.robot import load_robot
    from nlo_lab.training import TrainSettings, train_model

    flags = {"epochs": args.epochs, "max_seconds": args.max_seconds, "batch_size": args.batch_size, "lr": args.lr,
             "kind": args.kind, "latent_per_node": args.latent_per_node}
    settings = dataclasses.replace(TrainSettings(seed=args.seed, progress=not args.quiet), **{k: v for k, v in flags.items() if v is not None})
    if args.threads is not None:
        torch.set_num_threads(args.threads)
    robot = load_robot(args.robot)
    result = train_model(robot, settings)
    # A checkout retrains the shipped file in place; an installed package is never written to.
    out = Path(args.out) if args.out else checkpoint_path(robot.name) if is_editable_checkout() else Path(f"{robot.name}.pt")
    save_checkpoint(result.model, out, robot)
    print(
        f"trained {escape(robot.name)}: {result.steps} steps in {result.seconds:.1f} s, "
        f"best validation loss {result.val_loss:.4f}; wrote {escape(out)} ({out.stat().st_size / 1e6:.2f} MB)"
    )
    return 0


def cmd_evaluate(args) -> int:
    import dataclasses
    import time

    import torch

    from nlo_lab.evaluation import METHODS, BaselineSettings, check_methods, evaluate_split, format_table, to_json
    from nlo_lab.robot import load_robot

    if args.threads is not None:
        torch.set_num_threads(args.threads)
    methods = check_methods([m.strip() for m in args.methods.split(",") if m.strip()] if args.methods is not None else METHODS)
    settings = BaselineSettings() if args.iters is None else dataclasses.replace(BaselineSettings(), iterations=args.iters)
    robot = load_robot(args.robot)
    start = time.perf_counter()
    ev = evaluate_split(robot, args.split, limit=args.limit, settings=settings, methods=methods, progress=not args.quiet)
    if args.json:
        print(json.dumps(to_json(ev)))
        return 0
    print(format_table(ev))
    if ev.info.get("nn_label_seconds") is not None and ev.info.get("nn_train_seconds") is not None:
        print(
            f"nn_supervised: labels {ev.info['nn_label_seconds']:.1f} s + training {ev.info['nn_train_seconds']:.1f} s"
            " (once, then cached; not part of its wall time)"
        )
    frames = sum(s.frames for s in ev.scores[methods[0]].values())
    print(f"{len(ev.sequences)} {args.split} sequences, {frames} frames, {time.perf_counter() - start:.1f} s in all")
    return 0


def cmd_demo(args) -> int:
    from nlo_lab.robot import load_robot

    for name in BUNDLED_ROBOTS:
        robot = load_robot(name)
        print(f"\n{name}: {robot.n_joints} actuated joints")
        print(f"  {'joint':<40} {'lower':>9} {'upper':>9}")
        for joint, lo, hi in zip(robot.joint_names, robot.lower_limits.tolist(), robot.upper_limits.tolist(), strict=True):
            print(f"  {joint:<40} {lo:>9.4f} {hi:>9.4f}")
    out = Path("out/demo")
    print(f"\nretargeting {DEMO_CLIP} to yumi ...")
    ns = build_parser().parse_args(["retarget", DEMO_CLIP, "--robot", "yumi", "--out", str(out)])
    return cmd_retarget(ns)


def cmd_lab(args) -> int:
    from nlo_lab.lab import copy_notebooks, lab_command
    from nlo_lab.paths import user_notebooks_dir

    folder = Path(args.dir).expanduser() if args.dir else user_notebooks_dir()
    copied, kept = copy_notebooks(folder)
    note = f" (kept your {len(kept)} existing files)" if kept else ""
    print(f"notebooks: {folder}: copied {len(copied)} files{note}", file=sys.stderr)
    if args.copy_only:
        print(folder)
        return 0
    command = lab_command(folder, args.port)
    os.execv(sys.executable, command)
    return 0  # not reached


COMMANDS = {
    "retarget": cmd_retarget,
    "train": cmd_train,
    "evaluate": cmd_evaluate,
    "demo": cmd_demo,
    "lab": cmd_lab,
}


def main(argv: list[str] | None = None) -> int:
    """Run ``nlo-lab``; returns the exit status (0 ok, 2 bad input or a fault, 128+N on signal N)."""
    with signals_raise():
        try:
            args = build_parser().parse_args(argv)
            with one_warning_channel(getattr(args, "quiet", False)):
                import torch

                from nlo_lab.threads import default_threads

                torch.set_num_threads(default_threads())  # see nlo_lab.threads: one thread unless NLO_LAB_THREADS says otherwise
                status = COMMANDS[args.command](args)
                raise_pending_signal()
                return status
        except NloLabError as exc:
            return error_line(exc)
        except FileNotFoundError as exc:
            return error_line(f"file not found: {exc.filename}")
        except MemoryError:
            return error_line("out of memory (the input is too large for this machine; try a shorter recording)")
        except OSError as exc:  # disk full, permissions, I/O errors: the environment, not a bug
            return error_line(os_error_text(exc))
        except Interrupted as exc:
            name = signal.Signals(exc.signum).name
            print(f"nlo-lab: interrupted by {name}", file=sys.stderr)
            return 128 + exc.signum
        except KeyboardInterrupt:
            print("nlo-lab: interrupted by SIGINT", file=sys.stderr)
            return 128 + signal.SIGINT


if __name__ == "__main__":
    sys.exit(main())

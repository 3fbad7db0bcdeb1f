"""The ``nlo-lab`` command (README.md, "Command line": a contract).

One error path: every failure the command meets (input files, flags, output
places, disk, permissions, memory) ends with exit status 2 and one line on stderr
that names what is wrong and where, with names taken from files escaped
(:func:`nlo_lab.errors.escape`). Only a bug of nlo_lab itself gives a traceback
(exit 1). Warnings, ours and the libraries', go through one channel: one line
each (``nlo-lab: warning: ...``), silenced by ``--quiet``. SIGTERM, SIGHUP and
SIGINT end the run with exit 128+signal after the clean-up ran: the outputs of
``retarget --out`` appear as a whole set or not at all (:func:`nlo_lab.atomic_files.output_set`).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import signal
import sys
import threading
import warnings
from pathlib import Path

from nlo_lab.errors import Interrupted, NloLabError, escape

__all__ = ["main", "build_parser"]

ROBOTS = ("yumi", "nao", "pepper")
INITS = ("encoder", "random", "train-stats", "zeros")
DEMO_CLIP = "demo:introduction_06"  # "HELLO, NAME, STUDENT" (133 frames at 20 fps)
OUTPUT_FILES = ("trajectory.npz", "trajectory.csv", "viewer.html")  # the set `retarget --out` writes
MAX_SEED = 2**32 - 1  # numpy's and torch's generators both take it
# Stated ranges of the numeric flags: a value outside is refused (exit 2, one line) before any work.
ITERS_RANGE = (0, 10_000)  # Adam steps; 0 = the start point. The paper's longest budget is 600
EPOCHS_RANGE = (1, 10_000)  # passes over the training frames (30 by default)
LIMIT_RANGE = (1, 1_000_000)  # sequences of a split to evaluate
THREADS_RANGE = (1, 256)  # Holistic instances of the pose estimation, at most
WEIGHT_RANGE = (0.0, 1e6)  # each loss weight: 1000x the largest default; beyond it float32 losses overflow to NaN


class UsageError(NloLabError):
    """A bad flag or argument on the command line."""


class _Parser(argparse.ArgumentParser):
    # argparse prints usage plus a message and exits; we want one line and status 2.
    def error(self, message: str):  # type: ignore[override]
        raise UsageError(f"{self.prog}: {message}")


def _ranged_int(lo: int, hi: int):
    def parse(text: str) -> int:
        if len(text) > 40:  # int() of a huge digit string is slow and its echo floods the line
            raise argparse.ArgumentTypeError(f"must be a whole number in [{lo}, {hi}], got {len(text)} characters")
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number in [{lo}, {hi}], got {text!r}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"must be in [{lo}, {hi}], got {text}")
        return value

    return parse


def _check_weights(weights) -> None:
    """Each loss weight within :data:`WEIGHT_RANGE` (refused before any work)."""
    lo, hi = WEIGHT_RANGE
    for name, value in weights.as_dict().items():
        if not lo <= value <= hi:  # NaN fails this too
            raise UsageError(f"nlo-lab retarget: --weights: weight {name}={value!r} must be in [{lo:g}, {hi:g}]")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``nlo-lab`` (exposed for the docs and the tests)."""
    parser = _Parser(prog="nlo-lab", description="Kinematic motion retargeting by neural latent optimisation.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser("retarget", help="retarget a recording (.pose, .h5, .npz, a video or demo:NAME) to a robot")
    p.add_argument("input", metavar="INPUT",
                   help="a .pose/.h5/.npz file, a video (.mp4/.mov/.webm/.avi), or demo:NAME for a clip of the embedded corpus")
    p.add_argument("--robot", required=True, help="yumi, nao, pepper, or a robot spec .json")
    p.add_argument("--init", default="encoder", choices=INITS, help="initialisation of the latent code (default: encoder)")
    p.add_argument("--iters", type=_ranged_int(*ITERS_RANGE), default=100,
                   help=f"latent optimisation budget, {ITERS_RANGE[0]}..{ITERS_RANGE[1]} (default: 100)")
    p.add_argument("--weights", default=None,
                   help=f"loss weights, each {WEIGHT_RANGE[0]:g}..{WEIGHT_RANGE[1]:g}, "
                        "e.g. ee=1000,ori=100,elbow=100,finger=100,collision=1000")
    p.add_argument("--out", default=None, help="folder for trajectory.npz, trajectory.csv and viewer.html")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.add_argument("--seed", type=_ranged_int(0, MAX_SEED), default=0, help="seed of the random initialisation")
    p.add_argument("--quiet", action="store_true", help="no progress bar (shown only when stderr is a terminal), no warnings")
    p.add_argument("--save-pose", metavar="FILE", default=None,
                   help="video input: also keep MediaPipe Holistic's landmarks as this .pose file")
    p.add_argument("--threads", type=_ranged_int(*THREADS_RANGE), default=None,
                   help=f"video input: the most cores the pose estimation may use, {THREADS_RANGE[0]}..{THREADS_RANGE[1]} "
                        "(default: NLO_LAB_THREADS, else every core available; the result is the same for any N)")

    p = sub.add_parser("train", help="train the encoder and decoder of a robot on the synthetic corpus")
    p.add_argument("--robot", required=True, help="yumi, nao, pepper, or a robot spec .json")
    p.add_argument("--epochs", type=_ranged_int(*EPOCHS_RANGE), default=None,
                   help=f"passes over the training frames, {EPOCHS_RANGE[0]}..{EPOCHS_RANGE[1]}")
    p.add_argument("--out", default=None, help="checkpoint path (default: assets/checkpoints/NAME.pt in a checkout, ./NAME.pt in an installed package)")
    p.add_argument("--seed", type=_ranged_int(0, MAX_SEED), default=0)
    p.add_argument("--quiet", action="store_true", help="no progress bar, no warnings")

    p = sub.add_parser("evaluate", help="compare the method with the baselines on a corpus split")
    p.add_argument("--robot", required=True)
    p.add_argument("--split", default="test", choices=("train", "test"))
    p.add_argument("--json", action="store_true", help="print the results as one JSON object on the last line")
    p.add_argument("--limit", type=_ranged_int(*LIMIT_RANGE), default=None,
                   help=f"evaluate only the first N sequences, {LIMIT_RANGE[0]}..{LIMIT_RANGE[1]}")

    sub.add_parser("demo", help="retarget a clip of the embedded test split to YuMi and print the summary")

    p = sub.add_parser("lab", help="copy the notebooks to a folder of yours and open JupyterLab there")
    p.add_argument("--port", type=_ranged_int(1, 65535), default=8888)
    p.add_argument("--dir", default=None, help="your notebook folder (default: $NLO_LAB_NOTEBOOKS or ~/nlo_lab_notebooks)")
    p.add_argument("--copy-only", action="store_true", help="copy the notebooks and print the folder; do not start JupyterLab")
    return parser


# ----------------------------------------------------------------------------- commands
def _load_input(text: str):
    from nlo_lab.human import corpus_clip, load_demonstration

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
        _raise_pending_signal()  # a signal an import swallowed still ends the run, before the swap


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
    from nlo_lab.losses import LossWeights
    from nlo_lab.optimize import OptimizeSettings
    from nlo_lab.retarget import retarget
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
    result = retarget(demo, robot, settings=settings, weights=weights, progress=progress)
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
    from nlo_lab.train import main as train_main

    argv = ["--robot", args.robot, "--seed", str(args.seed)]
    if args.epochs is not None:
        argv += ["--epochs", str(args.epochs)]
    if args.out:
        argv += ["--out", args.out]
    if args.quiet:
        argv += ["--quiet"]
    return int(train_main(argv) or 0)


def cmd_evaluate(args) -> int:
    from nlo_lab.evaluate import main as evaluate_main

    argv = ["--robot", args.robot, "--split", args.split]
    if args.json:
        argv.append("--json")
    if args.limit is not None:
        argv += ["--limit", str(args.limit)]
    return int(evaluate_main(argv) or 0)


def cmd_demo(args) -> int:
    from nlo_lab.robot import load_robot

    for name in ROBOTS:
        robot = load_robot(name)
        print(f"\n{name}: {robot.n_joints} actuated joints")
        print(f"  {'joint':<40} {'lower':>9} {'upper':>9}")
        for joint, lo, hi in zip(robot.joint_names, robot.lower_limits.tolist(), robot.upper_limits.tolist()):
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


# ----------------------------------------------------------------------------- the one error path
_TERMINATING = ("SIGTERM", "SIGHUP", "SIGINT")
_pending: list[int] = []  # signals received, even those some library's `except BaseException` swallowed


def _on_signal(signum, frame):
    _pending.append(signum)
    raise Interrupted(signum)


def _raise_pending_signal() -> None:
    if _pending:
        raise Interrupted(_pending[0])


@contextlib.contextmanager
def _signals_raise():
    """SIGTERM, SIGHUP and SIGINT raise :class:`Interrupted` (so ``finally`` blocks clean up)."""
    if threading.current_thread() is not threading.main_thread():  # handlers only install there
        yield
        return
    previous = {}
    for name in _TERMINATING:
        if hasattr(signal, name):
            sig = getattr(signal, name)
            previous[sig] = signal.signal(sig, _on_signal)
    _pending.clear()
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@contextlib.contextmanager
def _one_warning_channel(quiet: bool):
    """Collect the run's warnings; print each distinct one as one line when the run succeeds.

    A failed run prints its error line only (the one line the error path promises).
    Python's default filters apply (deprecations inside libraries are not the user's business).
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.resetwarnings()
        warnings.simplefilter("ignore" if quiet else "default")
        for category in (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning):
            warnings.filterwarnings("ignore", category=category)
        yield
    seen = set()
    for w in caught:
        line = f"nlo-lab: warning: {escape(w.message)}"
        if line not in seen:
            seen.add(line)
            print(line, file=sys.stderr)


def _error(message) -> int:
    print(f"nlo-lab: error: {escape(message)}", file=sys.stderr)
    return 2


def _os_error(exc: OSError) -> str:
    reason = exc.strerror or str(exc) or type(exc).__name__
    where = exc.filename if exc.filename is not None else None
    return f"{reason}: {where}" if where is not None else reason


def main(argv: list[str] | None = None) -> int:
    """Run ``nlo-lab``; returns the exit status (0 ok, 2 bad input or a fault, 128+N on signal N)."""
    with _signals_raise():
        try:
            args = build_parser().parse_args(argv)
            with _one_warning_channel(getattr(args, "quiet", False)):
                import torch

                from nlo_lab.threads import default_threads

                torch.set_num_threads(default_threads())  # see nlo_lab.threads: one thread unless NLO_LAB_THREADS says otherwise
                status = COMMANDS[args.command](args)
                _raise_pending_signal()
                return status
        except NloLabError as exc:
            return _error(exc)
        except FileNotFoundError as exc:
            return _error(f"file not found: {exc.filename}")
        except MemoryError:
            return _error("out of memory (the input is too large for this machine; try a shorter recording)")
        except OSError as exc:  # disk full, permissions, I/O errors: the environment, not a bug
            return _error(_os_error(exc))
        except Interrupted as exc:
            name = signal.Signals(exc.signum).name
            print(f"nlo-lab: interrupted by {name}", file=sys.stderr)
            return 128 + exc.signum
        except KeyboardInterrupt:
            print("nlo-lab: interrupted by SIGINT", file=sys.stderr)
            return 128 + signal.SIGINT


if __name__ == "__main__":
    sys.exit(main())

"""``nlo-lab batch INPUT... --robot R --out DIR``: a whole corpus to robot motion on dask.distributed.

The thin shell of :func:`nlo_lab.batch.retarget_many`. Exit status 0 when every input is ok or
skipped; 1 when some failed, each with its one-line error in ``DIR/results.csv`` and one line
on stderr (``nlo-lab: error: ...``, as it happens); 2 for a usage error or a fault of the run
itself (no input, an unknown robot, an unreachable scheduler, an output folder that cannot be
written). Nothing here imports torch or dask before there is something to run, so a resumed
run over a finished corpus takes a fraction of a second.
"""

from __future__ import annotations

import argparse
import sys
import time

from nlo_lab.cli.flags import (
    MAX_SEED,
    WEIGHT_RANGE,
    UsageError,
    add_hand_flags,
    add_optimisation_flags,
    check_hand_flags,
    hand_settings,
    ranged_int,
)
from nlo_lab.errors import escape
from nlo_lab.settings import HANDSHAPE_WEIGHTS, WORKERS_RANGE  # workers: of the local cluster (the library's bound too)

__all__ = ["WORKERS_RANGE", "NEEDS_TORCH", "add_parser", "run"]

NEEDS_TORCH = False  # the workers import it; this process decides what to run without it (a resume takes a fraction of a second)


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("batch", help="retarget a whole corpus (files, folders, manifests) on a dask cluster")
    p.add_argument("inputs", nargs="+", metavar="INPUT",
                   help="files; folders (searched recursively for .pose .h5 .npz .mp4 .mov .webm .avi); "
                        "manifest .txt files (one path per line, relative to the manifest's folder)")
    p.add_argument("--robot", required=True, help="yumi, nao, pepper, or a robot spec .json")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output folder: one folder per input (trajectory.npz, trajectory.csv, summary.json) and results.csv")
    p.add_argument("--workers", type=ranged_int(*WORKERS_RANGE), default=None,
                   help="worker processes of the local cluster (default: the cores available)")
    p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help="run on this dask scheduler (tcp://HOST:PORT) instead; its cluster is never resized or shut down")
    p.add_argument("--no-resume", action="store_true",
                   help="run every input again (default: skip those done with the same content and settings)")
    p.add_argument("--retry-failed", action="store_true",
                   help="run inputs that failed before on unchanged content again (default: keep their failed rows)")
    add_optimisation_flags(p, "ee=1000,ori=100,smooth=10")
    add_hand_flags(p)
    p.add_argument("--seed", type=ranged_int(0, MAX_SEED), default=0,
                   help="seed of the random initialisation, 0..2^32-1 (default: 0)")
    p.add_argument("--viewer", action="store_true", help="also write each input's viewer.html")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr (failures are still listed)")
    return p


def _check(args):
    """Flags that contradict each other, weights out of their stated range and hand flags on a robot without hands,
    before any work; the weights to run (``--handshape``'s under ``--weights``)."""
    from nlo_lab.batch import BatchSettings

    if args.scheduler and args.workers is not None:
        raise UsageError("nlo-lab batch: --workers sizes the local cluster; with --scheduler the cluster's own workers run")
    if args.no_resume and args.retry_failed:
        raise UsageError("nlo-lab batch: --retry-failed has no effect with --no-resume (every input runs)")
    weights = BatchSettings(args.robot, weights=args.weights).weights
    lo, hi = WEIGHT_RANGE
    if isinstance(weights, str):
        raise UsageError(f"nlo-lab batch: --weights: expected KEY=VALUE pairs separated by commas, got {weights!r}")
    for name, value in weights:
        if not lo <= value <= hi:  # NaN fails this too
            raise UsageError(f"nlo-lab batch: --weights: weight {name}={value!r} must be in [{lo:g}, {hi:g}]")
    hand = hand_settings(args)
    if hand["hand_search"] or hand["hand_slowdown"] != 1.0:  # on a robot without hands: refused here, naming the flag
        from nlo_lab.robot import load_robot

        check_hand_flags(args, load_robot(args.robot), "batch")
    return {**HANDSHAPE_WEIGHTS, **dict(weights)} if args.handshape else args.weights


def run(args) -> int:
    from tqdm import tqdm

    from nlo_lab.batch import RESULTS_FILE, retarget_many

    weights = _check(args)
    start = time.perf_counter()

    def on_row(row: dict) -> None:
        if row["status"] == "failed":
            tqdm.write(f"nlo-lab: error: {row['error']}", file=sys.stderr)  # above the bar, if there is one

    table = retarget_many(args.inputs, args.robot, args.out, init=args.init, iterations=args.iters, seed=args.seed,
                          weights=weights, viewer=args.viewer, **hand_settings(args), workers=args.workers,
                          scheduler=args.scheduler,
                          resume=not args.no_resume, retry_failed=args.retry_failed, progress=not args.quiet, on_row=on_row)
    rows = table.to_dict("records") if hasattr(table, "to_dict") else table
    counts = {status: sum(r["status"] == status for r in rows) for status in ("ok", "skipped", "failed")}
    print(f"batch: {counts['ok']} ok, {counts['skipped']} skipped, {counts['failed']} failed of {len(rows)} inputs "
          f"in {time.perf_counter() - start:.1f} s; wrote {escape(args.out)}/{RESULTS_FILE}")
    return 1 if counts["failed"] else 0

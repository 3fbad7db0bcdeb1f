"""A long recording through the whole command line: time, peak memory, viewer size (prints a table).

    python benchmarks/long_recording.py [--robot yumi] [--frames 1000 5000 10000] [--iters 100] [--no-write]

Each length is a two-arm, two-hand recording made by concatenating clips of the
synthetic test split (20 fps: 10,000 frames are 8 min 20 s), saved as ``.npz`` and
retargeted by ``nlo-lab retarget FILE --robot ROBOT --out DIR --json`` in a fresh
process (default settings unless ``--iters``). Printed per length: wall time of the
whole command (imports, reading, optimisation, metrics, writing), its CPU time
(user + system: what the wall time would be alone on a core; the command runs one
torch thread, see nlo_lab.threads), the process's peak resident memory (``ru_maxrss``), the size of ``viewer.html``, and memory per
frame above the 1,000-frame run (linear growth keeps it flat).

Targets (issue 16): 10,000 frames to YuMi with the defaults in <= 120 s, <= 1.5 GB
peak memory, ``viewer.html`` <= 30 MB. The table also replaces the section
``long:ROBOT`` of docs/RESULTS.md (unless ``--no-write``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import results_doc  # noqa: E402

from nlo_lab.corpus import sign_corpus  # noqa: E402
from nlo_lab.human import Demonstration, save_npz  # noqa: E402
from nlo_lab.settings import LATENT_ITERATIONS  # noqa: E402

_RUN = """
import resource, sys
from nlo_lab.cli import main
code = main(sys.argv[1:])
usage = resource.getrusage(resource.RUSAGE_SELF)
print("MAXRSS_KB", usage.ru_maxrss, "CPU_S", usage.ru_utime + usage.ru_stime, file=sys.stderr)
sys.exit(code)
"""


def long_demo(frames: int) -> Demonstration:
    """The first ``frames`` frames of the test split's clips, repeated as needed."""
    clips = sign_corpus("test")
    keys = ("arm_positions", "arm_mask", "wrist_rotations", "wrist_mask", "finger_positions", "finger_mask")
    parts, total = [], 0
    while total < frames:
        for c in clips:
            parts.append(c)
            total += len(c)
            if total >= frames:
                break
    arrays = {k: np.concatenate([getattr(d, k) for d in parts])[:frames] for k in keys}
    return Demonstration(fps=clips[0].fps, name=f"long-{frames}", **arrays)


def run(path: Path, out: Path, robot: str, iters: int | None) -> dict:
    argv = ["retarget", str(path), "--robot", robot, "--out", str(out), "--json", "--quiet"]
    if iters is not None:
        argv += ["--iters", str(iters)]
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _RUN, *argv], capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"nlo-lab failed ({proc.returncode}): {proc.stderr.strip()}")
    fields = next(line.split() for line in proc.stderr.splitlines() if line.startswith("MAXRSS_KB"))
    rss_kb, cpu_s = int(fields[1]), float(fields[3])
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    return {
        "seconds": seconds,
        "cpu_s": cpu_s,
        "peak_mb": rss_kb / 1024,
        "viewer_mb": (out / "viewer.html").stat().st_size / 1e6,
        "retarget_s": summary["seconds"],
        "frechet_m": summary["frechet_m"],
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="yumi")
    parser.add_argument("--frames", type=int, nargs="+", default=[1000, 5000, 10000])
    parser.add_argument("--iters", type=int, default=None, help=f"default: the command line's ({LATENT_ITERATIONS})")
    parser.add_argument("--no-write", action="store_true", help="do not update docs/RESULTS.md")
    args = parser.parse_args(argv)
    print(f"nlo-lab retarget, {args.robot}, iterations {args.iters or f'default ({LATENT_ITERATIONS})'}, "
          f"NLO_LAB_THREADS={os.environ.get('NLO_LAB_THREADS', 'unset')}, {os.cpu_count()} cores")
    print(f"{'frames':>7} {'wall s':>8} {'CPU s':>7} {'retarget s':>10} {'peak MB':>8} {'MB/1k frames':>12} {'viewer MB':>9} {'frechet m':>9}")
    table = ["| frames | wall s | CPU s | retarget s | peak MB | MB per 1k frames above the first | viewer.html MB | Fréchet m |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    rows = []
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        for frames in args.frames:
            path = save_npz(long_demo(frames), Path(tmp) / f"long-{frames}.npz")
            r = run(path, Path(tmp) / f"out-{frames}", args.robot, args.iters)
            rows.append((frames, r))
            base = rows[0]
            per_k = (r["peak_mb"] - base[1]["peak_mb"]) / ((frames - base[0]) / 1000) if frames != base[0] else float("nan")
            print(f"{frames:>7} {r['seconds']:>8.1f} {r['cpu_s']:>7.1f} {r['retarget_s']:>10.1f} {r['peak_mb']:>8.0f} {per_k:>12.1f} "
                  f"{r['viewer_mb']:>9.1f} {r['frechet_m']:>9.4f}", flush=True)
            table.append(f"| {frames} | {r['seconds']:.1f} | {r['cpu_s']:.1f} | {r['retarget_s']:.1f} | {r['peak_mb']:.0f} | "
                         f"{'' if frames == base[0] else f'{per_k:.1f}'} | {r['viewer_mb']:.1f} | {r['frechet_m']:.4f} |")
    frames, r = rows[-1]
    verdict = (f"targets at {frames} frames: wall {r['seconds']:.1f} s (<= 120; CPU {r['cpu_s']:.1f} s), "
               f"peak {r['peak_mb']:.0f} MB (<= 1536), viewer {r['viewer_mb']:.1f} MB (<= 30)")
    load = f"load average (1 min) {load_before:.1f} before, {os.getloadavg()[0]:.1f} after, on {os.cpu_count()} cores"
    print(verdict)
    print(load)
    if not args.no_write:
        text = "\n".join([
            f"## Long recordings on {args.robot}", "", results_doc.stamp(),
            f"- `nlo-lab retarget FILE --robot {args.robot} --out DIR --json` in a fresh process per length"
            f" (iterations: {args.iters or 'the defaults, ' + results_doc.default_budget()}); the recording: test-split clips concatenated"
            " (two arms, two hands, 20 fps). Wall time depends on what else the machine runs; CPU time"
            " (user + system) is what one free core would take.",
            f"- {verdict}", f"- {load}", "", *table, ""])
        print(f"wrote {results_doc.update_section(f'long:{args.robot}', text)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

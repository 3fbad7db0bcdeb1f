"""Signals at any instant of a run: ``nlo-lab retarget --out`` killed at many moments, from startup to exit (prints a table).

    python benchmarks/signals.py [--signals SIGTERM SIGINT SIGHUP] [--points 24] [--no-write]

First one undisturbed run is timed (``nlo-lab retarget demo:introduction_06 --robot nao --iters 20
--out DIR --json``, in a fresh process). Then the same command is started again for each signal
and each of ``--points`` instants spread over that duration (from 5 ms after the start to past the
end, denser at the start, where the imports run) and the signal is sent then. Every run must end
with exit status 128 + signal (or 0, when the signal came after the run had finished its work, at
its exit) and at most one line on stderr, and leave the output folder holding either nothing or
the whole set (``trajectory.npz``, ``trajectory.csv``, ``viewer.html``), never a part or a
temporary folder. The table replaces the section ``signals`` of docs/RESULTS.md (unless ``--no-write``).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import results_doc  # noqa: E402

SET = ("trajectory.csv", "trajectory.npz", "viewer.html")
ARGV = ["retarget", "demo:introduction_06", "--robot", "nao", "--iters", "20", "--json"]


def run_once(folder: Path, sig: int | None, delay: float) -> dict:
    out = folder / "out"
    proc = subprocess.Popen([sys.executable, "-m", "nlo_lab.cli", *ARGV, "--out", str(out)], cwd=folder,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    start = time.perf_counter()
    if sig is not None:
        time.sleep(delay)
        if proc.poll() is None:
            proc.send_signal(sig)
    _, err = proc.communicate(timeout=600)
    seconds = time.perf_counter() - start
    entries = sorted(p.name for p in folder.iterdir() if p.name != "out")
    held = sorted(os.listdir(out)) if out.is_dir() else []
    return {"code": proc.returncode, "lines": [line for line in err.splitlines() if line.strip()], "seconds": seconds,
            "set": "whole" if held == list(SET) else "none" if not held else "part", "stray": entries}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--signals", nargs="+", default=["SIGTERM", "SIGINT", "SIGHUP"])
    parser.add_argument("--points", type=int, default=24)
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="nlo_lab_signals_") as tmp:
        base = run_once(Path(tmp), None, 0.0)
    if base["code"] != 0:
        raise SystemExit(f"the undisturbed run failed: {base}")
    total = base["seconds"]
    # denser at the start (imports), then evenly to 10 % past the end (exit)
    delays = sorted({round(0.005 * (1.6 ** k), 4) for k in range(12) if 0.005 * 1.6 ** k < total}
                    | {round(total * (i + 1) / args.points * 1.1, 4) for i in range(args.points)})
    rows, failures, outcomes = [], [], Counter()
    for name in args.signals:
        sig = getattr(signal, name)
        for delay in delays:
            with tempfile.TemporaryDirectory(prefix="nlo_lab_signals_") as tmp:
                r = run_once(Path(tmp), sig, delay)
            good = (r["code"] in (128 + sig, 0) and len(r["lines"]) <= 1 and r["set"] != "part" and not r["stray"]
                    and (r["code"] != 0 or r["set"] == "whole"))
            outcomes[name, r["code"], r["set"]] += 1
            if not good:
                failures.append((name, delay, r))
            rows.append((name, delay, r))
    lines = [f"- command: `python benchmarks/signals.py` (each run: `nlo-lab {' '.join(ARGV)} --out DIR` in a fresh process)",
             f"- an undisturbed run: {total:.2f} s wall; signals sent at {len(delays)} instants from 5 ms to {delays[-1]:.2f} s",
             f"- date: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average (1 min) {os.getloadavg()[0]:.1f} on "
             f"{os.cpu_count()} cores", "",
             "| signal | exit status | output folder | runs |", "|---|---:|---|---:|"]
    for (name, code, state), n in sorted(outcomes.items()):
        lines.append(f"| {name} | {code} | {state} | {n} |")
    lines.append("")
    lines.append(f"{len(rows)} runs; {len(failures)} with another status, more than one line on stderr, part of the set "
                 "or a temporary folder left" + (":" if failures else "."))
    for name, delay, r in failures:
        lines.append(f"- {name} at {delay:.3f} s: exit {r['code']}, {len(r['lines'])} lines {r['lines'][:2]}, set {r['set']}, "
                     f"left {r['stray']}")
    text = "\n".join(lines)
    print(text)
    if not args.no_write:
        results_doc.write_section("signals", "## Signals at any instant (issues 16 and 25)\n\n" + text)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

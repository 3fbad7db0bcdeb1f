"""Signals at any instant of a run: ``nlo-lab retarget --out`` killed at many moments, from startup to exit (prints a table).

    python benchmarks/signals.py [--signals SIGTERM SIGINT SIGHUP] [--points 24] [--no-write]

First one undisturbed run is timed (``nlo-lab retarget demo:introduction_06 --robot nao --iters 20
--out DIR --json``, in a fresh process, ``python -m nlo_lab.cli`` as a user runs it). Then the same
command is started again for each signal and each instant: 12 in the first 0.2 s (Python's own
start), 6 from the measured time of ``python -c "import nlo_lab.cli"`` on (nlo_lab's imports) and
``--points`` spread evenly to 10 % past the undisturbed run's end, and the
signal is sent then. Each run is classed:

- ``interrupted``: exit status 128 + signal, at most one line on stderr (``nlo-lab: interrupted by ...``);
- ``finished``: exit 0 with the whole set (the signal came after the run's work, at its exit);
- ``python start``: the signal came during Python's own start, before nlo_lab's entry point ran
  (the interpreter's default: killed by the signal itself, nothing said, a shell shows the same
  128 + N; or, for SIGINT, Python's ``KeyboardInterrupt`` traceback with no frame of nlo_lab's
  entry point);
- ``wrong``: anything else (a traceback, more than one line, another status).

Every run must also leave the output folder holding nothing or the whole set (``trajectory.npz``,
``trajectory.csv``, ``viewer.html``), never a part or a temporary folder. Also printed: how long
Python's own start takes here (``python -c pass`` and ``python -c "import nlo_lab.cli"``), against
which the ``python start`` instants are read. The table replaces the section ``signals`` of
docs/RESULTS.md (unless ``--no-write``); ``benchmarks/reliability.py`` runs a shorter sweep.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import statistics
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
EARLY = (0.0, 0.005, 0.01, 0.015, 0.02, 0.03, 0.04, 0.05, 0.07, 0.1, 0.14, 0.2)  # s: Python's start, then the imports


def default_signals() -> None:
    """In a child, before its program starts: SIGINT, SIGTERM and SIGHUP at their defaults, as a terminal gives them.
    Started in the background of a shell without job control (``cmd &`` in a script), this benchmark inherits SIGINT
    ignored, its children too, and a program rightly leaves an ignored signal ignored: the sweep would then measure
    runs that cannot be interrupted (seen 2026-11-26: every SIGINT run 'finished')."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)


def run_once(folder: Path, sig: int | None, delay: float) -> dict:
    out = folder / "out"
    proc = subprocess.Popen([sys.executable, "-m", "nlo_lab.cli", *ARGV, "--out", str(out)], cwd=folder,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=default_signals)
    start = time.perf_counter()
    if sig is not None:
        time.sleep(delay)
        if proc.poll() is None:
            proc.send_signal(sig)
    _, err = proc.communicate(timeout=600)
    seconds = time.perf_counter() - start
    entries = sorted(p.name for p in folder.iterdir() if p.name != "out")
    held = sorted(os.listdir(out)) if out.is_dir() else []
    lines = [line for line in err.splitlines() if line.strip()]
    return {"code": proc.returncode, "lines": lines, "err": err, "seconds": seconds,
            "set": "whole" if held == list(SET) else "none" if not held else "part", "stray": entries}


def kind(r: dict, sig: int) -> str:
    """The class of one run (module docstring)."""
    if r["code"] == 128 + sig and len(r["lines"]) <= 1 and all(line.startswith("nlo-lab: interrupted by ") for line in r["lines"]):
        return "interrupted"
    if r["code"] == 0 and r["set"] == "whole" and len(r["lines"]) <= 1:
        return "finished"
    if r["code"] == -sig and not r["lines"]:
        return "python start"
    entered = re.search(r'nlo_lab/cli/(program|app)\.py", line \d+, in (main|run)', r["err"])
    if sig == signal.SIGINT and r["lines"] and r["lines"][-1] == "KeyboardInterrupt" and not entered and r["set"] == "none":
        return "python start"
    return "wrong"


def python_start_ms(repeats: int = 5) -> tuple[float, float]:
    """Median wall time [ms] of ``python -c pass`` and of ``python -c 'import nlo_lab.cli'`` (nlo_lab's first line)."""
    def median(code: str) -> float:
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            subprocess.run([sys.executable, "-c", code], check=True)
            times.append(time.perf_counter() - start)
        return 1000 * statistics.median(times)

    return median("pass"), median("import nlo_lab.cli")


def sweep(signals: list[str], points: int) -> dict:
    """Run the sweep; returns the runs, the undisturbed run's time and Python's start."""
    with tempfile.TemporaryDirectory(prefix="nlo_lab_signals_") as tmp:
        base = run_once(Path(tmp), None, 0.0)
    if base["code"] != 0:
        raise SystemExit(f"the undisturbed run failed: {base}")
    total = base["seconds"]
    python_ms = python_start_ms()
    first_line = python_ms[1] / 1000  # then nlo_lab's handlers are in: its imports follow
    delays = sorted(set(EARLY) | {round(first_line + extra, 3) for extra in (0.0, 0.02, 0.05, 0.1, 0.2, 0.4)}
                    | {round(total * (i + 1) / points * 1.1, 3) for i in range(points)})
    runs = []
    for name in signals:
        sig = getattr(signal, name)
        for delay in delays:
            with tempfile.TemporaryDirectory(prefix="nlo_lab_signals_") as tmp:
                r = run_once(Path(tmp), sig, delay)
            r.update(signal=name, delay=delay, kind=kind(r, sig))
            if r["set"] == "part" or r["stray"]:
                r["kind"] = "wrong"
            runs.append(r)
            print(f"{name:7} at {delay:6.3f} s: exit {r['code']:4}, {len(r['lines'])} line(s), set {r['set']:5}: {r['kind']}",
                  flush=True)
    return {"runs": runs, "total": total, "delays": delays, "python_ms": python_ms}


def report(result: dict) -> list[str]:
    """Markdown lines: the classes per signal, the latest ``python start`` instant, every ``wrong`` run."""
    runs, (bare_ms, first_line_ms) = result["runs"], result["python_ms"]
    counts = Counter((r["signal"], r["kind"], r["code"], r["set"]) for r in runs)
    late_start = max((r["delay"] for r in runs if r["kind"] == "python start"), default=None)
    wrong = [r for r in runs if r["kind"] == "wrong"]
    lines = [f"- each run: `python -m nlo_lab.cli {' '.join(ARGV)} --out DIR` in a fresh process; an undisturbed run takes "
             f"{result['total']:.2f} s wall; signals sent at {len(result['delays'])} instants from 0 to {result['delays'][-1]:.2f} s",
             f"- Python's own start here: `python -c pass` {bare_ms:.0f} ms, `python -c 'import nlo_lab.cli'` (nlo_lab's first "
             f"line, where its handlers go in) {first_line_ms:.0f} ms (medians of 5)", "",
             "| signal | class | exit status | output folder | runs |", "|---|---|---:|---|---:|"]
    lines += [f"| {s} | {k} | {c} | {o} | {n} |" for (s, k, c, o), n in sorted(counts.items())]
    lines += ["", f"{len(runs)} runs: {sum(r['kind'] in ('interrupted', 'finished') for r in runs)} ended by nlo_lab "
              "(128 + N with at most one line, or 0 with the whole set); "
              f"{sum(r['kind'] == 'python start' for r in runs)} came during Python's own start "
              f"(the latest at {late_start if late_start is not None else 0:.3f} s: killed by the signal, or SIGINT's "
              "KeyboardInterrupt from Python), nothing written; "
              f"{len(wrong)} wrong (a traceback, more lines, part of the set or a temporary folder left)"
              + (":" if wrong else ".")]
    lines += [f"- {r['signal']} at {r['delay']:.3f} s: exit {r['code']}, {len(r['lines'])} lines {r['lines'][-1:]}, "
              f"set {r['set']}, left {r['stray']}" for r in wrong]
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--signals", nargs="+", default=["SIGTERM", "SIGINT", "SIGHUP"])
    parser.add_argument("--points", type=int, default=24)
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args()
    result = sweep(args.signals, args.points)
    text = "\n".join(report(result))
    print(text)
    if not args.no_write:
        results_doc.update_section("signals", "\n".join(["## Signals at any instant (issues 16 and 25)", "", results_doc.stamp(),
                                                         text, ""]))
    return 1 if any(r["kind"] == "wrong" for r in result["runs"]) else 0


if __name__ == "__main__":
    sys.exit(main())

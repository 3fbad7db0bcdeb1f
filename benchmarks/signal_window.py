"""How soon ``nlo-lab`` takes the signals: the window of Python's own start, measured (prints a table).

    python benchmarks/signal_window.py [--runs 30] [--no-write]

A signal that comes before a program's first handler is in is the interpreter's: SIGTERM and
SIGHUP kill the process by the signal, SIGINT gives Python's ``KeyboardInterrupt`` traceback (or,
before Python put its own SIGINT handler in, kills it too). This benchmark starts ``nlo-lab
retarget demo:introduction_06 --robot nao`` ``--runs`` times each way a user starts it and reads,
from outside, the process's caught signals (``SigCgt`` of ``/proc/PID/status``, polled without
pause) from the instant before the spawn:

- Python's SIGINT handler in: the end of the window where SIGINT kills the process outright;
- the first SIGTERM handler in: nlo_lab's (``nlo_lab/__main__.py``'s first lines); from then on
  a signal ends the run with 128 + N and at most one line.

The same is measured for ``python -c`` with a SIGTERM handler as its very first statement: the
earliest any Python program of this environment can take a signal (the interpreter, ``site`` and
the ``.pth`` files of the installed packages: an editable install's finder is one of them). The
console script is the installed one's text with the import line of the entry point
pyproject.toml declares (the same, unless the install predates a change of the entry point).
Medians, minima and maxima of the runs; the table replaces the section ``signal-window`` of
docs/RESULTS.md (unless ``--no-write``).
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
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import results_doc  # noqa: E402
from signals import default_signals  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ARGV = ["retarget", "demo:introduction_06", "--robot", "nao"]
FLOOR = "import signal, time; signal.signal(signal.SIGTERM, lambda *a: None); time.sleep(30)"


def entry_point() -> tuple[str, str]:
    """``(module, function)`` of the ``nlo-lab`` entry point pyproject.toml declares."""
    return re.search(r'^nlo-lab = "(\S+):(\S+)"$', (ROOT / "pyproject.toml").read_text(), re.M).groups()


def console_script(folder: Path) -> Path:
    """The installed ``nlo-lab`` script's text with the import line of the declared entry point, in ``folder``."""
    module, func = entry_point()
    text = (Path(sys.executable).parent / "nlo-lab").read_text()
    script = folder / "nlo-lab"
    script.write_text(re.sub(r"^from \S+ import \S+$", f"from {module} import {func}", text, count=1, flags=re.M))
    script.chmod(0o755)
    return script


def caught(pid: int) -> int:
    """The process's caught signals (a bit mask, bit N-1 for signal N); 0 once it is gone."""
    try:
        with open(f"/proc/{pid}/status") as f:
            return next(int(line.split()[1], 16) for line in f if line.startswith("SigCgt:"))
    except (OSError, StopIteration):
        return 0


def once(cmd: list[str], env: dict) -> tuple[float, float] | None:
    """Seconds from before the spawn to Python's SIGINT handler and to the first SIGTERM handler."""
    start = time.monotonic()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            preexec_fn=default_signals)  # an ignored SIGINT would never get Python's handler
    sigint = None
    try:
        while proc.poll() is None:
            mask, now = caught(proc.pid), time.monotonic() - start
            if sigint is None and mask >> (signal.SIGINT - 1) & 1:
                sigint = now
            if mask >> (signal.SIGTERM - 1) & 1:
                return (sigint if sigint is not None else now), now
        return None
    finally:
        proc.kill()
        proc.wait()


def measure(runs: int) -> dict[str, list[tuple[float, float]]]:
    with tempfile.TemporaryDirectory() as tmp:
        # bytecode cached, as pip leaves an installed package (in a folder of this run: the checkout stays as it is)
        env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
                   PYTHONPYCACHEPREFIX=str(Path(tmp) / "pycache"))
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        ways = {
            "`nlo-lab ...` (the console script)": [str(console_script(Path(tmp))), *ARGV],
            "`python -m nlo_lab ...`": [sys.executable, "-m", "nlo_lab", *ARGV],
            "`python -m nlo_lab.cli ...`": [sys.executable, "-m", "nlo_lab.cli", *ARGV],
            "`python -c` with a SIGTERM handler first (the floor)": [sys.executable, "-c", FLOOR],
        }
        for cmd in ways.values():  # the first run writes the bytecode
            once(cmd, env)
        found: dict[str, list[tuple[float, float]]] = {way: [] for way in ways}
        for _ in range(runs):  # interleaved: the machine's load falls on every way alike
            for way, cmd in ways.items():
                times = once(cmd, env)
                if times is not None:
                    found[way].append(times)
    return found


def report(found: dict[str, list[tuple[float, float]]], runs: int) -> list[str]:
    def spread(values: list[float]) -> str:
        ms = [v * 1000 for v in values]
        return f"{statistics.median(ms):.1f} ({min(ms):.1f}-{max(ms):.1f})"

    lines = [f"- each way started {runs} times, interleaved, after one run that wrote the bytecode (cached, as an installed "
             "package has it); milliseconds from before the spawn, median (min-max); "
             f"the command `{' '.join(ARGV)}`, killed once measured", "",
             "| started as | Python's SIGINT handler in | first SIGTERM handler in | runs |", "|---|---:|---:|---:|"]
    lines += [f"| {way} | {spread([a for a, _ in rows])} | {spread([b for _, b in rows])} | {len(rows)} |"
              for way, rows in found.items() if rows]
    script, floor = found["`nlo-lab ...` (the console script)"], found["`python -c` with a SIGTERM handler first (the floor)"]
    if script and floor:
        ours = statistics.median(b for _, b in script) * 1000
        least = statistics.median(b for _, b in floor) * 1000
        lines += ["", f"The console script takes the signals {ours:.1f} ms after the spawn (median); a Python program whose "
                  f"first statement takes them, {least:.1f} ms: the script adds {ours - least:.1f} ms (the installer's lines: "
                  "`import sys`, and `re` in older pips'; `nlo_lab/__init__.py`, `import signal`), the rest is the interpreter's own start with "
                  "`site` and the installed packages' `.pth` files, which runs before any code of a program."]
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=30)
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args()
    text = "\n".join(report(measure(args.runs), args.runs))
    print(text)
    if not args.no_write:
        results_doc.update_section("signal-window", "\n".join(
            ["## The signal window of Python's own start (issue 25)", "", results_doc.stamp(), text, ""]))
    return 0


if __name__ == "__main__":
    sys.exit(main())

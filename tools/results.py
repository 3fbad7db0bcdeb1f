"""`make results`: every figure the docs quote, made from the code as it is.

Runs each benchmark of :data:`STEPS` in turn; each rewrites its own sections of
``docs/RESULTS.md`` (stamped with command, commit, machine, load and date by
``benchmarks/results_doc.py``)::

    python tools/results.py                 # everything (hours on 2 cores: see the estimates)
    python tools/results.py --quick         # a short run of every step, written to build/results-quick/RESULTS.md
    python tools/results.py --only paper:yumi,quality:yumi --force
    python tools/results.py --list
    python tools/results.py --check         # which sections of docs/RESULTS.md lack a stamp, and any text outside sections

Resumable: a step that finished is recorded in ``build/results[-quick]/state.json`` with the
hash of the code it ran (``results_doc.code_hash``); a second run skips it while the code is
unchanged (``--force`` runs it again). A failed step does not stop the others; the exit status
is 1 if any failed. Each step's output is shown and kept in ``build/results[-quick]/logs/``.

After a full run the check (``--check``) lists every section that is not stamped with its
command, commit, machine and date (a section left from before the stamp was complete: run its
step again) and any text outside the sections (nothing regenerates it: a benchmark should
print it).

Adding a benchmark is one line in :data:`STEPS`: a name, the script and its arguments, the
arguments of the quick run (None: not part of the quick run), what it needs, and the minutes
a full run takes on an idle 2-core machine (for the progress line).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import results_doc  # noqa: E402


@dataclass(frozen=True)
class Step:
    """One benchmark run of ``make results``.

    Attributes:
        name: unique name (``--only``/``--skip`` take it).
        script: the benchmark, relative to the repository.
        args: its arguments for the full run.
        quick: its arguments for the quick run; None: skipped by ``--quick``.
        needs: what it needs besides the package: ``"video"`` (mediapipe), ``"chromium"``.
        minutes: about how long the full run takes on an idle 2-core machine.
    """

    name: str
    script: str
    args: str = ""
    quick: str | None = ""
    needs: str = ""
    minutes: float = 1.0


# One line per benchmark (in the order they run; the longest last). The sections each writes are
# named in its docstring; docs/RESULTS.md lists them all.
STEPS: tuple[Step, ...] = (
    Step("checkpoints", "benchmarks/checkpoints.py", "", "", minutes=0.2),
    Step("fk", "benchmarks/fk.py", "--robot yumi --threads 1", "--robot yumi --threads 1 --runs 3", minutes=1),
    Step("retarget-speed:yumi", "benchmarks/retarget_speed.py", "--robot yumi --against c9efdba",
         "--robot yumi --rounds 1 --repeats 1 --frames 3", minutes=7),
    Step("speed:yumi", "benchmarks/speed.py", "--robot yumi", "--robot yumi --lengths 30,170 --repeats 1 --frames 3 --sequences 1 --joint-cap 30", minutes=6),
    Step("motion", "benchmarks/motion.py", "", "--robots nao --clips 2", minutes=6),
    Step("hands", "benchmarks/hands.py", "", "--no-video", needs="video", minutes=4),  # dex-retargeting: make bench-venv
    Step("long:yumi", "benchmarks/long_recording.py", "--robot yumi", "--robot yumi --frames 200 400", minutes=4),
    Step("video", "benchmarks/video.py", "", "--repeats 1 --no-cli --workers 1", needs="video", minutes=5),
    Step("live", "benchmarks/live.py", "", "--passes 1", needs="video", minutes=2),
    Step("batch", "benchmarks/batch.py", "", "--inputs 10 --iters 10 --rounds 1", needs="video", minutes=8),
    Step("reliability", "benchmarks/reliability.py", "", "--frames 2000 --points 1", minutes=8),
    Step("signals", "benchmarks/signals.py", "", "--points 2", minutes=5),
    Step("signal-window", "benchmarks/signal_window.py", "", "--runs 3", minutes=0.5),
    Step("h5-reader", "benchmarks/h5_reader.py", "", "--frames 100 --repeats 1", minutes=1.5),
    Step("headroom:nao", "benchmarks/headroom.py", "--robot nao", "--robot nao --limit 2 --steps 20", minutes=3),
    Step("headroom:pepper", "benchmarks/headroom.py", "--robot pepper", "--robot pepper --limit 2 --steps 20", minutes=3),
    Step("headroom:yumi", "benchmarks/headroom.py", "--robot yumi", "--robot yumi --limit 2 --steps 20", minutes=4),
    Step("quality:nao", "benchmarks/quality.py", "--robot nao --skip init,table3", "--robot nao --quick --skip init,table3", minutes=3),
    Step("quality:pepper", "benchmarks/quality.py", "--robot pepper --skip init,table3", "--robot pepper --quick --skip init,table3", minutes=3),
    Step("quality:yumi", "benchmarks/quality.py", "--robot yumi", "--robot yumi --quick", minutes=40),
    Step("viewer", "benchmarks/viewer.py", "--moves 5 --rounds 3", "--moves 1 --rounds 1", needs="chromium", minutes=5),
    Step("paper:nao", "benchmarks/paper.py", "--robots nao", "--robots nao --quick", minutes=10),  # Table II, auto-decoder
    Step("paper:pepper", "benchmarks/paper.py", "--robots pepper", None, minutes=10),
    Step("paper:yumi", "benchmarks/paper.py", "--robots yumi", None, minutes=25),  # + the departures (YuMi's)
    Step("robot-init", "benchmarks/robot_init.py", "", "--robots baxter,romeo", minutes=10),
    Step("robots", "benchmarks/robots.py", "", "--robots nao,baxter --train-seconds 60 --out build/robots-quick", minutes=90),
)


STAMP_FIELDS = ("command", "commit", "machine", "date")  # results_doc.stamp()'s lines


def check(path: Path) -> list[str]:
    """One line per section of ``path`` missing a field of the stamp, and per line of text outside the sections."""
    text = path.read_text()
    problems = []
    for m in re.finditer(r"<!-- BEGIN (\S+) -->(.*?)<!-- END \1 -->", text, re.S):
        missing = [f for f in STAMP_FIELDS if not re.search(rf"^- {f}: \S", m.group(2), re.M)]
        if missing:
            problems.append(f"section {m.group(1)}: no {', '.join(missing)} in its stamp (run its step again)")
    body = text[text.find("<!-- BEGIN "):] if "<!-- BEGIN " in text else ""
    outside = re.sub(r"<!-- BEGIN (\S+) -->.*?<!-- END \1 -->", "\0", body, flags=re.S)
    for i, part in enumerate(outside.split("\0")):
        lines = [ln for ln in part.splitlines() if ln.strip()]
        if lines:
            after = re.findall(r"<!-- END (\S+) -->", body)[i - 1] if i else "the header"
            problems.append(f"{len(lines)} line(s) outside the sections after {after}: {lines[0][:60]!r}... (no step writes them)")
    return problems


def _needs_missing(need: str) -> str | None:
    """Why a step cannot run here (None: it can)."""
    if need == "video":
        try:
            import mediapipe  # noqa: F401
        except ImportError:
            return "the video extra (mediapipe) is not installed"
    if need == "chromium" and not (shutil.which("chromium") or shutil.which("chromium-browser")):
        return "chromium is not installed"
    return None


def _fingerprint(step: Step, code: str, quick: bool) -> str:
    """What a finished step depends on: the package's code, the script, its arguments, the results helper."""
    h = hashlib.sha256(f"{code}|{step.args if not quick else step.quick}|".encode())
    for path in (ROOT / step.script, ROOT / "benchmarks" / "results_doc.py"):
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _select(names: str | None, steps: tuple[Step, ...]) -> list[Step]:
    if not names:
        return list(steps)
    wanted = [n.strip() for n in names.split(",") if n.strip()]
    known = {s.name for s in steps}
    unknown = [n for n in wanted if n not in known]
    if unknown:
        raise SystemExit(f"results: unknown step(s) {', '.join(unknown)}; --list shows them")
    return [s for s in steps if s.name in wanted]


def run(argv: list[str] | None = None, steps: tuple[Step, ...] = STEPS) -> int:
    p = argparse.ArgumentParser(description="make results: run the benchmarks that write docs/RESULTS.md")
    p.add_argument("--quick", action="store_true", help="a short run of every step, into build/results-quick/RESULTS.md (or --out)")
    p.add_argument("--out", default=None, help="the results file to write (default: docs/RESULTS.md; quick: build/results-quick/RESULTS.md)")
    p.add_argument("--only", default=None, help="comma list of steps to run")
    p.add_argument("--skip", default="", help="comma list of steps not to run")
    p.add_argument("--force", action="store_true", help="run steps that already finished with this code")
    p.add_argument("--list", action="store_true", help="list the steps and exit")
    p.add_argument("--check", action="store_true", help="list the sections of the results file without a full stamp, and text outside them")
    args = p.parse_args(argv)

    chosen = [s for s in _select(args.only, steps) if s.name not in {n.strip() for n in args.skip.split(",")}]
    if args.list:
        for s in steps:
            print(f"{s.name:<18} {s.script} {s.args}  (~{s.minutes:g} min; quick: {s.quick if s.quick is not None else 'not run'})")
        return 0
    if args.quick:
        chosen = [s for s in chosen if s.quick is not None]
    work = ROOT / "build" / ("results-quick" if args.quick else "results")
    out = Path(args.out).resolve() if args.out else (work / "RESULTS.md" if args.quick else results_doc.RESULTS)
    if args.check:
        return _report(out)
    env = dict(os.environ)
    env.setdefault("TQDM_MININTERVAL", "10")  # progress bars: a line every 10 s in the logs, not every step
    if out != results_doc.RESULTS:
        env["NLO_LAB_RESULTS"] = str(out)
    (work / "logs").mkdir(parents=True, exist_ok=True)
    state_file = work / "state.json"
    state = json.loads(state_file.read_text()) if state_file.is_file() else {}
    code = results_doc.code_hash()
    total = sum(s.minutes for s in chosen)
    print(f"results: {len(chosen)} steps into {out} (code {code}, commit {results_doc.commit()}); "
          f"{'quick run' if args.quick else f'about {total:.0f} min on an idle 2-core machine'}", flush=True)
    failed, done_minutes, start = [], 0.0, time.perf_counter()
    for i, step in enumerate(chosen, 1):
        head = f"[{i}/{len(chosen)}] {step.name}"
        key = f"{step.name}|{out}"
        fingerprint = _fingerprint(step, code, args.quick)
        if not args.force and state.get(key, {}).get("code") == fingerprint:
            print(f"{head}: done with this code at {state[key]['date']}; skipped (--force runs it again)", flush=True)
            done_minutes += step.minutes
            continue
        missing = _needs_missing(step.needs)
        if missing:
            print(f"{head}: skipped: {missing}", flush=True)
            continue
        cmd = [sys.executable, step.script, *(step.quick if args.quick else step.args).split()]
        if not args.quick:
            left = total - done_minutes
            print(f"{head}: {' '.join(cmd[1:])} (~{step.minutes:g} min; ~{left:.0f} min of steps left)", flush=True)
        else:
            print(f"{head}: {' '.join(cmd[1:])}", flush=True)
        t0 = time.perf_counter()
        log = work / "logs" / f"{step.name.replace(':', '_')}.log"
        with open(log, "w") as fh:
            proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
            assert proc.stdout is not None
            for line in proc.stdout:
                fh.write(line)
                if not args.quick:
                    sys.stdout.write("    " + line)
            status = proc.wait()
        seconds = time.perf_counter() - t0
        done_minutes += step.minutes
        if status != 0:
            failed.append(step.name)
            print(f"{head}: FAILED (exit {status}) after {seconds:.0f} s; log {log.relative_to(ROOT)}", flush=True)
            continue
        state[key] = {"code": fingerprint, "date": time.strftime("%Y-%m-%d %H:%M %Z"), "seconds": round(seconds, 1)}
        state_file.write_text(json.dumps(state, indent=1, sort_keys=True))
        print(f"{head}: done in {seconds:.0f} s", flush=True)
    print(f"results: {len(chosen) - len(failed)} of {len(chosen)} steps done in {time.perf_counter() - start:.0f} s; "
          + (f"failed: {', '.join(failed)}" if failed else f"sections in {out}"), flush=True)
    if out.is_file() and not args.quick and not args.only:
        _report(out)
    return 1 if failed else 0


def _report(out: Path) -> int:
    """Print :func:`check`'s findings on ``out``; 1 if there are any."""
    problems = check(out) if out.is_file() else [f"no results file {out}"]
    for p in problems:
        print(f"results check: {p}", flush=True)
    if not problems:
        print(f"results check: every section of {out.name} is stamped (command, commit, machine, date)", flush=True)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(run())

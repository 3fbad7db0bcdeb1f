"""Throughput of ``nlo-lab batch`` on the real recordings, and the targets of issue 29 (PASS/FAIL).

    nice -n 10 python benchmarks/batch.py [--inputs 40] [--robot yumi] [--iters 100] [--rounds 2] [--no-write] [--keep DIR]

The corpus: the real MediaPipe recordings (``../shared/data/pose/*.pose`` when present, and
``assets/recordings``: a ``.pose`` and the sample video), copied into numbered folders until there
are at least ``--inputs`` inputs. Each run is a fresh process, as a user runs it (interpreter start
and imports included):

1. a plain loop over ``retarget`` in one process (one torch thread, the video's pose estimation on
   one core; the same files written): the engine's baseline;
2. ``nlo-lab batch --workers 1`` and ``--workers 2`` (a LocalCluster), each into a fresh folder;
   and two plain loops side by side, each over every other input (what two cores give this very
   work, shared caches and memory included: the 2-worker speed-up's real ceiling); these four timed
   runs are repeated ``--rounds`` times in alternating order (loop, two loops, 1, 2 workers; then the
   reverse; ...) so that a load that comes or goes during the run weighs on each alike, and the
   ratios are taken of their medians (each round's 2-worker speed-up is printed too);
3. the last 2-worker run again over its finished folder (the resume);
4. ``nlo-lab batch --scheduler`` on a separately started ``dask scheduler`` and two ``dask worker``
   processes over loopback, one of which is killed with SIGKILL mid-run.

First a calibration: how much more throughput the machine gives two CPU-bound processes at once
than one (2.0 on an idle 2-core machine; a shared one gives less, and the 2-worker speed-up cannot
beat it). It prints the times (wall, the CPU seconds of every process of the run, and the inputs' own
time: reading, pose estimation and retargeting summed over the inputs, which splits a run's wall time
into the per-input work and the rest: start, engine, writing, end), then each
target with PASS or FAIL: 2 workers >= 1.6x the throughput of 1; 1 worker within 10 % of the plain
loop; the resumed run < 5 % of the first run's time; the kill -9 run with every input ok (and the
cluster left running); results identical across 1 and 2 workers; everything listening on 127.0.0.1
only (the sockets of every process, as ``ss -ltnp`` shows them). Rewrites the ``batch`` section of
docs/RESULTS.md unless ``--no-write``.

A timing target is judged only on a quiet machine: when the calibration gives less than the 1.6x
target, the 2-worker speed-up cannot reach it and is marked NOT JUDGED (with the ratio measured);
when the 1-minute load average at the start was above :data:`QUIET_LOAD`, the two timing ratios
are marked PROVISIONAL (other processes shared the cores unevenly between the runs). The other
targets (resume share, kill -9, identical results, loopback) hold or not whatever the load.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import psutil
from results_doc import ROOT, stamp, update_section

SHARED_POSE = ROOT.parent / "shared" / "data" / "pose"
RECORDINGS = ROOT / "assets" / "recordings"
TARGET_SPEEDUP, TARGET_OVERHEAD, TARGET_RESUME = 1.6, 0.10, 0.05
QUIET_LOAD = 1.0  # 1-min load average at the start above which the timing ratios are provisional (2 workers need 2 cores)
COMMAND = "nice -n 10 .venv/bin/python benchmarks/batch.py"  # from the checkout, ../shared/data/pose beside it when present


def uptime() -> str:
    """What ``uptime`` says (its load averages over 1, 5 and 15 minutes), on one line."""
    try:
        return " ".join(subprocess.run(["uptime"], capture_output=True, text=True, timeout=10).stdout.split())
    except (OSError, subprocess.SubprocessError):
        loads = os.getloadavg()
        return "load average: " + ", ".join(f"{x:.2f}" for x in loads)


def verdict(ok: bool, caveat: str | None = None) -> str:
    """PASS or FAIL, then why the measurement cannot settle it here (a timing on a busy machine), if it cannot."""
    mark = "PASS" if ok else "FAIL"
    return mark if caveat is None else f"{mark}, {caveat}"


def sources() -> list[Path]:
    shared = sorted(SHARED_POSE.glob("*.pose")) if SHARED_POSE.is_dir() else []
    return shared + sorted(RECORDINGS.glob("*.pose")) + sorted(RECORDINGS.glob("*.mp4"))


def build_corpus(folder: Path, n: int) -> list[Path]:
    """Copies of the real recordings in folders take_00, take_01, ... until there are at least ``n``."""
    files = []
    for take in range(math.ceil(n / len(sources()))):
        for src in sources():
            dst = folder / f"take_{take:02d}" / f"{src.parent.name}_{src.name}"
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(src, dst)
            files.append(dst)
    return files


def plain_loop(inputs: list[Path], out: Path, robot: str, iters: int) -> None:
    """The baseline, run as its own process: one model, one input after the other, the same files written.

    Prints (JSON, one line) the inputs' own time: reading (the video's pose estimation included) and
    retargeting, summed over the inputs: what ``results.csv``'s ``seconds`` counts in a batch, so the
    two runs split alike into the inputs' own time and the rest (start, engine, writing, end)."""
    from nlo_lab.batch import BatchSettings, find_inputs, write_output_folder
    from nlo_lab.human import load_demonstration, load_video

    retargeter = BatchSettings(robot, iterations=iters).build()
    own = 0.0
    for item in find_inputs(inputs, out):
        start = time.perf_counter()
        demo = load_video(item.path, threads=1) if item.is_video else load_demonstration(item.path)
        result = retargeter(demo)
        own += time.perf_counter() - start
        write_output_folder(out / item.name, result, demo, retargeter.robot, viewer=False)
    print(json.dumps({"inputs_seconds": own}))


def inputs_seconds(kind: str, out: Path, done: list[subprocess.CompletedProcess]) -> float:
    """The inputs' own time of a finished run (see :func:`plain_loop`): the plain loops say it; a batch's is
    the sum of its ``results.csv`` ``seconds`` (each input's time on its worker, pose estimation included)."""
    if kind in ("loop", "pair"):
        return sum(json.loads(proc.stdout.strip().splitlines()[-1])["inputs_seconds"] for proc in done)
    return sum(float(r["seconds"] or 0.0) for r in rows(out))


SPIN = "import time\nend = time.process_time() + {seconds}\nn = 0\nwhile time.process_time() < end:\n    n += 1\nprint(n)"


def parallel_capacity(seconds: float = 4.0) -> float:
    """How much more the machine gives two processes at once than one: the same CPU-bound loop of ``seconds``
    CPU seconds in one process, then in two side by side; the ratio of their wall times x 2 (2.0 on an idle
    2-core machine). The ceiling of the 2-worker speed-up here and now."""
    cmd = [sys.executable, "-c", SPIN.format(seconds=seconds)]
    one, _ = timed(cmd)
    start = time.perf_counter()
    procs = [subprocess.Popen(cmd, stdout=subprocess.DEVNULL) for _ in range(2)]
    for p in procs:
        p.wait()
    return 2 * one / (time.perf_counter() - start)


def plain_pair(files: list[Path], out: Path, robot: str, iters: int) -> tuple[float, list[subprocess.CompletedProcess]]:
    """Two plain loops side by side, each over every other input: the same work as one plain loop over the corpus,
    on two processes that share nothing. Their wall time (until both end) against the plain loop's is what two
    cores give this very work here (caches and memory shared): the ceiling of the 2-worker speed-up, which a
    spinning loop (:func:`parallel_capacity`) does not see."""
    start = time.perf_counter()
    procs = [subprocess.Popen([str(c) for c in plain_cmd(out / half, files[i::2], robot, iters)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for i, half in enumerate(("a", "b"))]
    done = []
    for proc in procs:
        stdout, stderr = proc.communicate()
        done.append(subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr))
    return time.perf_counter() - start, done


def plain_cmd(out: Path, inputs: list[Path], robot: str, iters: int) -> list:
    return [sys.executable, __file__, "--plain-loop", out, *inputs, "--robot", robot, "--iters", iters]


def children_cpu() -> float:
    """CPU seconds (user + system) of every ended and waited-for descendant of this process."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed(cmd: list, **options) -> tuple[float, subprocess.CompletedProcess]:
    start = time.perf_counter()
    proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, **options)
    return time.perf_counter() - start, proc


def listening(pids) -> set[str]:
    """``ip:port`` of every socket the processes ``pids`` and their children listen on."""
    found = set()
    for pid in pids:
        try:
            procs = [psutil.Process(pid), *psutil.Process(pid).children(recursive=True)]
        except psutil.Error:
            continue
        for proc in procs:
            try:
                found |= {f"{c.laddr.ip}:{c.laddr.port}" for c in proc.net_connections(kind="inet") if c.status == psutil.CONN_LISTEN}
            except psutil.Error:
                pass
    return found


def ss_lines(pids) -> list[str]:
    """What ``ss -ltnp`` says about the processes ``pids`` and their children (when ss is installed)."""
    if not shutil.which("ss"):
        return []
    tree = set()
    for pid in pids:
        try:
            tree |= {pid, *(c.pid for c in psutil.Process(pid).children(recursive=True))}
        except psutil.Error:
            pass
    text = subprocess.run(["ss", "-ltnp"], capture_output=True, text=True).stdout
    return [line for line in text.splitlines() if any(f"pid={p}," in line for p in tree)]


def batch_cmd(corpus: Path, out: Path, robot: str, iters: int, *extra) -> list:
    return [sys.executable, "-m", "nlo_lab.cli", "batch", corpus, "--robot", robot, "--out", out, "--iters", str(iters), *extra]


def run_watched(cmd: list) -> tuple[float, int, set[str], list[str]]:
    """Run ``cmd``, noting what its processes listen on while it runs."""
    start = time.perf_counter()
    proc = subprocess.Popen([str(c) for c in cmd], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    seen, lines = set(), []
    while proc.poll() is None:
        now = listening([proc.pid])
        if now - seen:
            lines = ss_lines([proc.pid]) or lines
        seen |= now
        time.sleep(0.5)
    out, err = proc.communicate()
    if proc.returncode not in (0, 1):
        print(err, file=sys.stderr)
    return time.perf_counter() - start, proc.returncode, seen, lines


def rows(out: Path) -> list[dict]:
    with open(out / "results.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def same_results(a: Path, b: Path, names: list[str]) -> tuple[bool, str]:
    """Every input's trajectory (angles and times) equal in ``a`` and ``b``, and its .csv byte for byte."""
    for name in names:
        ta, tb = np.load(a / name / "trajectory.npz"), np.load(b / name / "trajectory.npz")
        if not (np.array_equal(ta["angles"], tb["angles"]) and np.array_equal(ta["time"], tb["time"])):
            return False, f"{name}: trajectory.npz differs"
        if (a / name / "trajectory.csv").read_bytes() != (b / name / "trajectory.csv").read_bytes():
            return False, f"{name}: trajectory.csv differs"
    return True, f"{len(names)} inputs: angles, times and trajectory.csv equal"


def dask_command(*args) -> list[str]:
    script = Path(sys.executable).with_name("dask")
    return [str(script), *args] if script.exists() else [sys.executable, "-m", "dask", *args]


def external_cluster(corpus: Path, out: Path, robot: str, iters: int, log: Path) -> dict:
    """``dask scheduler`` + two ``dask worker`` over loopback; one worker killed with SIGKILL once a few inputs are done."""
    from distributed import Client

    env = dict(os.environ, NLO_LAB_THREADS="1", OMP_NUM_THREADS="1")
    sched_file = log / "scheduler.json"
    procs = [subprocess.Popen(dask_command("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                           "--dashboard-address", "127.0.0.1:0", "--scheduler-file", str(sched_file)), stdout=open(log / "scheduler.log", "w"),
                              stderr=subprocess.STDOUT, env=env)]
    try:
        deadline = time.monotonic() + 60
        while not sched_file.is_file() and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        for i in range(2):
            procs.append(subprocess.Popen(dask_command("worker", address, "--nthreads", "1", "--no-nanny", "--host", "127.0.0.1",
                                                       "--no-dashboard", "--dashboard-address", "127.0.0.1:0", "--name", f"worker-{i}"),
                                          stdout=open(log / f"worker-{i}.log", "w"), stderr=subprocess.STDOUT, env=env))
        with Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=120)
        sockets = listening([p.pid for p in procs])
        ss = ss_lines([p.pid for p in procs])
        start = time.perf_counter()
        batch = subprocess.Popen([str(c) for c in batch_cmd(corpus, out, robot, iters, "--scheduler", address, "--quiet")],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        killed_after = None
        while batch.poll() is None:
            if killed_after is None and (out / "results.csv").is_file() and len(rows(out)) >= 3:
                procs[1].send_signal(signal.SIGKILL)  # the first worker, mid-run
                killed_after = len(rows(out))
            time.sleep(0.2)
        seconds = time.perf_counter() - start
        _, err = batch.communicate()
        with Client(address, timeout=30) as client:
            alive = len(client.scheduler_info()["workers"])
        return {"seconds": seconds, "exit": batch.returncode, "stderr": err.strip(), "rows": rows(out), "killed_after": killed_after,
                "workers_left": alive, "scheduler_alive": procs[0].poll() is None, "sockets": sockets, "ss": ss, "address": address}
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.terminate()
                try:
                    p.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    p.kill()


def leftovers(out: Path) -> list[str]:
    return [str(p.relative_to(out)) for p in out.rglob(".*") if p.name != ".nlo-lab-batch.lock"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--inputs", type=int, default=40, help="at least this many inputs (copies of the recordings)")
    ap.add_argument("--robot", default="yumi")
    ap.add_argument("--iters", type=int, default=100)
    ap.add_argument("--rounds", type=int, default=2,
                    help="rounds of the four timed runs, in alternating order (loop, two loops, 1, 2 workers; then the reverse; "
                         "...): the ratios are taken of their medians")
    ap.add_argument("--no-write", action="store_true", help="print only; leave docs/RESULTS.md alone")
    ap.add_argument("--keep", type=Path, default=None, help="work in this folder and keep it (default: a temporary one)")
    ap.add_argument("--plain-loop", nargs="+", metavar="OUT INPUT", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.plain_loop:
        return plain_loop([Path(p) for p in args.plain_loop[1:]], Path(args.plain_loop[0]), args.robot, args.iters)
    if args.rounds < 1:
        ap.error("--rounds must be at least 1")

    work = args.keep or Path(tempfile.mkdtemp(prefix="nlo_lab_batch_bench_"))
    work.mkdir(parents=True, exist_ok=True)
    corpus = work / "corpus"
    files = build_corpus(corpus, args.inputs)
    load_start, uptime_start = os.getloadavg()[0], uptime()
    print(f"corpus: {len(files)} inputs ({len(files) // len(sources())} copies of {', '.join(s.name for s in sources())}); "
          f"robot {args.robot}, {args.iters} iterations; {os.cpu_count()} cores, niceness {os.nice(0)}, load average {load_start:.1f}")

    capacity = parallel_capacity()
    print(f"  the machine gives two processes at once {capacity:.2f}x the throughput of one (2.00 when idle): "
          "the ceiling of the 2-worker speed-up now")
    runs = {"loop": "plain loop over retarget, one process", "pair": "two plain loops side by side, half each",
            "w1": "nlo-lab batch --workers 1", "w2": "nlo-lab batch --workers 2"}
    walls: dict[str, list[float]] = {k: [] for k in runs}
    cpus: dict[str, list[float]] = {k: [] for k in runs}
    owns: dict[str, list[float]] = {k: [] for k in runs}  # the inputs' own time, summed (see plain_loop)
    codes: dict[str, list[int]] = {k: [] for k in runs}
    local_sockets: set[str] = set()
    local_ss: list[str] = []
    cpu_mark = [children_cpu()]

    def run(kind: str, rnd: int) -> None:
        out = work / f"{kind}_{rnd}"
        if kind in ("loop", "pair"):
            if kind == "loop":
                seconds, proc = timed(plain_cmd(out, [corpus], args.robot, args.iters))
                done = [proc]
            else:
                seconds, done = plain_pair(files, out, args.robot, args.iters)
            for proc in done:
                if proc.returncode:
                    sys.exit(f"the plain loop failed:\n{proc.stderr[-3000:]}")
            code = 0
        else:
            seconds, code, sockets, ss = run_watched(batch_cmd(corpus, out, args.robot, args.iters, "--workers", kind[1], "--quiet"))
            local_sockets.update(sockets)
            local_ss[:] = ss or local_ss
            done = []
        cpu = children_cpu() - cpu_mark[0]  # the run's processes, all of them (they have ended)
        cpu_mark[0] += cpu
        walls[kind].append(seconds)
        cpus[kind].append(cpu)
        codes[kind].append(code)
        owns[kind].append(inputs_seconds(kind, out, done))
        print(f"  round {rnd + 1}: {runs[kind]:<40} {seconds:8.1f} s  {len(files) / seconds:6.2f} inputs/s  CPU {cpu:7.1f} s  "
              f"inputs' own {owns[kind][-1]:6.1f} s  "
              f"(load {os.getloadavg()[0]:.1f})", flush=True)

    for rnd in range(args.rounds):  # alternating order: a load that comes or goes during the run weighs on each alike
        for kind in (runs if rnd % 2 == 0 else reversed(list(runs))):
            run(kind, rnd)
    med = {k: float(np.median(v)) for k, v in walls.items()}
    med_cpu = {k: float(np.median(v)) for k, v in cpus.items()}
    med_own = {k: float(np.median(v)) for k, v in owns.items()}
    last_w2 = work / f"w2_{args.rounds - 1}"
    first_rows = {"1 worker": rows(work / "w1_0"), "2 workers": rows(work / "w2_0")}
    resume_s, resume_proc = timed(batch_cmd(corpus, last_w2, args.robot, args.iters, "--workers", "2", "--quiet"))
    resumed = rows(last_w2)
    print(f"  {'nlo-lab batch --workers 2, resumed':<49} {resume_s:8.2f} s  "
          f"({sum(r['status'] == 'skipped' for r in resumed)} skipped, exit {resume_proc.returncode})")
    ext = external_cluster(corpus, work / "ext", args.robot, args.iters, work)
    ext_ok = sum(r["status"] == "ok" for r in ext["rows"])
    print(f"  {'dask scheduler + 2 dask workers, one kill -9':<49} {ext['seconds']:8.1f} s  {ext_ok}/{len(ext['rows'])} ok, "
          f"exit {ext['exit']}, killed after {ext['killed_after']} rows; workers left {ext['workers_left']}")

    names = [r["output"] for r in first_rows["1 worker"]]
    all_ok = all(r["status"] == "ok" for v in first_rows.values() for r in v) and all(c == 0 for k in ("w1", "w2") for c in codes[k])
    same, same_note = same_results(work / "w1_0", work / "w2_0", names)
    for rnd in range(1, args.rounds):  # every round's outputs too
        for kind in ("w1", "w2"):
            again, note = same_results(work / "w1_0", work / f"{kind}_{rnd}", names)
            if not again:
                same, same_note = False, f"round {rnd + 1}, {runs[kind]}: {note}"
    same_loop, _ = same_results(work / "w1_0", work / "loop_0", names)
    sockets = local_sockets | ext["sockets"]
    speedup, overhead, resume_share = med["w1"] / med["w2"], med["w1"] / med["loop"] - 1, resume_s / med["w2"]
    ceiling = med["loop"] / med["pair"]  # what two cores gave this work, engine aside
    per_round = [w1 / w2 for w1, w2 in zip(walls["w1"], walls["w2"], strict=True)]
    uptime_end = uptime()
    busy = None if load_start <= QUIET_LOAD else f"PROVISIONAL (load {load_start:.1f} on {os.cpu_count()} cores at the start)"
    speed_mark = verdict(speedup >= TARGET_SPEEDUP, busy)
    if capacity < TARGET_SPEEDUP:  # the machine itself cannot give the target: nothing is judged
        speed_mark = (f"NOT JUDGED (the machine gave two spinning processes only {capacity:.2f}x one's: no 2-worker run can "
                      f"show {TARGET_SPEEDUP}x here)")
    ext_pass = (ext["exit"] == 0 and ext_ok == len(files) == len(ext["rows"]) and ext["killed_after"] is not None
                and ext["workers_left"] == 1 and ext["scheduler_alive"] and not leftovers(work / "ext"))
    rounds_text = f"median of {args.rounds} rounds" if args.rounds > 1 else "one round"
    targets = [
        (speed_mark,
         f"2 workers vs 1: {speedup:.2f}x the throughput ({rounds_text}; each round's: "
         f"{', '.join(f'{r:.2f}x' for r in per_round)}; target >= {TARGET_SPEEDUP}x; the machine gave two spinning processes "
         f"{capacity:.2f}x one's, and two plain loops over half the corpus each {ceiling:.2f}x the plain loop's throughput: "
         f"the workers reached {speedup / ceiling:.0%} of what two cores gave this work)"),
        (verdict(overhead <= TARGET_OVERHEAD, busy),
         f"1 worker vs the plain loop: {overhead * 100:+.1f} % time ({rounds_text}; target within {TARGET_OVERHEAD:.0%}; "
         f"CPU seconds of all processes: {(med_cpu['w1'] / med_cpu['loop'] - 1) * 100:+.1f} %; where the time goes: the inputs' "
         f"own time (reading, pose estimation, retargeting) {med_own['loop']:.1f} s in the loop, {med_own['w1']:.1f} s on the worker "
         f"({(med_own['w1'] / med_own['loop'] - 1) * 100:+.1f} %); the rest (start, engine, writing, end) {med['loop'] - med_own['loop']:.1f} s "
         f"in the loop, {med['w1'] - med_own['w1']:.1f} s in the batch)"),
        (verdict(resume_share < TARGET_RESUME and resume_proc.returncode == 0 and all(r["status"] == "skipped" for r in resumed)),
         f"resumed run over the finished corpus: {resume_share * 100:.1f} % of the first run's time (target < {TARGET_RESUME:.0%})"),
        (verdict(ext_pass), f"dask scheduler + 2 dask workers, kill -9 of one after {ext['killed_after']} rows: {ext_ok}/{len(files)} "
                            f"ok, exit {ext['exit']}, the cluster left running ({ext['workers_left']} worker), no half-written folder"),
        (verdict(same and all_ok), f"results identical across 1 and 2 workers ({same_note}, every round; every input ok: {all_ok}); "
                                   f"equal to the plain loop's too: {same_loop}"),
        (verdict(bool(sockets) and all(s.startswith("127.0.0.1:") for s in sockets)),
         f"listening on 127.0.0.1 only: {len(local_sockets)} sockets of the LocalCluster runs, {len(ext['sockets'])} of the "
         f"dask scheduler and workers"),
    ]
    print(f"\nuptime at the start: {uptime_start}\nuptime at the end:   {uptime_end}")
    print("\ntargets")
    for mark, text in targets:
        print(f"  {mark}  {text}")
    print("\nwhat listened (ss -ltnp):")
    for line in local_ss + ext["ss"]:
        print("  " + " ".join(line.split()))
    if ext["stderr"]:
        print(f"\nthe --scheduler run's stderr: {ext['stderr'][:500]}")
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    if args.no_write:
        return

    def spread(values: list[float]) -> str:
        return f"{min(values):.1f}-{max(values):.1f}" if len(values) > 1 else f"{values[0]:.1f}"

    lines = [
        "## Batch: a corpus on dask.distributed (`nlo-lab batch`)",
        "",
        stamp().rstrip(),
        "- run as: the stamp's command with `nice -n 10` in front (e.g. `" + COMMAND + "`); the coordinator's re-run on a "
        "quiet machine is the one to quote",
        f"- `uptime` at the start: {uptime_start}; at the end: {uptime_end}",
        f"- a load at the start above {QUIET_LOAD:g} means other work shared the cores: the two timing ratios are then marked "
        "PROVISIONAL, and the 2-worker speed-up NOT JUDGED when the calibration is below its target",
        f"- calibration: the machine gave two CPU-bound processes at once {capacity:.2f}x the throughput of one (2.00 on an "
        "idle 2-core machine): the ceiling of the 2-worker speed-up during this run; and this work itself (two plain loops "
        f"side by side over half the corpus each, against one over all of it; shared caches and memory count): {ceiling:.2f}x",
        f"- corpus: {len(files)} inputs, copies of {', '.join(s.name for s in sources())}; robot {args.robot}, {args.iters} iterations",
        f"- {args.rounds} round(s) of the four timed runs, each in fresh processes, in alternating order (plain loop, two plain "
        "loops, 1 worker, 2 workers; then the reverse): a load that comes or goes weighs on each alike; the figures are "
        "medians over the rounds",
        "",
        "| run (a fresh process each) | wall [s] (median) | wall [s] (each round) | inputs/s | CPU [s] (all its processes) "
        "| the inputs' own time [s] (summed) |",
        "|---|---:|---:|---:|---:|---:|",
        *(f"| {label} | {med[k]:.1f} | {spread(walls[k])} | {len(files) / med[k]:.2f} | {med_cpu[k]:.1f} | {med_own[k]:.1f} |"
          for k, label in runs.items()),
        f"| nlo-lab batch --workers 2, resumed (all skipped) | {resume_s:.2f} | | | | |",
        f"| dask scheduler + 2 dask workers over loopback, one killed -9 | {ext['seconds']:.1f} | | {len(files) / ext['seconds']:.2f} | | |",
        "",
        "The inputs' own time: each input's reading (a video's pose estimation included) and retargeting, summed over the "
        "inputs (a batch's `results.csv` `seconds`; the plain loop times the same span): what is left of a run's wall time "
        "is its start (imports, model), the engine, the writing and its end.",
        "",
        *(f"- **{mark}** {text}" for mark, text in targets),
    ]
    print(f"wrote {update_section('batch', chr(10).join(lines))} (section batch)")


if __name__ == "__main__":
    main()

"""The reliability figures of issues 16 and 25, measured again (prints them; writes the RESULTS section ``reliability``).

    python benchmarks/reliability.py [--frames 20000] [--robot yumi] [--points 6] [--no-write]

1. **A long recording**: ``--frames`` frames (test-split clips concatenated, two arms and hands,
   20 fps: 20,000 frames are 16 min 40 s) through ``nlo-lab retarget FILE --robot ROBOT --out DIR
   --json`` in a fresh process with the defaults: wall time, CPU time, peak resident memory
   (``ru_maxrss``), as ``benchmarks/long_recording.py`` measures them.
2. **All or nothing**: the signal sweep of ``benchmarks/signals.py`` (SIGTERM, SIGINT, SIGHUP at 12
   early instants and ``--points`` spread over a run, each into a fresh output folder), and two
   runs started together into one output folder: each folder holds nothing or a whole set.
3. **127.0.0.1 only**: the listening sockets of ``nlo-lab lab`` (JupyterLab, as root with
   ``--allow-root``) and of ``nlo-lab batch`` (its LocalCluster: scheduler and 2 workers) and of
   every process they start, read from ``/proc`` while they run.

Exit status 1 if any figure misses its rule (a wrong signal run, a part of a set, a socket on
another address); the section is written either way.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import long_recording  # noqa: E402
import results_doc  # noqa: E402
import signals  # noqa: E402

from nlo_lab.human import save_npz  # noqa: E402


# ----------------------------------------------------------------------------- sockets from /proc
def _address(hex_addr: str) -> str:
    ip, port = hex_addr.split(":")
    raw = bytes.fromhex(ip)
    if len(raw) == 4:
        host = socket.inet_ntop(socket.AF_INET, raw[::-1])
    else:  # four 32-bit words, each little-endian
        host = socket.inet_ntop(socket.AF_INET6, b"".join(raw[i:i + 4][::-1] for i in range(0, 16, 4)))
    return f"{host}:{int(port, 16)}"


def _listening_inodes() -> dict[str, str]:
    found = {}
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with open(table) as f:
            for line in f.readlines()[1:]:
                fields = line.split()
                if fields[3] == "0A":  # LISTEN
                    found[fields[9]] = _address(fields[1])
    return found


def _tree(root: int) -> set[int]:
    parents = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    parents[int(entry)] = int(f.read().rsplit(")", 1)[1].split()[1])
            except OSError:
                continue
    tree, grew = {root}, True
    while grew:
        more = {pid for pid, parent in parents.items() if parent in tree} - tree
        tree |= more
        grew = bool(more)
    return tree


def listening_sockets(root: int) -> set[str]:
    """Every TCP address a process of ``root``'s tree listens on."""
    inodes, found = _listening_inodes(), set()
    for pid in _tree(root):
        try:
            fds = os.listdir(f"/proc/{pid}/fd")
        except OSError:
            continue
        for fd in fds:
            try:
                link = os.readlink(f"/proc/{pid}/fd/{fd}")
            except OSError:
                continue
            if link.startswith("socket:[") and link[8:-1] in inodes:
                found.add(inodes[link[8:-1]])
    return found


def watch(cmd: list[str], env: dict, *, until_listening: float | None, timeout: float) -> tuple[set[str], int | None]:
    """Run ``cmd``, sampling its tree's listening sockets every 0.2 s; stop it (SIGTERM) once it listened
    ``until_listening`` s, or let it end. Returns the sockets seen and its exit status."""
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    seen: set[str] = set()
    first = None
    start = time.monotonic()
    while proc.poll() is None and time.monotonic() - start < timeout:
        now = listening_sockets(proc.pid)
        seen |= now
        if now and first is None:
            first = time.monotonic()
        if until_listening is not None and first is not None and time.monotonic() - first > until_listening:
            break
        time.sleep(0.2)
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return seen, proc.returncode


def local_only(addresses: set[str]) -> bool:
    return bool(addresses) and all(a.startswith(("127.0.0.1:", "::1:")) for a in addresses)


# ----------------------------------------------------------------------------- the three figures
def long_run(frames: int, robot: str) -> dict:
    with tempfile.TemporaryDirectory(prefix="nlo_lab_reliability_") as tmp:
        path = save_npz(long_recording.long_demo(frames), Path(tmp) / f"long-{frames}.npz")
        return long_recording.run(path, Path(tmp) / "out", robot, None)


def two_runs_into_one_folder() -> tuple[list[int], list[str]]:
    with tempfile.TemporaryDirectory(prefix="nlo_lab_reliability_") as tmp:
        out = Path(tmp) / "out"
        procs = [subprocess.Popen([sys.executable, "-m", "nlo_lab.cli", *signals.ARGV[:-1], "--seed", str(seed), "--quiet",
                                   "--out", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for seed in (1, 2)]
        codes = [p.wait(timeout=600) for p in procs]
        return codes, sorted(os.listdir(out)) + sorted(p.name for p in Path(tmp).iterdir() if p.name != "out")


def sockets() -> dict[str, set[str]]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JUPYTERHUB_", "JPY_", "JUPYTER_"))}
    with tempfile.TemporaryDirectory(prefix="nlo_lab_reliability_") as tmp:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        lab = [sys.executable, "-m", "nlo_lab.cli", "lab", "--dir", f"{tmp}/notebooks", "--port", str(port)]
        if hasattr(os, "geteuid") and os.geteuid() == 0:
            lab.append("--allow-root")
        lab_seen, _ = watch(lab, dict(env, BROWSER="true"), until_listening=3.0, timeout=120)
        inputs = [str(save_npz(long_recording.long_demo(40 + 20 * i), Path(tmp) / f"clip-{i}.npz")) for i in range(2)]
        batch = [sys.executable, "-m", "nlo_lab.cli", "batch", *inputs, "--robot", "nao", "--out", f"{tmp}/batch",
                 "--workers", "2", "--iters", "20", "--quiet"]
        batch_seen, batch_code = watch(batch, env, until_listening=None, timeout=600)
    return {"nlo-lab lab": lab_seen, f"nlo-lab batch (exit {batch_code})": batch_seen}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20_000)
    parser.add_argument("--robot", default="yumi")
    parser.add_argument("--points", type=int, default=6, help="signal instants spread over a run (after 12 early ones)")
    parser.add_argument("--no-write", action="store_true", help="do not update docs/RESULTS.md")
    args = parser.parse_args(argv)
    load_before = os.getloadavg()[0]

    print(f"1. {args.frames} frames to {args.robot} ...", flush=True)
    long = long_run(args.frames, args.robot)
    print(json.dumps(long), flush=True)
    print("2. signals and two runs into one folder ...", flush=True)
    sweep = signals.sweep(["SIGTERM", "SIGINT", "SIGHUP"], args.points)
    codes, left = two_runs_into_one_folder()
    print("3. listening sockets ...", flush=True)
    seen = sockets()

    wrong = [r for r in sweep["runs"] if r["kind"] == "wrong"]
    both_whole = codes == [0, 0] and left == list(signals.SET)
    only_local = all(local_only(addresses) for addresses in seen.values())
    lines = [
        "### A long recording",
        f"- `nlo-lab retarget FILE --robot {args.robot} --out DIR --json` (the defaults: {results_doc.default_budget()}) on {args.frames} frames "
        f"(test-split clips concatenated, two arms and hands, 20 fps: {args.frames / 20 / 60:.1f} min), a fresh process",
        f"- wall {long['seconds']:.1f} s, CPU {long['cpu_s']:.1f} s (user + system), peak resident memory "
        f"{long['peak_mb']:.0f} MB ({long['peak_mb'] / 1024:.2f} GiB); viewer.html {long['viewer_mb']:.1f} MB; "
        f"Fréchet {long['frechet_m']:.4f} m (issue 16 measured 1.2 GiB in 107 s)",
        "", "### All or nothing",
        *signals.report(sweep),
        f"- two runs started together into one output folder: exit statuses {codes}; the folder then holds {left} "
        f"({'a whole set, nothing else' if both_whole else 'NOT one whole set'})",
        "", "### Listening sockets",
        *[f"- {name}: {', '.join(sorted(addresses)) or 'none seen'}" for name, addresses in seen.items()],
        f"- every socket on 127.0.0.1: {'yes' if only_local else 'NO'}",
        "", f"- load average (1 min) {load_before:.1f} before, {os.getloadavg()[0]:.1f} after, on {os.cpu_count()} cores",
    ]
    text = "\n".join(lines)
    print(text)
    if not args.no_write:
        body = "\n".join(["## Reliability: long recordings, all-or-nothing outputs, loopback only (issues 16 and 25)", "",
                          results_doc.stamp(), "", text, ""])
        print(f"wrote {results_doc.update_section('reliability', body)}")
    return 0 if not wrong and both_whole and only_local else 1


if __name__ == "__main__":
    sys.exit(main())

"""Mutation fuzzing of nlo_lab's readers, grown from the corpus, under time and memory limits (``make fuzz``).

    python tests/fuzz/fuzz.py [--seconds 300] [--seed 0] [--kinds pose,npz,h5,...] [--memory BYTES]
                              [--case-seconds 60] [--cli] [--grow]

Each round takes a corpus file (``tests/fuzz/corpus``), mutates it (bits flipped, bytes and
whole integers set to boundary values, cut, a piece repeated or dropped, spliced with
another file of its kind) and hands it to the library reader of its kind in a worker
process whose address space is limited to the stated ceiling (``--memory``, default 3 GiB)
and which must answer within ``--case-seconds``. A case passes when the reader returns or
raises an NloLabError whose message is one line; it fails on any other exception (a
traceback for a user), a MemoryError, a crash (a signal or an abort in a C library) or a
hang. ``--cli`` also runs every unmutated corpus file through ``nlo-lab retarget`` under
``prlimit --as``. ``--grow`` saves each failing input as ``corpus/KIND/found-HASH.EXT``
(then fix the reader: a found file must be read or refused, like every other).

Prints a table of the cases per kind and outcome; exits 1 if any case failed.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import random
import resource
import select
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import targets  # noqa: E402

INTERESTING = (0, 1, 2, 0x7F, 0x80, 0xFF, 0x7FFF, 0x8000, 0xFFFF, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF, 0xFFFFFFFFFFFFFFFF)


# ----------------------------------------------------------------------------- mutations
def mutate(data: bytes, rng: random.Random, others: list[bytes]) -> bytes:
    """One to four random edits of ``data``."""
    out = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        if not out:
            out = bytearray(b"\0")
        op = rng.randrange(8)
        at = rng.randrange(len(out))
        if op == 0:  # flip bits
            for _ in range(rng.randint(1, 8)):
                i = rng.randrange(len(out))
                out[i] ^= 1 << rng.randrange(8)
        elif op == 1:  # a boundary integer, 2, 4 or 8 bytes, little or big endian
            size = rng.choice((2, 4, 8))
            value = rng.choice(INTERESTING) & ((1 << (8 * size)) - 1)
            out[at:at + size] = value.to_bytes(size, rng.choice(("little", "big")))
        elif op == 2:  # a run of one byte value
            n = rng.randint(1, 64)
            out[at:at + n] = bytes([rng.choice((0, 0xFF, 0x7F, 0x80, 0x20))]) * n
        elif op == 3:  # cut
            del out[at:]
        elif op == 4:  # drop a piece
            del out[at:at + rng.randint(1, 256)]
        elif op == 5:  # repeat a piece
            piece = out[at:at + rng.randint(1, 256)]
            out[at:at] = piece * rng.randint(1, 4)
        elif op == 6 and others:  # splice with another file of the same kind
            other = rng.choice(others)
            cut = rng.randrange(len(other)) if other else 0
            out = out[:at] + bytearray(other[cut:])
        else:  # a random byte
            out[at] = rng.randrange(256)
    return bytes(out)


# ----------------------------------------------------------------------------- the worker
WORKER = r"""
import json, resource, sys, warnings
sys.path.insert(0, {here!r})
import targets
from nlo_lab.errors import NloLabError
warnings.simplefilter("ignore")
resource.setrlimit(resource.RLIMIT_AS, ({memory}, resource.getrlimit(resource.RLIMIT_AS)[1]))
print(json.dumps({{"ready": True}}), flush=True)
for line in sys.stdin:
    case = json.loads(line)
    try:
        targets.read(case["kind"], __import__("pathlib").Path(case["path"]))
        answer = {{"outcome": "read"}}
    except NloLabError as err:
        text = str(err)
        answer = {{"outcome": "refused" if len(text.splitlines()) == 1 else "refused in several lines", "message": text[:300]}}
    except MemoryError:
        answer = {{"outcome": "memory"}}
    except BaseException as err:
        answer = {{"outcome": "escaped " + type(err).__name__, "message": str(err)[:300]}}
    print(json.dumps(answer), flush=True)
"""


class Worker:
    """A process that reads cases in a loop under the memory limit; restarted after a crash or a hang."""

    def __init__(self, memory: int):
        self.memory = memory
        self.proc = None

    def start(self) -> None:
        code = WORKER.format(here=str(HERE), memory=self.memory)
        self.proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, text=True, env={**os.environ, "NLO_LAB_THREADS": "1"})
        ready = self._answer(300)
        if not ready or not ready.get("ready"):
            raise SystemExit("fuzz: the worker did not start (does nlo_lab import under the memory limit?)")

    def _answer(self, seconds: float):
        readable, _, _ = select.select([self.proc.stdout], [], [], seconds)
        if not readable:
            return None
        line = self.proc.stdout.readline()
        return json.loads(line) if line else None

    def run(self, kind: str, path: Path, seconds: float) -> dict:
        if self.proc is None or self.proc.poll() is not None:
            self.start()
        self.proc.stdin.write(json.dumps({"kind": kind, "path": str(path)}) + "\n")
        self.proc.stdin.flush()
        answer = self._answer(seconds)
        if answer is None:
            code = self.proc.poll()
            if code is None:
                self.proc.kill()
                self.proc.wait()
                outcome = "hang"
            else:
                outcome = f"crash (exit {code})" if code >= 0 else f"crash (signal {-code})"
            self.proc = None
            return {"outcome": outcome}
        return answer

    def close(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.stdin.close()
            self.proc.wait(timeout=30)
        self.proc = None


PASS = ("read", "refused")


def fuzz(seconds: float, seed: int, kinds, memory: int, case_seconds: float, grow: bool, log=print) -> Counter:
    """Mutate and read for ``seconds``; returns the outcomes per ``(kind, outcome)``."""
    rng = random.Random(seed)
    seeds = {kind: [(p, p.read_bytes()) for k, p, _ in targets.corpus_cases((kind,)) if p.is_file()] for kind in kinds}
    seeds = {k: v for k, v in seeds.items() if v and k != "robot"}  # robot cases are folders: their specs are fuzzed as files below
    if "robot" in kinds:
        seeds["robot"] = [(p, p.read_bytes()) for k, p, _ in targets.corpus_cases(("robot",))]
    outcomes: Counter = Counter()
    worker, video_worker = Worker(memory), Worker(memory)
    stop = time.monotonic() + seconds
    with tempfile.TemporaryDirectory(prefix="nlo_lab_fuzz_") as tmp:
        try:
            while time.monotonic() < stop:
                kind = rng.choice([k for k in sorted(seeds) for _ in range(1 if k == "video" else 4)])  # a video case takes seconds
                source, data = rng.choice(seeds[kind])
                mutated = mutate(data, rng, [d for _, d in seeds[kind]])
                if kind == "robot":  # the spec mutated, beside its own URDF
                    folder = Path(tmp) / "robot"
                    folder.mkdir(exist_ok=True)
                    for f in source.parent.iterdir():
                        (folder / f.name).write_bytes(f.read_bytes())
                    path = folder / "spec.json"
                else:
                    path = Path(tmp) / f"case{source.suffix}"
                path.write_bytes(mutated)
                if kind == "video":  # MediaPipe keeps 1.5 GiB of address space reserved after a video: videos have their own worker
                    answer = video_worker.run(kind, path, case_seconds)
                else:
                    answer = worker.run(kind, path, case_seconds)
                outcome = answer["outcome"]
                outcomes[kind, outcome] += 1
                if outcome not in PASS:
                    name = f"found-{hashlib.sha256(mutated).hexdigest()[:12]}{source.suffix if kind != 'robot' else ''}"
                    log(f"FAIL {kind} {outcome}: from {source.name}: {answer.get('message', '')[:200]}")
                    if grow:
                        target = targets.CORPUS / kind / name
                        if kind == "robot":
                            target.mkdir(parents=True, exist_ok=True)
                            for f in source.parent.iterdir():
                                (target / f.name).write_bytes(f.read_bytes())
                            (target / "spec.json").write_bytes(mutated)
                        else:
                            target.write_bytes(mutated)
                        log(f"     saved as {target.relative_to(targets.REPO)}")
        finally:
            worker.close()
            video_worker.close()
    return outcomes


def cli_sweep(memory: int, case_seconds: float, kinds, log=print) -> Counter:
    """Every corpus and special file through ``nlo-lab`` under ``prlimit --as``: exit 0 or 2 and one line."""
    outcomes: Counter = Counter()
    with tempfile.TemporaryDirectory(prefix="nlo_lab_fuzz_cli_") as tmp:
        cases = targets.corpus_cases(kinds) + targets.special_cases(Path(tmp), kinds)
        for kind, path, expect in cases:
            argv = targets.cli_argv(kind, path)
            if argv is None:
                continue
            try:
                run = subprocess.run(targets.cli_command(argv, memory), capture_output=True, text=True, timeout=case_seconds,
                                     cwd=tmp)
            except subprocess.TimeoutExpired:
                outcomes[kind, "hang"] += 1
                log(f"FAIL cli {kind} {path.name}: no answer in {case_seconds} s")
                continue
            lines = [line for line in run.stderr.splitlines() if not line.startswith("nlo-lab: warning:")]
            good = (run.returncode == 0 and not lines and expect != "bad") or (
                run.returncode == 2 and len(lines) == 1 and expect != "ok" and "out of memory" not in lines[0])
            outcome = "pass" if good else f"exit {run.returncode}"
            outcomes[kind, f"cli {outcome}"] += 1
            if not good:
                log(f"FAIL cli {kind} {path.name}: exit {run.returncode}: {run.stderr[-300:]!r}")
    return outcomes


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=300.0, help="how long to mutate (default 300)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--kinds", default=",".join(targets.KINDS), help="corpus folders to fuzz (default: all)")
    parser.add_argument("--memory", type=int, default=targets.MEMORY_CEILING, help="address space of a reader [bytes] (default 3 GiB)")
    parser.add_argument("--case-seconds", type=float, default=60.0, help="the most one case may take (default 60)")
    parser.add_argument("--cli", action="store_true", help="also run every corpus file through nlo-lab under prlimit --as")
    parser.add_argument("--grow", action="store_true", help="save failing inputs into the corpus as found-*")
    args = parser.parse_args()
    kinds = [k for k in args.kinds.split(",") if k]
    unknown = sorted(set(kinds) - set(targets.KINDS))
    if unknown:
        parser.error(f"unknown kinds {unknown}; expected some of {targets.KINDS}")
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))  # a crash leaves no core file
    start = time.perf_counter()
    outcomes = fuzz(args.seconds, args.seed, kinds, args.memory, args.case_seconds, args.grow)
    if args.cli:
        outcomes += cli_sweep(args.memory, max(args.case_seconds, 300), kinds)
    print(f"\nfuzz: seed {args.seed}, {time.perf_counter() - start:.0f} s, memory ceiling {args.memory / 2**30:.1f} GiB, "
          f"at most {args.case_seconds:g} s a case")
    print("| kind | outcome | cases |\n|---|---|---:|")
    for (kind, outcome), n in sorted(outcomes.items()):
        print(f"| {kind} | {outcome} | {n} |")
    failed = sum(n for (kind, outcome), n in outcomes.items() if outcome not in PASS and outcome != "cli pass")
    print(f"{sum(outcomes.values())} cases, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

"""Where each fuzz case goes: the library reader and the command line that read its kind, and the special files.

Shared by ``tests/fuzz/test_fuzz_corpus.py`` (the corpus, once each, inside ``make test``) and
``tests/fuzz/fuzz.py`` (``make fuzz``: the corpus mutated, under time and memory limits).

A case is ``(kind, path, expect)``: ``kind`` the corpus folder (``pose``, ``npz``, ``h5``,
``video``, ``robot``, ``checkpoint``, ``trajectory``), ``expect`` ``"ok"`` (must be read),
``"bad"`` (must be refused with one line naming the file) or ``"any"`` (either; never a
crash, a traceback or a hang).
"""

from __future__ import annotations

import contextlib
import os
import resource
import signal
import socket
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
CORPUS = HERE / "corpus"
KINDS = ("pose", "npz", "h5", "video", "robot", "checkpoint", "trajectory")
RECORDINGS = ("pose", "npz", "h5", "video")

# The stated memory ceiling (README, "Failures and faults"): nlo-lab reads or refuses any input,
# hostile or not, in this much address space (torch and MediaPipe included): `prlimit --as`.
MEMORY_CEILING = 3 << 30
# What one reading may add to a process that has already imported nlo_lab (in-process checks).
READ_BUDGET = 2 << 30


def expectation(path: Path) -> str:
    name = path.parent.name if path.name == "spec.json" else path.name
    return "ok" if name.startswith("ok-") else "bad" if name.startswith("bad-") else "any"


def corpus_cases(kinds=KINDS) -> list[tuple[str, Path, str]]:
    """Every file of the committed corpus (robot cases: each folder's ``spec.json``), plus the shipped valid controls."""
    cases = []
    for kind in kinds:
        folder = CORPUS / kind
        if kind == "robot":
            files = sorted(p / "spec.json" for p in folder.iterdir() if (p / "spec.json").is_file())
        else:
            files = sorted(p for p in folder.iterdir() if p.is_file() and not p.name.startswith("."))
        cases += [(kind, p, expectation(p)) for p in files]
    if "video" in kinds:
        cases.append(("video", REPO / "assets" / "recordings" / "signer_webcam_58f.mp4", "ok"))
    if "checkpoint" in kinds:
        cases.append(("checkpoint", REPO / "assets" / "checkpoints" / "nao.pt", "ok"))
    return cases


SPECIALS = ("fifo", "dev-zero", "socket", "sparse-64-gib", "folder", "dangling", "empty")


def make_special(special: str, path: Path) -> Path:
    """``path`` as one of :data:`SPECIALS`: a FIFO, a symlink to /dev/zero, a socket, a sparse 64 GiB file
    (more than any format allows, no disk taken), a folder, a dangling symlink, an empty file."""
    if path.exists() or path.is_symlink():
        path.unlink()
    if special == "fifo":
        os.mkfifo(path)
    elif special == "dev-zero":
        os.symlink("/dev/zero", path)
    elif special == "socket":
        s = socket.socket(socket.AF_UNIX)
        s.bind(str(path))
        s.close()
    elif special == "sparse-64-gib":
        with open(path, "wb") as f:
            f.truncate(64 << 30)
    elif special == "folder":
        path.mkdir()
    elif special == "dangling":
        os.symlink(path.with_name("gone"), path)
    elif special == "empty":
        path.write_bytes(b"")
    else:
        raise ValueError(special)
    return path


@contextlib.contextmanager
def deadline(seconds: int = 20):
    """Fail instead of hanging: a reader blocked (on a FIFO, say) is interrupted by SIGALRM with TimeoutError."""

    def expired(signum, frame):
        raise TimeoutError(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def special_cases(folder: Path, kinds=KINDS) -> list[tuple[str, Path, str]]:
    """Inputs no repository holds, made in ``folder``: a FIFO, a symlink to /dev/zero, a socket, a sparse
    64 GiB file, for each kind; a video announcing 8192x8192 pixels."""
    suffix = {"pose": ".pose", "npz": ".npz", "h5": ".h5", "video": ".mp4", "robot": ".json", "checkpoint": ".pt",
              "trajectory": ".npz"}
    cases = []
    for kind in kinds:
        for special in ("fifo", "dev-zero", "socket", "sparse-64-gib"):
            path = make_special(special, folder / f"bad-{kind}-{special}{suffix[kind]}")
            cases.append((kind, path, "bad"))
    if "video" in kinds:
        import numpy as np

        try:
            import cv2
        except ImportError:
            return cases
        path = folder / "bad-video-8192x8192.avi"
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (8192, 8192))
        writer.write(np.zeros((8192, 8192, 3), np.uint8))
        writer.release()
        cases.append(("video", path, "bad"))
    return cases


def read(kind: str, path: Path):
    """The library's reader of ``kind`` on ``path`` (what a user calls)."""
    if kind in RECORDINGS:
        from nlo_lab.human import load_demonstration

        return load_demonstration(path)
    if kind == "robot":
        from nlo_lab.robot import load_robot

        return load_robot(path)
    if kind == "checkpoint":
        from nlo_lab.model import load_checkpoint

        return load_checkpoint(path, "nao")
    if kind == "trajectory":
        from nlo_lab.inference import RobotTrajectory

        return RobotTrajectory.load(path)
    raise ValueError(kind)


def cli_argv(kind: str, path: Path) -> list[str] | None:
    """The command line that reads ``path`` (None: no command reads this kind)."""
    if kind in RECORDINGS:
        return ["retarget", str(path), "--robot", "nao", "--iters", "0", "--json", "--threads", "1"]
    if kind == "robot":
        return ["retarget", "demo:introduction_06", "--robot", str(path), "--iters", "0", "--json"]
    return None


def cli_command(argv: list[str], ceiling: int = MEMORY_CEILING) -> list[str]:
    """``nlo-lab ARGV`` under the memory ceiling (``prlimit --as``), with this interpreter and its PYTHONPATH."""
    return ["prlimit", f"--as={ceiling}", sys.executable, "-m", "nlo_lab.cli", *argv]


def current_address_space() -> int:
    """This process's address space in bytes (VmSize)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmSize:"):
            return int(line.split()[1]) * 1024
    return 0


class memory_budget:
    """``with memory_budget(n):`` lets the block add at most ``n`` bytes of address space (RLIMIT_AS), then restores the limit.

    An allocation beyond it raises MemoryError (or makes a C library abort): what the readers must never need.
    """

    def __init__(self, budget: int = READ_BUDGET):
        self.budget = budget

    def __enter__(self):
        self.previous = resource.getrlimit(resource.RLIMIT_AS)
        hard = self.previous[1]
        soft = current_address_space() + self.budget
        resource.setrlimit(resource.RLIMIT_AS, (soft if hard == resource.RLIM_INFINITY else min(soft, hard), hard))
        return self

    def __exit__(self, *exc):
        resource.setrlimit(resource.RLIMIT_AS, self.previous)
        return False

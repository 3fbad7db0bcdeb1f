"""benchmarks/signals.py: its runs can be interrupted even when the benchmark itself was started with SIGINT ignored."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

CHILD = "import signal; print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)"


def test_children_get_sigint_back_when_the_benchmark_inherited_it_ignored():
    """`benchmarks/reliability.py &` in a script starts with SIGINT ignored (no job control); its children must not."""
    code = f"""
import signal, subprocess, sys
sys.path.insert(0, {str(ROOT / "benchmarks")!r})
from signals import default_signals
signal.signal(signal.SIGINT, signal.SIG_IGN)
plain = subprocess.run([sys.executable, "-c", {CHILD!r}], capture_output=True, text=True).stdout.strip()
reset = subprocess.run([sys.executable, "-c", {CHILD!r}], capture_output=True, text=True, preexec_fn=default_signals).stdout.strip()
print(plain, reset)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["False", "True"]  # ignored is inherited; default_signals gives it back

"""A short run of the mutation fuzzer (``make fuzz`` runs it for ten minutes, and the command line on every file)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

FUZZ = Path(__file__).resolve().parent / "fuzz.py"


def test_a_short_fuzz_run_finds_nothing(tmp_path):
    """30 s of mutated corpus files (seed 0) through every reader, 3 GiB and 60 s a case: only NloLabError escapes."""
    run = subprocess.run([sys.executable, str(FUZZ), "--seconds", "30", "--seed", "0"], capture_output=True, text=True,
                         timeout=900, cwd=tmp_path)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    counts = [line for line in run.stdout.splitlines() if line.endswith(" failed")]
    assert counts and counts[-1].endswith(" 0 failed") and int(counts[-1].split()[0]) > 100, run.stdout[-2000:]


def test_mutations_change_the_input_and_are_reproducible():
    import random

    sys.path.insert(0, str(FUZZ.parent))
    import fuzz

    data = bytes(range(256)) * 4
    first = [fuzz.mutate(data, random.Random(3), [data]) for _ in range(20)]
    again = [fuzz.mutate(data, random.Random(3), [data]) for _ in range(20)]
    assert first == again and sum(m != data for m in first) >= 19

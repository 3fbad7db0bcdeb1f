"""One torch thread for our small problems, restored afterwards; NLO_LAB_THREADS overrides, validated like --threads."""

import subprocess
import sys

import pytest
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.threads import THREADS_RANGE, default_threads, env_threads, single_thread


def test_single_thread_sets_and_restores():
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        with single_thread():
            assert torch.get_num_threads() == 1
        assert torch.get_num_threads() == 2
        with single_thread(3):
            assert torch.get_num_threads() == 3
    finally:
        torch.set_num_threads(before)


def test_single_thread_limits_numpys_blas_too():
    """numpy's BLAS pool (OpenBLAS in numpy's wheels) is not torch's: single_thread limits it and restores it."""
    threadpoolctl = pytest.importorskip("threadpoolctl")
    import numpy  # noqa: F401  (its BLAS must be loaded to be seen)

    def blas_threads():
        return [p["num_threads"] for p in threadpoolctl.threadpool_info() if p["user_api"] == "blas"]

    before = blas_threads()
    if not before:
        pytest.skip("numpy has no BLAS library that threadpoolctl can see here")
    with threadpoolctl.threadpool_limits(2, user_api="blas"):
        with single_thread():
            assert blas_threads() == [1] * len(before)
        assert blas_threads() == [min(2, b) for b in before]


def test_environment_overrides(monkeypatch):
    monkeypatch.setenv("NLO_LAB_THREADS", "3")
    assert default_threads() == 3
    monkeypatch.setenv("NLO_LAB_THREADS", " 256 ")
    assert default_threads() == 256
    monkeypatch.setenv("NLO_LAB_THREADS", "")
    assert default_threads() == 1 and env_threads() is None
    monkeypatch.delenv("NLO_LAB_THREADS")
    assert default_threads() == 1 and env_threads() is None


@pytest.mark.parametrize("value, shown", [
    ("zero", "got 'zero'"), ("0", "got 0"), ("-3", "got -3"), ("257", "got 257"),
    ("100000", "got 100000"), ("1" * 20, "got 11111111111111111111"), ("9" * 100, "got 100 characters"),
    ("2.5", "got '2.5'"), ("0x10", "got '0x10'"),
])
def test_a_bad_environment_value_is_refused(value, shown, monkeypatch):
    monkeypatch.setenv("NLO_LAB_THREADS", value)
    with pytest.raises(SettingsError, match=f"NLO_LAB_THREADS must be a whole number in \\[1, 256\\], {shown}"):
        default_threads()


@pytest.mark.parametrize("n", [0, 257, 2.0, "2", True])
def test_a_bad_thread_count_is_refused(n):
    with pytest.raises(SettingsError, match="threads must be an integer in \\[1, 256\\]"):
        with single_thread(n):
            pass


def test_the_range_is_the_flags():
    assert THREADS_RANGE == (1, 256)


@pytest.mark.slow
@pytest.mark.parametrize("value", ["100000", "1" * 20, "zero"])
def test_command_line_refuses_a_bad_environment_with_one_line(value, tmp_path):
    """100000 used to crash torch (SIGSEGV), a 20-digit value gave a traceback: now one line, exit 2."""
    run = subprocess.run([sys.executable, "-m", "nlo_lab.cli", "retarget", "demo:introduction_06", "--robot", "nao", "--iters", "0"],
                         capture_output=True, text=True, cwd=tmp_path, env={**__import__("os").environ, "NLO_LAB_THREADS": value},
                         timeout=300)
    assert run.returncode == 2, run.stderr
    lines = run.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("nlo-lab: error: NLO_LAB_THREADS must be a whole number in [1, 256]"), run.stderr
    assert run.stdout == ""

"""One torch thread for our small problems, restored afterwards; NLO_LAB_THREADS overrides."""

import torch

from nlo_lab.threads import default_threads, single_thread


def test_single_thread_sets_and_restores():
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        with single_thread():
            assert torch.get_num_threads() == 1
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)


def test_environment_overrides(monkeypatch):
    monkeypatch.setenv("NLO_LAB_THREADS", "3")
    assert default_threads() == 3
    monkeypatch.setenv("NLO_LAB_THREADS", "zero")
    assert default_threads() == 1
    monkeypatch.delenv("NLO_LAB_THREADS")
    assert default_threads() == 1

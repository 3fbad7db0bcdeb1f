"""nlo_lab.model.checkpoint: the shipped checkpoints load unchanged, and loading needs no trainer."""

from __future__ import annotations

import subprocess
import sys

import pytest
import torch

from nlo_lab.model import checkpoint_path, load_pretrained
from nlo_lab.robot import load_robot


@pytest.mark.parametrize("name", ["yumi", "nao", "pepper"])
def test_shipped_checkpoints_load_bit_identically(name):
    """Every tensor of the file's state dict is in the model under the same key, with the same bits."""
    robot = load_robot(name)
    model = load_pretrained(robot)
    saved = torch.load(checkpoint_path(name), map_location="cpu", weights_only=True)["state_dict"]
    state = model.state_dict()
    assert sorted(state) == sorted(saved)
    for key, value in saved.items():
        assert state[key].dtype == robot.lower_limits.dtype
        assert torch.equal(state[key].to(value.dtype), value), key  # float32 -> float32: the same bits


@pytest.mark.slow
def test_loading_a_model_does_not_import_training():
    code = (
        "import sys; from nlo_lab.model import load_pretrained; load_pretrained('nao'); "
        "print(sorted(m for m in sys.modules if m in ('nlo_lab.training', 'nlo_lab.evaluation')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"

"""Candidate starts (TrainSettings.starts): a few seeds train a while, the lowest validation objective goes on."""

from __future__ import annotations

import json
import shutil

import pytest
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.inference import RetargetInputs
from nlo_lab.paths import ASSETS
from nlo_lab.robot import load_robot
from nlo_lab.threads import single_thread
from nlo_lab.training import TrainSettings, train_model
from nlo_lab.training.train import DEFAULT_STARTS


@pytest.fixture(scope="module")
def pose_data(nao, demonstration_from_robot, random_feasible_pose):
    train = RetargetInputs.from_demonstration(demonstration_from_robot(nao, random_feasible_pose(nao, 96, seed=31)))
    val = RetargetInputs.from_demonstration(demonstration_from_robot(nao, random_feasible_pose(nao, 32, seed=32)))
    return train, val


def short(**kw) -> TrainSettings:
    return TrainSettings(**{"epochs": 50, "batch_size": 16, "lr": 3e-3, "val_every": 2, "max_steps": 12, "progress": False, **kw})


def test_the_start_with_the_lowest_validation_goes_on_as_if_it_had_trained_alone(nao, pose_data):
    train, val = pose_data
    with single_thread(1):
        r = train_model(nao, short(starts=3, start_steps=4, seed=5), train_data=train, val_data=val)
    assert [s["seed"] for s in r.starts] == [5, 6, 7] and [s["steps"] for s in r.starts] == [4, 4, 4]
    vals = [s["val"] for s in r.starts]
    chosen = r.starts[vals.index(min(vals))]["seed"]
    assert r.model.train_info["starts"] == r.starts
    # the chosen start, trained alone from its seed on the same frames, is the same model step for step
    with single_thread(1):
        alone = train_model(nao, short(starts=1, seed=chosen), train_data=train, val_data=val)
    assert r.steps == alone.steps == 12
    assert [h["val"] for h in r.history] == [h["val"] for h in alone.history]
    a, b = r.model.state_dict(), alone.model.state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert alone.starts == [{"seed": chosen, "steps": 12, "val": alone.val_loss}]


def test_a_robot_of_ones_own_tries_three_starts_a_robot_with_a_shipped_checkpoint_one(nao, pose_data, tmp_path):
    train, val = pose_data
    with single_thread(1):
        shipped = train_model(nao, short(), train_data=train, val_data=val)
    assert len(shipped.starts) == 1  # the recipe of assets/checkpoints/nao.pt
    shutil.copy(ASSETS / "robots" / "nao.urdf", tmp_path / "nao.urdf")
    spec = json.loads((ASSETS / "robots" / "nao.json").read_text())
    (tmp_path / "mine.json").write_text(json.dumps({**spec, "name": "mine"}))
    own = load_robot(tmp_path / "mine.json")
    with single_thread(1):
        r = train_model(own, short(), train_data=train, val_data=val)
    assert DEFAULT_STARTS == 3 and len(r.starts) == 3 and all(s["steps"] == 12 // 3 for s in r.starts)
    with single_thread(1):
        continued = train_model(own, short(max_steps=3), train_data=train, val_data=val, model=r.model)
        too_short = train_model(own, short(max_steps=2), train_data=train, val_data=val)  # a third of it: no step
    assert len(continued.starts) == 1 and len(too_short.starts) == 1


@pytest.mark.parametrize("kwargs", [{"starts": 0}, {"starts": 17}, {"start_steps": 0}])
def test_start_settings_are_validated(kwargs):
    with pytest.raises(SettingsError, match=next(iter(kwargs))):
        TrainSettings(**kwargs)

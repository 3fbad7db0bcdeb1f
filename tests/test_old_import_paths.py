"""Old import paths that notebooks of earlier versions use (a learner's copies are never
overwritten by ``nlo-lab lab``): each still gives the very objects of the new home."""

from __future__ import annotations

import importlib

import pytest

OLD_TO_NEW = {
    "nlo_lab.notebook": ["nlo_lab.lab"],
    "nlo_lab.widgets": ["nlo_lab.lab"],
    "nlo_lab.video_view": ["nlo_lab.lab"],
    "nlo_lab.baselines": ["nlo_lab.evaluation", "nlo_lab.training"],
    "nlo_lab.evaluate": ["nlo_lab.evaluation"],
    "nlo_lab.train": ["nlo_lab.training", "nlo_lab.model"],
    "nlo_lab.losses": ["nlo_lab.objective"],
    "nlo_lab.human.signs": ["nlo_lab.corpus"],
    "nlo_lab.optimize": ["nlo_lab.inference"],
    "nlo_lab.retarget": ["nlo_lab.inference"],
    "nlo_lab.retime": ["nlo_lab.inference", "nlo_lab.inference.retime"],
    "nlo_lab.trajectory": ["nlo_lab.inference"],
}


@pytest.mark.parametrize("old", sorted(OLD_TO_NEW))
def test_an_old_path_gives_the_new_homes_objects(old):
    module = importlib.import_module(old)
    homes = [importlib.import_module(name) for name in OLD_TO_NEW[old]]
    assert module.__all__, old
    for name in module.__all__:
        value = getattr(module, name)
        owners = [home.__name__ for home in homes if name in home.__all__ and getattr(home, name) is value]
        assert owners, f"{old}.{name} is not the object of {' or '.join(OLD_TO_NEW[old])}"

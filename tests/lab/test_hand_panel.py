"""HandPanel (notebook 12): the hand weights on sliders re-optimise one letter; the measures follow."""

from __future__ import annotations

import math

import pytest

from nlo_lab.corpus.fingerspelling import fingerspelling_demonstration
from nlo_lab.errors import SettingsError
from nlo_lab.lab import HAND_SLIDERS, HandPanel
from nlo_lab.robot import load_robot


@pytest.fixture(scope="module")
def yumi():
    return load_robot("yumi")


def test_sliders_retarget_the_chosen_letter(yumi):
    demo = fingerspelling_demonstration("LS")
    panel = HandPanel(demo, yumi, frame=0, iterations=10, view=None)
    assert set(HAND_SLIDERS) <= set(panel.controls) and panel.error == ""
    first = dict(panel.measures)
    assert all(math.isfinite(v) for v in first.values())
    panel.controls["frame"].value = 1  # S: a fist
    assert panel.error == "" and panel.measures != first
    fist_q = panel.q.copy()
    panel.controls["tip"].value = 0.1
    panel.controls["thumb"].value = 0.1
    panel.controls["finger"].value = 0.1
    panel.controls["pinch"].value = 0.1
    assert panel.weights.tip == pytest.approx(0.1) and panel.weights.smooth == 0.0
    assert (panel.q != fist_q).any()  # the weights changed the robot's hand


def test_a_robot_without_hands_is_refused():
    with pytest.raises(SettingsError, match="no fingers"):
        HandPanel(fingerspelling_demonstration("A"), load_robot("nao"), view=None)

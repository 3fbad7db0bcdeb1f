"""HandPanel (notebook 12): the hand weights on sliders re-optimise one letter; the measures follow."""

from __future__ import annotations

import math

import numpy as np
import pytest

import nlo_lab.lab.hand_panel as hand_panel
from nlo_lab.corpus.fingerspelling import fingerspelling_demonstration
from nlo_lab.errors import SettingsError
from nlo_lab.inference import HAND_SEARCH, HANDSHAPE_SEARCH, OptimizeSettings
from nlo_lab.lab import HAND_SLIDERS, HandPanel
from nlo_lab.objective import LossWeights
from nlo_lab.pipeline import RetargetConfig
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


def test_the_panel_starts_with_the_search_it_is_given(yumi):
    panel = HandPanel(fingerspelling_demonstration("A"), yumi, iterations=10, view=None, weights=LossWeights.handshape(),
                      search=HANDSHAPE_SEARCH)
    assert panel.settings.hand_search == HANDSHAPE_SEARCH and panel.controls["search"].value == HANDSHAPE_SEARCH
    for bad in (("wrist",), ("ring", "ring")):
        with pytest.raises(SettingsError, match="hand_search"):
            HandPanel(fingerspelling_demonstration("A"), yumi, iterations=10, view=None, search=bad)


def test_the_panel_starts_with_the_pipelines_search(yumi):
    panel = HandPanel(fingerspelling_demonstration("A"), yumi, iterations=10, view=None)
    assert panel.controls["search"].value == HAND_SEARCH and panel.settings.hand_search == HAND_SEARCH


def test_a_robot_without_hands_is_refused():
    with pytest.raises(SettingsError, match="no fingers"):
        HandPanel(fingerspelling_demonstration("A"), load_robot("nao"), view=None)


def test_the_search_control_reaches_the_hand_stage(yumi):
    demo = fingerspelling_demonstration("V")
    panel = HandPanel(demo, yumi, iterations=10, view=None)
    before = panel.q.copy()
    panel.controls["search"].value = ("middle", "ring")
    assert panel.settings.hand_search == ("middle", "ring") and panel.error == ""
    assert np.abs(panel.q - before).max() > 1e-3  # the searched start moved the hand
    alone = RetargetConfig(yumi, settings=OptimizeSettings(iterations=10, hand_search=("middle", "ring")), weights=panel.weights,
                           model=panel.model, retime=False).build()(demo.slice(0, 1)).trajectory.angles[0]
    np.testing.assert_allclose(panel.q, np.asarray(alone, dtype=np.float64), atol=1e-6)  # the pipeline with that search


def test_the_preset_button_sets_weights_and_search_in_one_update(yumi):
    panel = HandPanel(fingerspelling_demonstration("B"), yumi, iterations=10, view=None)
    drawn = []
    panel._draw = drawn.append  # one per update
    panel.preset.click()
    preset = LossWeights.handshape()
    assert panel.error == "" and len(drawn) == 1
    assert {n: panel.weights.as_dict()[n] for n in HAND_SLIDERS} == pytest.approx({n: getattr(preset, n) for n in HAND_SLIDERS})
    assert panel.settings.hand_search == HANDSHAPE_SEARCH


def test_use_weights_refuses_a_bad_search_before_it_sets_any_control(yumi):
    panel = HandPanel(fingerspelling_demonstration("B"), yumi, iterations=10, view=None)
    before = {n: panel.controls[n].value for n in (*HAND_SLIDERS, "search")}
    drawn = []
    panel._draw = drawn.append
    for bad in (("thumb", "toe"), ("ring", "ring")):
        with pytest.raises(SettingsError, match="hand_search"):
            panel.use_weights(LossWeights.handshape(), bad)
    assert {n: panel.controls[n].value for n in (*HAND_SLIDERS, "search")} == before and drawn == []
    assert panel._holding is False


def test_an_update_error_is_shown_in_the_status_line(yumi, monkeypatch):
    panel = HandPanel(fingerspelling_demonstration("A"), yumi, iterations=10, view=None)

    def broken(*args, **kwargs):
        raise RuntimeError("the optimiser broke")

    monkeypatch.setattr(hand_panel, "RetargetConfig", broken)
    with pytest.raises(RuntimeError, match="optimiser broke"):
        panel.controls["tip"].value = 10.0
    assert "optimiser broke" in panel.error and "optimiser broke" in panel.status.value

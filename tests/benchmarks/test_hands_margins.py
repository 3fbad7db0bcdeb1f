"""benchmarks/hands.py's account of how sure its comparison is: the recordings added after the preset's choice are told
apart, the margins over dex-retargeting have the targets' sign, and resampling whole recordings shows a margin one
recording carries as unsure."""

from __future__ import annotations

import numpy as np
import pytest

from nlo_lab.evaluation.hands import HandScores


@pytest.fixture(scope="module")
def hands(checkout_script):
    return checkout_script("benchmarks/hands.py")


def scores(tip: float, frames: int = 20, seed: int = 0) -> HandScores:
    """A recording's hand-frames with wrist->tip errors about ``tip`` and the other measures alike for every method."""
    rng = np.random.default_rng(seed)
    pinch = rng.uniform(0.2, 1.0, frames)
    return HandScores(tip=tip + rng.normal(0, 0.1, frames), thumb=np.full(frames, 20.0), finger=np.full(frames, 30.0),
                      pinch_human=pinch, pinch_robot=pinch, side=np.ones(frames, int), frame=np.arange(frames),
                      tip_fingers=np.tile(tip, (frames, 5)))


def test_the_added_recordings_are_told_apart(hands):
    assert {p.stem for p in hands.ADDED.glob("*.pose")} == {"right_hand_121f", "left_hand_91f", "both_hands_18f", "both_hands_5f"}
    assert hands.added_after_choice("left_hand_91f")
    assert not hands.added_after_choice("holistic_both_hands_47f")
    assert not hands.added_after_choice("signer_webcam_58f (MediaPipe)")
    assert (hands.ADDED / "LICENSE.txt").read_text().startswith("MIT License")


def test_margins_are_positive_where_ours_is_ahead_of_dex_s_best(hands):
    ours = {"tip_deg": 10.0, "thumb_deg": 30.0, "pinch_r": 0.8, "finger_deg": 20.0}
    dex = [{"tip_deg": 12.0, "thumb_deg": 25.0, "pinch_r": 0.7, "finger_deg": 21.0},
           {"tip_deg": 11.0, "thumb_deg": 28.0, "pinch_r": 0.9, "finger_deg": 19.0}]
    assert hands.margins(ours, dex) == pytest.approx({"tip_deg": 1.0, "thumb_deg": -5.0, "pinch_r": -0.1, "finger_deg": -1.0})


def test_resampling_recordings_tells_a_sure_margin_from_one_recording_s(hands):
    dex = [scores(15.0, seed=i) for i in range(8)]
    everywhere = [scores(14.0, seed=10 + i) for i in range(8)]  # 1 deg ahead on every recording
    one = [scores(15.0, seed=20 + i) for i in range(7)] + [scores(5.0, seed=27)]  # as far ahead pooled, all from one
    per = {"dex, filtered": dex, "dex, unfiltered": dex, "everywhere": everywhere, "one": one}
    boot = hands.recording_bootstrap(per, ["everywhere", "one"], draws=400)
    assert boot["everywhere"]["tip_deg"].shape == (400,)
    assert np.all(boot["everywhere"]["tip_deg"] > 0.5)
    assert 0.4 < np.mean(boot["one"]["tip_deg"] > 0) < 0.9  # ahead only where the resample draws that recording
    assert np.all(boot["everywhere"]["thumb_deg"] == 0)  # the same thumb errors: no margin
    pooled = {m: HandScores.cat(v).summary() for m, v in per.items()}
    table = "\n".join(hands.bootstrap_table(pooled, boot, 8))
    row = next(line for line in table.splitlines() if line.startswith("| wrist→fingertip [deg] |"))
    everywhere_cell = row.split("|")[2]
    assert float(everywhere_cell.split("[")[0]) == pytest.approx(1.0, abs=0.1) and everywhere_cell.strip().endswith(", 100 %")
    assert "| all four at once (the target) | ahead in 0 % | ahead in 0 % |" in table  # equal thumbs: never ahead on all


def test_the_target_row_names_the_measures_where_ours_is_not_ahead(hands):
    dex = [{"tip_deg": 12.0, "thumb_deg": 25.0, "pinch_r": 0.7, "finger_deg": 21.0}]
    ahead = {"tip_deg": 11.0, "thumb_deg": 24.0, "pinch_r": 0.8, "finger_deg": 20.0}
    rows = hands.target_rows("x", ahead, dex, 0.002, 0.003, 0, 0)
    assert rows[0].endswith("| yes |") and "tip_deg: 11.00 vs 12.00" in rows[0] and "pinch_r: 0.800 vs 0.700" in rows[0]
    level = dict(ahead, tip_deg=12.0, pinch_r=0.6)  # level is not ahead
    assert hands.target_rows("x", level, dex, 0.002, 0.003, 0, 0)[0].endswith("| **no** (tip_deg, pinch_r) |")
    assert "(ratio 1.50) | yes |" in hands.target_rows("x", ahead, dex, 0.002, 0.003, 0, 0)[-1]

"""benchmarks/hands_levers.py: the hand stage's what-if levers. With every lever at its neutral value a run is the
pipeline's own; a lever moves what it names; the path search is the cheapest path within the caps; the swapped
internals are put back."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from nlo_lab.evaluation.hands import hand_scores
from nlo_lab.human import load_demonstration
from nlo_lab.model import load_pretrained
from nlo_lab.robot import load_robot

CLIP = Path(__file__).resolve().parents[2] / "assets" / "recordings" / "holistic_both_hands_47f.pose"


@pytest.fixture(scope="module")
def levers(checkout_script):
    return checkout_script("benchmarks/hands_levers.py")


@pytest.fixture(scope="module")
def setup():
    robot = load_robot("yumi")
    return robot, load_pretrained(robot), [("clip", load_demonstration(CLIP))]


def test_the_path_is_the_cheapest_within_the_caps(levers):
    """Against every path of a small problem: the per-frame cheapest values jump from end to end, the caps forbid it."""
    rng = np.random.default_rng(40)
    cost = rng.uniform(0.0, 1.0, (6, 5))  # (G, T)
    cost[0, ::2] = cost[5, 1::2] = -5.0
    values = np.linspace(0.0, 1.0, 6)
    caps = np.full(4, 0.21)  # one grid step (0.2) at a time
    path, _ = levers.path_within_caps(cost, values, caps)
    assert (np.abs(np.diff(values[path])) <= 0.21).all()
    best = min((p for p in itertools.product(range(6), repeat=5) if all(abs(a - b) <= 1 for a, b in itertools.pairwise(p))),
               key=lambda p: cost[p, np.arange(5)].sum())
    assert np.isclose(cost[path, np.arange(5)].sum(), cost[best, np.arange(5)].sum())
    assert (levers.path_within_caps(cost, values, np.full(4, 1.0))[0] == cost.argmin(0)).all()  # in reach: each frame's best


def test_neutral_levers_give_the_pipeline_s_own_handshapes(levers, setup):
    """Factors of 1 and a pinch scale of 1 run through every swapped piece and change nothing: the measures of the
    pipeline without the levers, to the bit; and the internals are the originals afterwards."""
    import nlo_lab.inference.hand_stage as hand_stage
    import nlo_lab.pipeline as pipeline
    from nlo_lab.objective.numpy_backend import HandTerms

    robot, model, items = setup
    before = (HandTerms.__init__, HandTerms.build.__func__, pipeline.refine_hands, hand_stage.step_caps)
    own = hand_scores(robot, pipeline.RetargetConfig(robot, model=model).build()(items[0][1]).trajectory.angles, items[0][1]).summary()
    neutral = levers.Levers.parse("finger:tip_dir=1,1,1,1,1 finger:tip=1,1,1,1,1 pair:thumb=1,1,1,1 pair:thumb_gap=1,1,1,1 "
                                  "pair:pinch=1,1,1,1 pinch-scale=1 caps=1")
    got = levers.run(robot, model, items, neutral)
    assert {k: got[k] for k in own} == own
    assert np.isclose(got["fingers"].mean(), own["tip_deg"])  # the per-finger errors average to the measure
    assert (HandTerms.__init__, HandTerms.build.__func__, pipeline.refine_hands, hand_stage.step_caps) == before


def test_a_lever_moves_what_it_names(levers, setup):
    """The thumb's wrist->tip direction weighed 3x: the thumb's wrist->tip error drops; a search of the index and middle
    joints before the stage changes their errors."""
    robot, model, items = setup
    plain = levers.run(robot, model, items, levers.Levers())
    thumb = levers.run(robot, model, items, levers.Levers.parse("finger:tip_dir=3,1,1,1,1"))
    assert thumb["fingers"][0] < plain["fingers"][0] - 0.1
    search = levers.run(robot, model, items, levers.Levers.parse("search=index,middle"))
    assert not np.allclose(search["fingers"][1:3], plain["fingers"][1:3])


@pytest.mark.parametrize("text", ["finger:tip_dir=3,1", "pair:tip=1,1,1,1", "search=wrist", "nonsense", "finger:tip=0,1,1,1,1"])
def test_bad_levers_are_refused(levers, text):
    with pytest.raises(SystemExit):
        levers.Levers.parse(text)


def test_the_corpus_clips_are_the_held_out_test_split_with_hands(levers):
    """``--corpus N``: the first N test clips that show a hand, none from the split the checkpoints trained on."""
    from nlo_lab.corpus import corpus_names
    from nlo_lab.evaluation.hands import hand_frames_mask

    items = levers.corpus_items(3)
    assert len(items) == 3
    assert {label for label, _ in items} <= set(corpus_names("test"))
    assert not {label for label, _ in items} & set(corpus_names("train"))
    assert all(hand_frames_mask(d).any() for _, d in items)


def test_the_recording_groups_split_the_real_recordings(levers):
    labels = ["holistic_both_hands_47f", "signer_webcam_58f (MediaPipe)", "both_hands_5f", "right_hand_121f"]
    items = [(label, None) for label in labels]
    assert [label for label, _ in levers.recording_group(items, "added")] == ["both_hands_5f", "right_hand_121f"]
    assert [label for label, _ in levers.recording_group(items, "chosen")] == labels[:2]
    assert levers.recording_group(items, "all") == items
    with pytest.raises(ValueError, match="some"):
        levers.recording_group(items, "some")


@pytest.mark.parametrize("flags", [["--corpus", "0"], ["--corpus", "many"], ["--corpus", "3", "--recordings", "added"],
                                   ["--recordings", "some"]])
def test_bad_data_flags_are_refused_before_any_work(flags):
    import subprocess
    import sys

    script = Path(__file__).resolve().parents[2] / "benchmarks" / "hands_levers.py"
    proc = subprocess.run([sys.executable, str(script), *flags], capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0
    assert "--corpus" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.skipif(not (Path(__file__).resolve().parents[2] / ".venv-bench" / "bin" / "python").is_file(),
                    reason="no .venv-bench (make bench-venv builds dex-retargeting's environment)")
def test_dex_rows_score_dex_s_hands_on_the_same_data(levers, setup):
    """``--dex``: both variants scored by the same scorer on the same hand-frames; dex-retargeting's hands follow the
    human's (its wrist->tip error below the open hand that does not move), each finger's error averages to the measure."""
    robot, _, items = setup
    rows = levers.run_dex_variants(robot, items)
    assert set(rows) == {"dex, filtered", "dex, unfiltered"}
    demo = items[0][1]
    still = hand_scores(robot, np.tile(robot.neutral_q.double().numpy(), (len(demo), 1)), demo).summary()
    for m in rows.values():
        assert m["hand_frames"] == still["hand_frames"]
        assert np.isclose(m["fingers"].mean(), m["tip_deg"])
        assert m["tip_deg"] < still["tip_deg"] - 1.0


def test_the_thumb_gate_masks_the_thumb_direction_where_its_hand_pinches(levers, setup):
    """``thumb-gate=2``: each thumb's wrist->tip direction item counts only in the frames where its own hand does not
    pinch (its largest pinch activation, from the human's thumb-fingertip distances, below 0.5), at twice its weight;
    every other item as without the lever."""
    from nlo_lab.objective import Objective, point_plan, targets_from_demonstration
    from nlo_lab.objective.numpy_backend import HandTerms
    from nlo_lab.objective.terms import pinch_activation

    robot, _, items = setup
    t = targets_from_demonstration(items[0][1], dtype=robot.lower_limits.dtype)
    plan, objective = point_plan(robot, robot.lower_limits.dtype), Objective(robot, t)

    def terms():
        return HandTerms.build(plan, t, objective.tip_mask, objective.pair_mask, plan.pinch_floor())

    plain = terms()
    with levers.applied(robot, levers.Levers.parse("thumb-gate=2")):
        gated = terms()
    d = (t.finger_tip[:, :, 1:] - t.finger_tip[:, :, :1]).norm(dim=-1) / t.hand_length[..., None]  # (T, 2, 4)
    pinching = (pinch_activation(d).amax(-1) >= 0.5).numpy()  # (T, 2)
    assert pinching.any() and (~pinching).any()  # the clip has both kinds of frame
    kinds = plain.kind.argmax(1)
    thumb_dirs = np.flatnonzero(kinds == 2)[plan.finger_index.numpy() == 0]
    expected = plain.mask[..., 0].copy()
    for i in thumb_dirs:
        expected[:, i] &= ~pinching[:, plain.side[i]]
    assert (gated.mask[..., 0] == expected).all() and (gated.mask_planes[:, 0] == expected).all()
    assert (gated.mask[..., 0] != plain.mask[..., 0]).any()
    factor = np.ones(len(kinds))
    factor[thumb_dirs] = 2.0
    np.testing.assert_array_equal(gated.kind, plain.kind * factor[:, None])


@pytest.mark.parametrize("text", ["thumb-gate=-1", "thumb-gate=1 thumb-gate-on=0", "thumb-gate=1 pair:pinch=2,1,1,1"])
def test_bad_thumb_gates_are_refused(levers, text):
    with pytest.raises(SystemExit, match="thumb-gate"):
        levers.Levers.parse(text)


def test_the_thumb_gate_on_a_hand_that_pinches_in_every_frame(levers, setup):
    """Frames 9-28 of the clip: the right hand pinches in all of them, so the gate masks its thumb's direction item in
    every frame and the terms drop it (``HandTerms.observed``); the levers find the thumb by its point, not by position."""
    robot, model, items = setup
    clip = [("pinching", items[0][1].slice(9, 29))]
    got = levers.run(robot, model, clip, levers.Levers.parse("thumb-gate=2"))
    plain = levers.run(robot, model, clip, levers.Levers())
    assert np.isfinite(got["fingers"]).all() and got["hand_frames"] == plain["hand_frames"]
    assert got["fingers"][0] != plain["fingers"][0]

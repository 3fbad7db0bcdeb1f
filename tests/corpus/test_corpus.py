"""The embedded synthetic sign corpus: organisation, determinism, split, plausibility."""

from __future__ import annotations

import re

import numpy as np
import pytest

from nlo_lab.corpus import (
    ARM_RANGES,
    FINGER_RANGES,
    HANDSHAPES,
    LOCATIONS,
    MOVEMENTS,
    PATTERNS,
    SCENARIOS,
    BodyParams,
    arm_fk,
    corpus_angles,
    corpus_clip,
    corpus_lexicon,
    corpus_names,
    is_test_combination,
    sign_corpus,
)
from nlo_lab.errors import DemonstrationError
from nlo_lab.human import Demonstration, wrist_frame_from_hand

WRIST_ACCEL_BOUND = 30.0  # [m/s^2] plausible peak wrist acceleration of signing
FINGERTIP_ACCEL_BOUND = 80.0  # [m/s^2] fingertips also swing with the wrist's rotation
WRIST_SPEED_BOUND = 2.5  # [m/s] no jumps between frames
CONTACT_MARGIN = 0.005  # [m] a hand point may come this close to the skin, never closer
ELBOW_RADIUS = 0.025  # [m] the elbow joint centre lies at least an arm's radius outside the torso


@pytest.fixture(scope="module")
def corpus():
    return {"train": sign_corpus("train"), "test": sign_corpus("test")}


@pytest.fixture(scope="module")
def all_demos(corpus):
    return corpus["train"] + corpus["test"]


def test_organisation(corpus):
    assert len(SCENARIOS) == 5
    assert sorted(s.split for s in SCENARIOS.values()) == ["test", "test", "train", "train", "train"]
    for split in ("train", "test"):
        demos = corpus[split]
        assert [d.name for d in demos] == corpus_names(split)
        scen = {d.meta["scenario"] for d in demos}
        assert scen == {n for n, s in SCENARIOS.items() if s.split == split}
        for name in scen:
            members = [d for d in demos if d.meta["scenario"] == name]
            assert len(members) >= 12 and len(members) == SCENARIOS[name].n_sequences
        for d in demos:
            assert isinstance(d, Demonstration)
            assert re.fullmatch(r"[a-z_]+_\d\d", d.name) and d.name.startswith(d.meta["scenario"])
            assert 60 <= len(d) <= 250, d.name
            assert 15 <= d.fps <= 30
            assert d.meta["split"] == split
            assert d.arm_mask.all() and d.wrist_mask.all() and d.finger_mask.all()
            assert len(d.meta["signs"]) >= 2 and len(d.meta["signs"]) == len(d.meta["sign_frames"])
    assert set(corpus_names()) == set(corpus_names("train")) | set(corpus_names("test"))
    assert len(set(d.meta["signer"] for d in corpus["train"])) >= 4


def test_timing(all_demos):
    all_gaps = []
    for d in all_demos:
        frames = np.array(d.meta["sign_frames"])
        assert frames[0, 0] > 0 and frames[-1, 1] < len(d)  # starts and ends at rest
        durations = (frames[:, 1] - frames[:, 0] - 1) / d.fps
        assert np.all((durations >= 0.5 - 1e-9) & (durations <= 1.2 + 1e-9)), d.name
        gaps = (frames[1:, 0] - frames[:-1, 1] + 1) / d.fps  # transition between two signs
        assert np.all((gaps >= 0.15) & (gaps <= 0.65)), (d.name, gaps)
        all_gaps.extend(gaps)
    assert 0.2 <= np.median(all_gaps) <= 0.42  # about half the transitions take 0.2-0.4 s, long moves up to 0.6 s


def test_deterministic_and_cached_copies():
    a, b = sign_corpus("test"), sign_corpus("test", seed=0)
    for x, y in zip(a, b, strict=True):
        assert x is not y
        np.testing.assert_array_equal(x.arm_positions, y.arm_positions)
        np.testing.assert_array_equal(x.finger_positions, y.finger_positions)
        np.testing.assert_array_equal(x.wrist_rotations, y.wrist_rotations)
        assert x.meta == y.meta
    # callers cannot corrupt the cache
    a[0].arm_positions[:] = 0.0
    a[0].meta["signs"].append("X")
    c = corpus_clip(a[0].name)
    np.testing.assert_array_equal(c.arm_positions, b[0].arm_positions)
    assert c.meta == b[0].meta


def test_another_seed_gives_another_corpus():
    a, b = corpus_clip("hospital_03"), corpus_clip("hospital_03", seed=1)
    assert a.arm_positions.shape != b.arm_positions.shape or not np.allclose(a.arm_positions, b.arm_positions)
    again = corpus_clip("hospital_03", seed=1)
    np.testing.assert_array_equal(again.finger_positions, b.finger_positions)


def test_clip_lookup_and_errors():
    d = corpus_clip("hospital_03")
    assert d.name == "hospital_03" and d.meta["scenario"] == "hospital"
    with pytest.raises(DemonstrationError) as err:
        corpus_clip("hospital_99")
    assert "hospital_99" in str(err.value) and "business_01" in str(err.value)
    with pytest.raises(DemonstrationError, match="split"):
        sign_corpus("validation")
    with pytest.raises(DemonstrationError, match="split"):
        corpus_names("dev")
    with pytest.raises(DemonstrationError, match="seed"):
        sign_corpus("train", seed=-1)
    with pytest.raises(DemonstrationError, match="scenario"):
        corpus_lexicon("moon")


def test_test_combinations_are_unseen_in_training(corpus):
    def combos(demos):
        return {(c["handshape"], c["location"], c["movement"]) for d in demos for c in d.meta["sign_components"]}

    train, test = combos(corpus["train"]), combos(corpus["test"])
    assert len(test) >= 10 and len(train) >= 20
    assert not train & test
    assert all(is_test_combination(*c) for c in test)
    assert not any(is_test_combination(*c) for c in train)
    # the lexicons agree with what the sequences use
    for name, sc in SCENARIOS.items():
        for sign in corpus_lexicon(name).values():
            assert is_test_combination(*sign.combination) == (sc.split == "test")


def test_vocabulary_is_used(all_demos):
    comps = [c for d in all_demos for c in d.meta["sign_components"]]
    assert {c["pattern"] for c in comps} == set(PATTERNS)
    assert {c["movement"] for c in comps} == set(MOVEMENTS)
    assert {c["location"] for c in comps} == set(LOCATIONS)
    assert len({c["handshape"] for c in comps}) >= 10
    assert {c["handshape"] for c in comps} <= set(HANDSHAPES)
    assert {d.meta["dominant"] for d in all_demos} == {"left", "right"}


def test_body_frame_and_conventions(all_demos):
    for d in all_demos:
        sh = d.arm_positions[:, :, 0]  # (T, 2, 3)
        np.testing.assert_allclose(sh.mean(axis=1), 0.0, atol=1e-12)  # origin between the shoulders
        assert np.all(sh[:, 0, 1] > 0.1) and np.all(sh[:, 1, 1] < -0.1)  # left arm at +Y
        for s, side in enumerate(("left", "right")):
            upper, fore = d.arm_lengths(side)
            seg = np.linalg.norm(np.diff(d.arm_positions[:, s], axis=1), axis=-1)  # (T, 2)
            np.testing.assert_allclose(seg, np.broadcast_to([upper, fore], seg.shape), atol=1e-9)
            assert 0.27 <= upper <= 0.32 and 0.23 <= fore <= 0.28
            R = d.wrist_rotation(side)
            np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
            f = d.fingers(side)  # (T, 5, 2, 3)
            x = f[:, 2, 0] - d.position(side, "wrist")
            np.testing.assert_allclose(R[..., 0], x / np.linalg.norm(x, axis=-1, keepdims=True), atol=1e-9)
            assert np.all(np.einsum("ti,ti->t", R[..., 1], f[:, 1, 0] - f[:, 4, 0]) > 0.03)
            # the same frame as the readers build from hand landmarks
            from_hand = wrist_frame_from_hand(d.position(side, "wrist"), f[:, 1, 0], f[:, 4, 0], f[:, 2, 0])
            np.testing.assert_allclose(R, from_hand, atol=1e-9)
            # the rest pose hangs below the shoulders, the hands come up to sign
            wrist_z = d.position(side, "wrist")[:, 2]
            assert wrist_z[0] < -0.35


def test_arrays_match_the_body_model(all_demos):
    for d in all_demos[::7]:
        arm, fingers = corpus_angles(d.name)
        body = BodyParams(**d.meta["body"])
        for s, side in enumerate(("left", "right")):
            pose = arm_fk(body, arm[:, s], fingers[:, s], side)
            np.testing.assert_allclose(d.position(side, "elbow"), pose.elbow, atol=1e-12)
            np.testing.assert_allclose(d.fingers(side)[:, :, 1], pose.finger_tip, atol=1e-12)


def test_joint_angles_inside_human_ranges(all_demos):
    for d in all_demos:
        arm, fingers = corpus_angles(d.name)
        assert arm.shape == (len(d), 2, 7) and fingers.shape == (len(d), 2, 5, 4)
        assert np.all((arm >= ARM_RANGES[:, 0]) & (arm <= ARM_RANGES[:, 1])), d.name
        assert np.all((fingers >= FINGER_RANGES[..., 0]) & (fingers <= FINGER_RANGES[..., 1])), d.name
        assert np.all(arm[:, :, 3] > 0.1)  # the elbow is never locked straight


def _torso_distance(body: BodyParams, p: np.ndarray) -> np.ndarray:
    # independent of body.torso_signed_distance: distance to a rounded box
    q = np.abs(p - body.torso_center) - (body.torso_half_extents - body.torso_rounding)
    return np.where(
        np.all(q <= 0, axis=-1), q.max(axis=-1), np.linalg.norm(np.clip(q, 0, None), axis=-1)
    ) - body.torso_rounding


def test_hands_never_enter_torso_or_head(all_demos):
    for d in all_demos:
        body = BodyParams(**d.meta["body"])
        arm, fingers = corpus_angles(d.name)
        for s, side in enumerate(("left", "right")):
            # the Demonstration's own points ...
            pts = np.concatenate([d.position(side, "wrist")[:, None], d.fingers(side).reshape(len(d), 10, 3)], axis=1)
            # ... and every finger joint of the body model
            pts = np.concatenate([pts, arm_fk(body, arm[:, s], fingers[:, s], side).hand_points()], axis=1)
            head = np.linalg.norm(pts - body.head_center, axis=-1) - body.head_radius
            assert head.min() > CONTACT_MARGIN, (d.name, side, head.min())
            torso = _torso_distance(body, pts)
            assert torso.min() > CONTACT_MARGIN, (d.name, side, torso.min())
        elbows = _torso_distance(body, d.arm_positions[:, :, 1])
        assert elbows.min() > ELBOW_RADIUS, (d.name, elbows.min())  # the upper arm stays beside the torso
        gap = np.linalg.norm(d.finger_positions[:, 0].reshape(-1, 1, 10, 3) - d.finger_positions[:, 1].reshape(-1, 10, 1, 3), axis=-1)
        assert gap.min() > CONTACT_MARGIN, d.name  # the two hands do not pass through each other


def test_motion_is_smooth(all_demos):
    for d in all_demos:
        wrist = d.arm_positions[:, :, 2]  # (T, 2, 3)
        speed = np.linalg.norm(np.diff(wrist, axis=0), axis=-1) * d.fps
        acc = np.linalg.norm(np.diff(wrist, n=2, axis=0), axis=-1) * d.fps**2
        tips = d.finger_positions[:, :, :, 1]
        tip_acc = np.linalg.norm(np.diff(tips, n=2, axis=0), axis=-1) * d.fps**2
        assert speed.max() < WRIST_SPEED_BOUND, (d.name, speed.max())
        assert acc.max() < WRIST_ACCEL_BOUND, (d.name, acc.max())
        assert tip_acc.max() < FINGERTIP_ACCEL_BOUND, (d.name, tip_acc.max())
        # signing actually moves: the dominant wrist travels and changes speed
        assert speed.max() > 0.3

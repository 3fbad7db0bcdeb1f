"""The causal reader against the offline ``.pose`` reader on the same landmarks, and its outlier tests."""

from __future__ import annotations

import dataclasses

import numpy as np

from nlo_lab.human import load_demonstration
from nlo_lab.live import POSE_INDEX, CausalReader, FilterSettings

RECORDING_NAME = "holistic_both_hands_47f.pose"


def _read(frames, times, settings=None):
    reader = CausalReader(settings)
    return [reader.read(lm, t) for lm, t in zip(frames, times, strict=True)], reader


def test_the_pose_landmark_numbers_are_mediapipes():
    import pytest

    mp = pytest.importorskip("mediapipe", reason="the video extra (mediapipe) is not installed")
    for name, i in POSE_INDEX.items():
        assert mp.solutions.pose.PoseLandmark[name].value == i, name


def test_close_to_the_offline_reader(recorded):
    frames, times = recorded
    from pathlib import Path

    offline = load_demonstration(Path(__file__).resolve().parents[2] / "assets" / "recordings" / RECORDING_NAME)
    live, reader = _read(frames, times)
    assert all(d is not None for d in live)
    assert reader.up_from == offline.meta["up_from"]
    arms = np.stack([d.arm_positions[0] for d in live])
    dist = np.linalg.norm(arms - offline.arm_positions, axis=-1)  # (T, 2, 3) [m]
    assert np.nanmean(dist) < 0.03, np.nanmean(dist)  # measured 18 mm: the filter's lag and the running medians
    assert np.abs(arms[:, :, 0][..., [0, 2]]).max() < 1e-9  # the shoulders on the body frame's Y axis, as offline
    fingers = np.stack([d.finger_mask[0] for d in live])
    # the same hands seen, but for gaps: offline fills them from both sides, live holds the last value
    assert (fingers == offline.finger_mask).mean() > 0.9, (fingers == offline.finger_mask).mean()
    # the control: without the body frame (the camera's axes) the check fails
    raw = np.stack([[lm.world[[POSE_INDEX[f"{s}_{j}"] for j in ("SHOULDER", "ELBOW", "WRIST")]] for s in ("LEFT", "RIGHT")]
                    for lm in frames])
    assert np.nanmean(np.linalg.norm(raw - raw[:, :, :1] - offline.arm_positions, axis=-1)) > 0.1


def test_a_spike_is_held_and_a_lasting_move_is_taken(recorded):
    frames, times = recorded
    wrist = POSE_INDEX["RIGHT_WRIST"]
    spiked = list(frames)
    moved = frames[20].world.copy()
    moved[wrist] += [0.0, 0.0, -0.5]  # 0.5 m towards the camera, one frame
    spiked[20] = dataclasses.replace(frames[20], world=moved)
    clean, _ = _read(frames, times)
    dirty, _ = _read(spiked, times)
    step = np.linalg.norm(dirty[20].arm_positions[0, 1, 2] - clean[20].arm_positions[0, 1, 2])
    assert step < 0.02, step  # held: the spike never reaches the output
    # the same offset from frame 20 on: a real move, taken after at most the longest gap (0.25 s = 6 frames at 25 fps)
    lasting = [dataclasses.replace(lm, world=lm.world + np.where(np.arange(33)[:, None] == wrist, [0, 0, -0.5], 0))
               if i >= 20 else lm for i, lm in enumerate(frames)]
    moved, _ = _read(lasting, times)
    late = np.linalg.norm(moved[30].arm_positions[0, 1, 2] - clean[30].arm_positions[0, 1, 2])
    assert late > 0.2, late


def test_nobody_for_longer_than_the_gap_gives_none(recorded, nobody):
    frames, times = recorded
    reader = CausalReader()
    for lm, t in zip(frames[:10], times[:10], strict=True):
        assert reader.read(lm, t) is not None
    t = times[9]
    assert reader.read(nobody, t + 0.1) is None
    # back after a long gap: read afresh, no stale held values
    assert reader.read(frames[10], t + 1.0) is not None


def test_filter_settings_reach_every_track(recorded):
    """Switched to a cutoff of 1000 Hz (no smoothing) mid-stream, a reader gives what one unfiltered from the start
    gives: arms, fingertips and wrist rotations alike (each has its own filter)."""
    frames, times = recorded
    switched, fresh = CausalReader(FilterSettings(min_cutoff=0.5)), CausalReader(FilterSettings(min_cutoff=1000.0, beta=0.0))
    for i, (lm, t) in enumerate(zip(frames, times, strict=True)):
        if i == 10:
            switched.set_filter(min_cutoff=1000.0, beta=0.0)
        a, b = switched.read(lm, t), fresh.read(lm, t)
        if i == 9:
            assert np.abs(a.arm_positions - b.arm_positions).max() > 0.005  # the control: before the switch they differ
        if i >= 20:
            assert np.nanmax(np.abs(a.arm_positions - b.arm_positions)) < 2e-3
            # fingertips as directions from the wrist (their scale is a running median of the past's hand lengths)
            tips = [d.finger_positions[0, :, :, 1] - d.arm_positions[0, :, 2, None] for d in (a, b)]
            unit = [x / np.linalg.norm(x, axis=-1, keepdims=True) for x in tips]
            assert np.nanmax(np.abs(unit[0] - unit[1])) < 1e-2
            assert np.nanmax(np.abs(a.wrist_rotations - b.wrist_rotations)) < 1e-2
    assert switched.settings.as_dict() == {"min_cutoff": 1000.0, "beta": 0.0, "d_cutoff": 1.0}

"""The MediaPipe Holistic ``.pose`` reader: files written here with pose-format's own writer, and the shared recordings."""

from __future__ import annotations

import numpy as np
import pytest

pose_format = pytest.importorskip("pose_format")

from nlo_lab.errors import DemonstrationError  # noqa: E402
from nlo_lab.human import load_demonstration  # noqa: E402
from nlo_lab.human.readers.pose import MAX_GAP_SECONDS, load_pose  # noqa: E402


def test_world_file_reads_back_the_truth(tmp_path, pose_files):
    path = tmp_path / "w.pose"
    body, hands = pose_files.write(path)
    d = load_pose(path, condition=False)  # the raw geometry; conditioning: test_world_file_conditioned_stays_close
    assert len(d) == 40 and d.fps == pose_files.FPS and d.meta["arm_source"] == "POSE_WORLD_LANDMARKS"
    for side in ("left", "right"):
        for joint in ("shoulder", "elbow", "wrist"):
            np.testing.assert_allclose(d.position(side, joint), body[f"{side.upper()}_{joint.upper()}"], atol=2e-5)
        rel = hands[side.upper()]
        wrist = d.position(side, "wrist")[:, None]
        np.testing.assert_allclose(d.fingers(side)[:, :, 0], wrist + rel[:, [2, 5, 9, 13, 17]], atol=2e-4)
        np.testing.assert_allclose(d.fingers(side)[:, :, 1], wrist + rel[:, [4, 8, 12, 16, 20]], atol=2e-4)
        R = d.wrist_rotation(side)
        np.testing.assert_allclose(R[:, :, 0], np.broadcast_to([1.0, 0, 0], (40, 3)), atol=1e-3)  # fingers forward
        # y from pinky to index: towards the thumb, which is on the body's midline side for both hands
        assert np.all(R[:, 1, 1] * (1 if side == "right" else -1) > 0.99)
        np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
    # palm down: for the right hand z is the back of the hand (up), for the left hand the palm (down)
    assert np.all(d.wrist_rotation("right")[:, 2, 2] > 0.99) and np.all(d.wrist_rotation("left")[:, 2, 2] < -0.99)


def test_world_file_conditioned_stays_close(tmp_path, pose_files):
    """Smoothing a clean, smooth motion changes it by less than 0.2 mm (the window's polynomial fit)."""
    path = tmp_path / "w.pose"
    body, _ = pose_files.write(path)
    d = load_demonstration(path)
    assert d.meta["depth"] == "world" and d.meta["conditioning"]["spike_frames"] == 0
    for side in ("left", "right"):
        for joint in ("shoulder", "elbow", "wrist"):
            np.testing.assert_allclose(d.position(side, joint), body[f"{side.upper()}_{joint.upper()}"], atol=2e-4)


def test_image_only_file_scales_by_the_nominal_shoulder_width(tmp_path, pose_files):
    path = tmp_path / "i.pose"
    body, _ = pose_files.write(path, world=False)
    with pytest.warns(UserWarning, match="no world landmarks"):
        d = load_pose(path, condition=False)
    assert d.meta["arm_source"] == "POSE_LANDMARKS" and d.meta["depth"] == "image"
    # image plane: Y and Z are exact because the true shoulder width is 0.36 m; X (depth) is reconstructed
    # from the segment lengths: each segment has its reconstructed length, and points forward
    lengths = d.meta["segment_lengths_m"]
    for side in ("left", "right"):
        for joint in ("shoulder", "elbow", "wrist"):
            truth = body[f"{side.upper()}_{joint.upper()}"]
            np.testing.assert_allclose(d.position(side, joint)[:, 1:], truth[:, 1:], atol=1e-4)
        np.testing.assert_allclose(d.position(side, "shoulder")[:, 0], 0.0, atol=1e-4)
        for a, b, seg in (("shoulder", "elbow", "upper"), ("elbow", "wrist", "fore")):
            length = np.linalg.norm(d.position(side, b) - d.position(side, a), axis=-1)
            np.testing.assert_allclose(length, lengths[f"{side}_{seg}"], atol=1e-6)
            assert np.all(d.position(side, b)[:, 0] > d.position(side, a)[:, 0])


def test_short_hand_gaps_interpolated_long_gaps_masked(tmp_path, pose_files):
    path = tmp_path / "g.pose"
    short = list(range(5, 8))  # 3 frames < 0.25 s at 25 fps
    long = list(range(15, 30))  # 15 frames
    pose_files.write(path, hand_missing=short + long, left_hand=False)
    d = load_demonstration(path)
    assert d.meta["max_gap_frames"] == round(MAX_GAP_SECONDS * pose_files.FPS)
    r = 1  # right
    assert d.finger_mask[short, r].all() and d.wrist_mask[short, r].all()
    assert np.isfinite(d.finger_positions[short, r]).all()
    assert not d.finger_mask[long, r].any() and not d.wrist_mask[long, r].any()
    assert np.isnan(d.finger_positions[long, r]).all() and np.isnan(d.wrist_rotations[long, r]).all()
    # never a silent zero: the missing left hand is NaN + masked
    assert not d.finger_mask[:, 0].any() and np.isnan(d.finger_positions[:, 0]).all() and not d.wrist_mask[:, 0].any()


def test_second_person_is_ignored(tmp_path, pose_files):
    path = tmp_path / "p.pose"
    body, _ = pose_files.write(path, people=2)
    np.testing.assert_allclose(load_pose(path, condition=False).position("left", "wrist"), body["LEFT_WRIST"], atol=2e-5)


# ---------------------------------------------------------------- bad input
def test_required_landmark_missing_everywhere(tmp_path, pose_files):
    path = tmp_path / "m.pose"
    elbow = pose_files.BODY8.index("LEFT_ELBOW")
    world_elbow = 8 + 42 + elbow
    pose_files.write(path, T=10, conf_overrides={**{(t, elbow): 0.0 for t in range(10)}, **{(t, world_elbow): 0.0 for t in range(10)}})
    with pytest.raises(DemonstrationError, match="missing in every frame") as err:
        load_demonstration(path)
    assert "LEFT_ELBOW" in err.value.field and "m.pose" in str(err.value)


def test_nan_in_an_observed_landmark(tmp_path, pose_files):
    path = tmp_path / "n.pose"
    pose_files.write(path, T=10, data_overrides={(4, pose_files.BODY8.index("RIGHT_WRIST")): np.nan})
    with pytest.raises(DemonstrationError, match="NaN") as err:
        load_demonstration(path)
    assert err.value.frame == 4 and err.value.field == "POSE_LANDMARKS/RIGHT_WRIST"


def test_zero_length_arm(tmp_path, pose_files):
    path = tmp_path / "z.pose"
    T = 10
    body = pose_files.body_truth(T)
    hip_c = (body["LEFT_HIP"] + body["RIGHT_HIP"]) / 2
    shoulder_world = pose_files.to_camera(body["RIGHT_SHOULDER"][6] - hip_c[6]) * np.array([pose_files.W, pose_files.H, 1.0])
    pose_files.write(path, T=T, data_overrides={(6, 8 + 42 + pose_files.BODY8.index("RIGHT_ELBOW")): shoulder_world})
    with pytest.raises(DemonstrationError, match="zero length") as err:
        load_pose(path, condition=False)
    assert err.value.frame == 6 and err.value.field == "right/upper_arm"
    # conditioned (the default), the collapsed upper arm is a segment-length jump: repaired by interpolation
    d = load_demonstration(path)
    assert d.meta["conditioning"]["segment_jump_frames"] + d.meta["conditioning"]["spike_frames"] >= 1
    np.testing.assert_allclose(d.position("right", "elbow")[6], body["RIGHT_ELBOW"][6], atol=0.01)


def test_bad_fps_no_frames_truncated_garbage(tmp_path, pose_files):
    pose_files.write(tmp_path / "f.pose", T=5, fps=0)
    with pytest.raises(DemonstrationError, match="fps"):
        load_demonstration(tmp_path / "f.pose")
    pose_files.write(tmp_path / "e.pose", T=0)
    with pytest.raises(DemonstrationError, match="no frames"):
        load_demonstration(tmp_path / "e.pose")
    pose_files.write(tmp_path / "ok.pose", T=30)
    raw = (tmp_path / "ok.pose").read_bytes()
    (tmp_path / "cut.pose").write_bytes(raw[: len(raw) // 2])
    with pytest.raises(DemonstrationError, match="cut.pose"):
        load_demonstration(tmp_path / "cut.pose")
    (tmp_path / "junk.pose").write_bytes(b"\x00\x01junk" * 3)
    with pytest.raises(DemonstrationError, match="junk.pose"):
        load_demonstration(tmp_path / "junk.pose")
    (tmp_path / "empty.pose").write_bytes(b"")
    with pytest.raises(DemonstrationError, match="empty"):
        load_demonstration(tmp_path / "empty.pose")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.pose", "e.pose", "empty.pose", "f.pose", "junk.pose", "ok.pose"]


# ---------------------------------------------------------------- the shared real recordings
REAL = ["mediapipe_right_hand_170f.pose", "holistic_both_hands_47f.pose", "holistic_world_97f.pose"]
# Upper-arm length CV bound: the reader gives 0.036-0.103 on these files (monocular MediaPipe is noisy);
# a wrong depth scale (image z at MediaPipe's nominal scale) gives 0.28-0.32, a mixed-up axis far more.
MAX_UPPER_ARM_CV = 0.15


@pytest.fixture(params=REAL)
def real(request, shared_pose):
    return load_demonstration(shared_pose(request.param))


def test_real_origin_between_shoulders_left_at_plus_y(real):
    ls, rs = real.position("left", "shoulder"), real.position("right", "shoulder")
    m = real.arm_mask[:, 0, 0] & real.arm_mask[:, 1, 0]
    assert m.mean() > 0.9
    np.testing.assert_allclose((ls + rs)[m], 0.0, atol=1e-9)
    np.testing.assert_allclose(ls[m][:, [0, 2]], 0.0, atol=1e-9)
    assert np.all(ls[m][:, 1] > 0.1) and np.all(rs[m][:, 1] < -0.1)
    # not only the shoulders: the whole left arm chain lies on the left of the right one
    lw, rw = real.position("left", "wrist"), real.position("right", "wrist")
    assert np.nanmean(lw[:, 1]) > np.nanmean(rw[:, 1]) + 0.1


def test_real_upper_arm_length_consistent(real):
    for s, side in enumerate(("left", "right")):
        ok = real.arm_mask[:, s, 0] & real.arm_mask[:, s, 1]
        length = np.linalg.norm(real.position(side, "elbow") - real.position(side, "shoulder"), axis=-1)[ok]
        assert ok.sum() >= 0.9 * len(real)
        cv = length.std() / length.mean()
        assert cv < MAX_UPPER_ARM_CV, f"{real.name} {side}: upper arm CV {cv:.3f}"
        assert 0.15 < np.median(length) < 0.45  # metres, a human upper arm


def test_real_wrist_rotations_are_rotations(real):
    R = real.wrist_rotations[real.wrist_mask]
    assert len(R) > 0
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
    assert np.isnan(real.wrist_rotations[~real.wrist_mask]).all()


def test_real_world_files_have_the_hands_in_front(real):
    # image-only recordings too: their depth is reconstructed from the limb lengths, forward unless MediaPipe says away
    # signing happens in front of the body: X (forward) of both wrists is positive on average
    for side in ("left", "right"):
        assert np.nanmean(real.position(side, "wrist")[:, 0]) > 0.1


def test_real_missing_left_hand_is_masked_not_zero(shared_pose):
    d = load_demonstration(shared_pose("mediapipe_right_hand_170f.pose"))
    assert d.meta["arm_source"] == "POSE_LANDMARKS"  # the 8-point layout, no world landmarks
    assert not d.finger_mask[:, 0].any() and not d.wrist_mask[:, 0].any()
    assert np.isnan(d.finger_positions[:, 0]).all() and np.isnan(d.wrist_rotations[:, 0]).all()
    assert 0.8 * len(d) <= d.finger_mask[:, 1, 0].sum() < len(d)  # the right hand: present in about 85 % of frames
    assert np.isnan(d.finger_positions[~d.finger_mask[:, 1, 0], 1]).all()


def test_pose_files_and_videos_share_one_first_check(tmp_path):
    """Missing, folder, empty: the same one-line messages for a .pose file and a video (human.file_head)."""
    from nlo_lab.human.readers.video import check_video_file

    (tmp_path / "d.pose").mkdir()
    (tmp_path / "d.mp4").mkdir()
    (tmp_path / "e.pose").write_bytes(b"")
    (tmp_path / "e.mp4").write_bytes(b"")
    for name, match in (("missing", "no such file"), ("d", "is a folder, not a {} file"), ("e", "the file is empty")):
        with pytest.raises(DemonstrationError, match=match.format(".pose")) as pose_err:
            load_pose(tmp_path / f"{name}.pose")
        with pytest.raises(DemonstrationError, match=match.format("video")) as video_err:
            check_video_file(tmp_path / f"{name}.mp4")
        assert f"{name}.pose" in str(pose_err.value) and f"{name}.mp4" in str(video_err.value)

"""Robot-ready motion (issue 14): body frame under camera roll, conditioning, smoothness, velocity limits, retiming, files."""

from __future__ import annotations

import io
import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch

from nlo_lab.cli import main
from nlo_lab.corpus import corpus_clip
from nlo_lab.human import load_demonstration
from nlo_lab.human.conditioning import condition_demonstration, savgol
from nlo_lab.inference import (
    OptimizeSettings,
    RobotTrajectory,
    initial_latent,
    optimize_latent,
    retime_times,
    segment_durations,
    sequence_start,
)
from nlo_lab.metrics import joint_speed_ratios, max_joint_speed_ratio, max_joint_step, velocity_violations
from nlo_lab.model import encoder_input, load_pretrained
from nlo_lab.objective import LossWeights, smoothness_loss, targets_from_demonstration
from nlo_lab.pipeline import retarget
from nlo_lab.robot import load_robot

RECORDINGS = ["holistic_both_hands_47f.pose", "holistic_world_97f.pose", "mediapipe_right_hand_170f.pose"]


def _load_quiet(path, **kw):
    from nlo_lab.human import load_pose

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_pose(path, **kw)


# ---------------------------------------------------------------- robot velocity limits
def test_published_velocity_limits_in_the_specs(robots):
    yumi, nao, pepper = robots["yumi"], robots["nao"], robots["pepper"]
    for robot in robots.values():
        v = robot.velocity_limits
        assert v.shape == (robot.n_joints,) and torch.isfinite(v).all() and (v > 0).all(), robot.name
        assert robot.spec.velocity_limits_source
    ys = dict(zip(yumi.joint_names, yumi.velocity_limits.tolist(), strict=True))
    assert ys["yumi_joint_1_l"] == pytest.approx(3.1416) and ys["yumi_joint_4_r"] == pytest.approx(6.9813)
    ns = dict(zip(nao.joint_names, nao.velocity_limits.tolist(), strict=True))
    assert ns["LShoulderPitch"] == pytest.approx(8.26797) and ns["RElbowRoll"] == pytest.approx(7.19407)
    assert ns["LWristYaw"] == pytest.approx(24.6229)
    ps = dict(zip(pepper.joint_names, pepper.velocity_limits.tolist(), strict=True))
    assert ps["RShoulderRoll"] == pytest.approx(9.22756) and ps["LWristYaw"] == pytest.approx(17.3835)


def test_spec_with_a_bad_velocity_limit_is_rejected(tmp_path):
    from nlo_lab.errors import RobotDescriptionError
    from nlo_lab.paths import ROBOTS_DIR

    data = json.loads((ROBOTS_DIR / "nao.json").read_text())
    data["urdf"] = str(ROBOTS_DIR / "nao.urdf")
    data["velocity_limits"]["LWristYaw"] = -1
    spec = tmp_path / "nao.json"
    spec.write_text(json.dumps(data))
    with pytest.raises(RobotDescriptionError, match="velocity_limits"):
        load_robot(str(spec))
    data["velocity_limits"] = {"LWristYawn": 1.0}
    spec.write_text(json.dumps(data))
    with pytest.raises(RobotDescriptionError, match="LWristYawn"):
        load_robot(str(spec))


# ---------------------------------------------------------------- retiming
def test_retimed_velocities_within_the_limits_and_time_optimal():
    rng = np.random.default_rng(0)
    limits = np.array([3.1416, 6.9813, 2.0, np.inf])
    q = np.cumsum(rng.normal(0.0, 0.3, (200, 4)), axis=0)  # jittery: up to ~1 rad per frame
    fps = 25.0
    times = retime_times(q, fps, limits)
    assert times[0] == 0.0 and (np.diff(times) >= 1 / fps - 1e-12).all()
    speed = np.abs(np.diff(q, axis=0)) / np.diff(times)[:, None]
    assert (speed <= limits).all()  # on the file's own time base
    # time-optimal: every stretched segment has a joint exactly at its limit
    dt = np.diff(times)
    stretched = dt > 1 / fps + 1e-12
    assert stretched.any()
    assert np.allclose((speed / limits)[stretched].max(axis=1), 1.0, atol=1e-6)
    # a trajectory already within the limits is not slowed down
    slow = np.linspace(0, 0.5, 50)[:, None].repeat(4, 1)
    np.testing.assert_allclose(segment_durations(slow, fps, limits), 1 / fps)


def test_velocity_metrics_count_on_the_given_time_base(robots):
    robot = robots["nao"]
    q = np.zeros((5, robot.n_joints))
    q[2, 0] = 1.0  # LShoulderPitch jumps 1 rad and back: 25 rad/s at 25 fps, limit 8.27
    assert velocity_violations(robot, q, fps=25) == 2
    assert max_joint_speed_ratio(robot, q, fps=25) == pytest.approx(25 / 8.26797)
    times = retime_times(q, 25, robot.velocity_limits.numpy())
    assert velocity_violations(robot, q, times) == 0 and max_joint_speed_ratio(robot, q, times) <= 1.0
    assert joint_speed_ratios(robot, q, times).shape == (4, robot.n_joints)
    assert max_joint_step(q) == 1.0


# ---------------------------------------------------------------- trajectory files: time
def test_trajectory_files_carry_time_and_old_files_still_read(tmp_path):
    times = np.array([0.0, 0.04, 0.1, 0.3])
    traj = RobotTrajectory("nao", ("a", "b"), np.arange(8.0).reshape(4, 2), fps=25.0, time=times)
    assert traj.duration == pytest.approx(0.34)
    for suffix in (".npz", ".json"):
        p = tmp_path / f"t{suffix}"
        traj.save_npz(p) if suffix == ".npz" else traj.save_json(p)
        back = RobotTrajectory.load(p)
        np.testing.assert_array_equal(back.times, times)
        assert back == traj
    with np.load(tmp_path / "t.npz") as z:
        np.testing.assert_array_equal(z["time"], times)
        assert int(z["format_version"]) == 2
    traj.save_csv(tmp_path / "t.csv")
    rows = (tmp_path / "t.csv").read_text().splitlines()
    assert rows[0].split(",")[0] == "time_s"
    np.testing.assert_array_equal([float(r.split(",")[0]) for r in rows[1:]], times)
    # a version 1 file (no time): frames 1/fps apart
    old = tmp_path / "old.npz"
    np.savez(old, format_version=np.int64(1), robot=np.str_("nao"), joint_names=np.array(["a", "b"]),
             angles=np.zeros((3, 2)), fps=np.float64(10.0))
    np.testing.assert_allclose(RobotTrajectory.load(old).times, [0.0, 0.1, 0.2])
    old_json = tmp_path / "old.json"
    old_json.write_text(json.dumps({"format_version": 1, "robot": "nao", "joint_names": ["a"], "fps": 2.0, "angles": [[0.0], [1.0]]}))
    np.testing.assert_allclose(RobotTrajectory.load(old_json).times, [0.0, 0.5])


@pytest.mark.parametrize("bad, match", [
    ([0.0, 0.1, 0.1, 0.2], "strictly increase"), ([0.1, 0.2, 0.3, 0.4], "start at 0"), ([0.0, 0.1], r"\(4,\)"),
    ([0.0, np.nan, 0.2, 0.3], "NaN"),
])
def test_bad_time_is_rejected(bad, match):
    from nlo_lab.inference import TrajectoryError

    with pytest.raises(TrajectoryError, match=match):
        RobotTrajectory("nao", ("a",), np.zeros((4, 1)), fps=25.0, time=bad)


def test_cli_json_keys_and_time_column(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["retarget", "demo:hospital_01", "--robot", "nao", "--iters", "10", "--json", "--out", str(out)])
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 0
    for key in ("velocity_violations", "max_joint_speed_ratio", "slowdown", "depth", "recording_speed_ratio", "max_joint_step_rad"):
        assert key in summary, key
    assert summary["velocity_violations"] == 0 and summary["depth"] == "world" and summary["slowdown"] >= 1.0
    traj = RobotTrajectory.load(out / "trajectory.npz")
    assert traj.duration / (summary["frames"] / summary["fps"]) == pytest.approx(summary["slowdown"], abs=1e-3)
    csv_times = [float(r.split(",")[0]) for r in (out / "trajectory.csv").read_text().splitlines()[1:]]
    np.testing.assert_allclose(csv_times, traj.times)


# ---------------------------------------------------------------- smoothness term and warm start
def test_smoothness_loss_is_the_speed_in_units_of_the_limit():
    limits = torch.tensor([2.0, 24.0])  # the second is faster than SMOOTH_SPEED_CAP: counted at the cap
    q = torch.tensor([[0.0, 0.0], [0.1, 0.1], [0.1, 0.3]], dtype=torch.float64)
    got = smoothness_loss(q, 10.0, limits)
    cap = math.pi
    expect = torch.tensor([0.0, (0.1 * 10 / 2) ** 2 + (0.1 * 10 / cap) ** 2, (0.2 * 10 / cap) ** 2], dtype=torch.float64)
    torch.testing.assert_close(got, expect)
    # a jump beyond SMOOTH_MAX_STEP costs more than its speed alone
    from nlo_lab.objective import SMOOTH_MAX_STEP

    big = torch.tensor([[0.0, 0.0], [SMOOTH_MAX_STEP + 0.1, 0.0]], dtype=torch.float64)
    assert float(smoothness_loss(big, 10.0, limits)[1]) > ((SMOOTH_MAX_STEP + 0.1) * 10 / 2) ** 2


@pytest.mark.slow
def test_smoothing_removes_jumps_and_keeps_the_best_sequence(robots):
    robot = robots["nao"]
    model = load_pretrained(robot)
    demo = corpus_clip("introduction_12")
    targets, x = targets_from_demonstration(demo), encoder_input(demo)
    rough = optimize_latent(model, robot, targets, OptimizeSettings(), weights=LossWeights(smooth=0.0), encoder_input=x)
    smooth = optimize_latent(model, robot, targets, OptimizeSettings(), weights=LossWeights(), encoder_input=x)
    step = lambda r: float((r.q[1:] - r.q[:-1]).abs().max())  # noqa: E731
    assert step(smooth) < 0.5 < step(rough)
    speed = lambda r: max_joint_speed_ratio(robot, r.q.double().numpy(), fps=demo.fps)  # noqa: E731
    assert speed(smooth) < speed(rough)


def test_sequence_start_picks_neighbouring_latents(robots):
    robot = robots["nao"]
    model = load_pretrained(robot)
    demo = corpus_clip("hospital_11")
    targets = targets_from_demonstration(demo)
    z0 = initial_latent(model, encoder_input(demo), OptimizeSettings())
    z = sequence_start(model, robot, targets, z0, LossWeights(), window=2)
    T = len(targets)
    flat0, flat = z0.flatten(1), z.flatten(1)
    for t in range(T):  # every start is one of the frame's own or its neighbours' encoder latents
        near = [s for s in range(max(0, t - 2), min(T, t + 3)) if torch.equal(flat[t], flat0[s])]
        assert near, t
    assert torch.equal(sequence_start(model, robot, targets, z0, LossWeights(smooth=0.0)), z0)


# ---------------------------------------------------------------- noisy input, robot-ready output
def _noisy(demo, seed=0):
    """The clip with 1 cm jitter on every arm point, and three outlier frames (a wrist 0.4 m away, a flipped hand)."""
    rng = np.random.default_rng(seed)
    arms = demo.arm_positions + rng.normal(0.0, 0.01, demo.arm_positions.shape)
    arms[20, 1, 2] += [0.0, 0.0, 0.4]
    arms[40, 0, 1] += [-0.3, 0.0, 0.0]
    rots = demo.wrist_rotations.copy()
    flip = np.diag([1.0, -1.0, -1.0])  # 180 degrees about the hand's x
    rots[30, 1] = rots[30, 1] @ flip
    fingers = demo.finger_positions + rng.normal(0.0, 0.005, demo.finger_positions.shape)
    from nlo_lab.human import Demonstration

    return Demonstration(demo.fps, arms, demo.arm_mask, rots, demo.wrist_mask, fingers, demo.finger_mask, name=demo.name + "+noise")


def test_conditioning_repairs_outliers_and_jitter():
    clean = corpus_clip("hospital_02")
    noisy = _noisy(clean)
    fixed = condition_demonstration(noisy)
    err = lambda d: np.linalg.norm(d.arm_positions - clean.arm_positions, axis=-1)  # noqa: E731
    assert err(noisy)[20, 1, 2] > 0.35 and err(fixed)[20, 1, 2] < 0.05
    assert err(noisy)[40, 0, 1] > 0.25 and err(fixed)[40, 0, 1] < 0.05
    assert np.nanmean(err(fixed)) < 0.6 * np.nanmean(err(noisy))
    R, R0 = fixed.wrist_rotations[30, 1], clean.wrist_rotations[30, 1]
    assert np.arccos(np.clip((np.trace(R0.T @ R) - 1) / 2, -1, 1)) < 0.3  # the flip is repaired


@pytest.mark.slow
@pytest.mark.parametrize("robot_name", ["yumi", "nao", "pepper"])
def test_noisy_demonstration_gives_robot_ready_motion(robots, robot_name):
    robot = robots[robot_name]
    demo = condition_demonstration(_noisy(corpus_clip("hospital_02")))
    s = retarget(demo, robot).summary
    assert s["velocity_violations"] == 0 and s["max_joint_speed_ratio"] <= 1.0
    assert s["limit_violations"] == 0 and s["self_collision_frames"] == 0
    assert s["max_joint_step_rad"] <= 0.5 and s["slowdown"] <= 3.0


# ---------------------------------------------------------------- the body frame under camera roll
def _rotated_pose_bytes(path: Path, degrees: float) -> bytes:
    """The recording as a camera rolled by ``degrees`` would have seen it: image points turned about the
    image centre (for 90 and 270 the frame's width and height swap), world points about the camera axis."""
    from pose_format import Pose

    pose = Pose.read(path.read_bytes())
    W, H = float(pose.header.dimensions.width), float(pose.header.dimensions.height)
    swap = int(round(degrees)) % 180 == 90
    W2, H2 = (H, W) if swap else (W, H)
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    data = np.ma.getdata(pose.body.data).astype(np.float64)
    start = 0
    for comp in pose.header.components:
        n = len(comp.points)
        block = data[:, :, start:start + n]
        if comp.name == "POSE_WORLD_LANDMARKS":
            x, y = block[..., 0] / W, block[..., 1] / H  # metres
            block[..., 0], block[..., 1] = (c * x - s * y) * W2, (s * x + c * y) * H2
        else:
            x, y = block[..., 0] - W / 2, block[..., 1] - H / 2
            block[..., 0], block[..., 1] = c * x - s * y + W2 / 2, s * x + c * y + H2 / 2
            if np.abs(block[..., 2]).max() <= 10.0:  # z on MediaPipe's scale (a fraction of the width): same depth in pixels
                block[..., 2] *= W / W2
        start += n
    pose.body.data = np.ma.masked_array(data.astype(np.float32), mask=np.ma.getmaskarray(pose.body.data))
    pose.header.dimensions.width, pose.header.dimensions.height = int(W2), int(H2)
    buf = io.BytesIO()
    pose.write(buf)
    return buf.getvalue()


@pytest.fixture(scope="module", params=RECORDINGS)
def recording(request, shared_pose):
    return shared_pose(request.param)


@pytest.mark.parametrize("degrees", [90, 180, 37.5])
def test_rolled_camera_gives_the_same_demonstration(recording, degrees, tmp_path):
    """Tolerance 2 mm and 0.01 rad: the rotated file is written in float32 (pixel coordinates)."""
    pytest.importorskip("pose_format")
    base = _load_quiet(recording)
    rolled = tmp_path / recording.name
    rolled.write_bytes(_rotated_pose_bytes(recording, degrees))
    got = _load_quiet(rolled)
    assert got.meta["up_from"] == base.meta["up_from"] != "image"
    for name in ("arm_mask", "wrist_mask", "finger_mask"):
        np.testing.assert_array_equal(getattr(got, name), getattr(base, name))
    np.testing.assert_allclose(got.arm_positions, base.arm_positions, atol=2e-3, equal_nan=True)
    np.testing.assert_allclose(got.finger_positions, base.finger_positions, atol=2e-3, equal_nan=True)
    np.testing.assert_allclose(got.wrist_rotations, base.wrist_rotations, atol=1e-2, equal_nan=True)


def test_sideways_recording_without_hips_takes_up_from_the_face(tmp_path, shared_pose):
    """The issue's case: a phone held sideways, hips not visible (confidence <= 0.01 here)."""
    path = shared_pose("holistic_both_hands_47f.pose")
    rolled = tmp_path / "sideways.pose"
    rolled.write_bytes(_rotated_pose_bytes(path, 90))
    d = _load_quiet(rolled)
    assert d.meta["up_from"] == "face"
    # the head is up: the shoulders' Z is 0 and the wrists are below the face, in front of the body
    for side in ("left", "right"):
        assert np.nanmean(d.position(side, "wrist")[:, 0]) > 0.05  # forward, not behind the back


def test_no_face_no_hips_warns_and_falls_back_to_the_image_up(tmp_path, shared_pose):
    path = shared_pose("holistic_world_97f.pose")
    from pose_format import Pose

    pose = Pose.read(path.read_bytes())
    conf = np.asarray(pose.body.confidence).copy()
    start = 0
    for comp in pose.header.components:
        n = len(comp.points)
        for i, name in enumerate(comp.points):
            if comp.name.startswith("FACE") or any(k in name for k in ("EAR", "EYE", "NOSE", "MOUTH", "HIP")):
                conf[:, :, start + i] = 0.0
        start += n
    pose.body.confidence = conf
    out = tmp_path / "faceless.pose"
    buf = io.BytesIO()
    pose.write(buf)
    out.write_bytes(buf.getvalue())
    with pytest.warns(UserWarning, match="neither the face nor the hips"):
        d = load_demonstration(out)
    assert d.meta["up_from"] == "image"


def test_image_only_recording_reports_image_depth(capsys, shared_pose):
    path = shared_pose("mediapipe_right_hand_170f.pose")
    with pytest.warns(UserWarning, match="no world landmarks"):
        d = load_demonstration(path)
    assert d.meta["depth"] == "image"
    # hands scaled with the arm: the hand (wrist -> middle fingertip) is 0.73 forearms, not 1.85
    fore = np.nanmedian(np.linalg.norm(d.position("right", "wrist") - d.position("right", "elbow"), axis=-1))
    tip = np.nanmedian(np.linalg.norm(d.fingers("right")[:, 2, 1] - d.position("right", "wrist"), axis=-1))
    assert 0.5 < tip / fore < 0.8


def test_savgol_matches_scipy_where_available():
    signal = pytest.importorskip("scipy.signal")
    x = np.sin(np.linspace(0, 6, 60))[:, None] + np.random.default_rng(1).normal(0, 0.05, (60, 1))
    ours = savgol(x, np.ones(60, bool), 7, 2)
    np.testing.assert_allclose(ours, signal.savgol_filter(x, 7, 2, axis=0, mode="interp"), atol=1e-10)


def test_panel_has_a_smoothness_slider_that_reaches_the_sequence(robots):
    from nlo_lab.lab import RetargetPanel

    demo = corpus_clip("hospital_11").slice(35, 60)
    panel = RetargetPanel(demo, "nao", iterations=20, frame_iterations=2, view=None)
    assert panel.weights.smooth == LossWeights().smooth
    panel.controls["smooth"].value = 0.0
    assert panel.weights.smooth == 0.0
    rough = max_joint_step(panel.optimise_sequence().q.double().numpy())
    panel.controls["smooth"].value = 30.0
    smooth = max_joint_step(panel.optimise_sequence().q.double().numpy())
    assert smooth < rough

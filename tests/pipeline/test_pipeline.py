"""The pipeline is assembled in one place (``RetargetConfig.build()``): ``retarget()``, the
command line, the lab's panel and the evaluation's latent methods run it, and it gives the
numbers of the parts put together by hand."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from nlo_lab.corpus import corpus_clip
from nlo_lab.errors import SettingsError
from nlo_lab.evaluation import BaselineSettings, run_method
from nlo_lab.inference import HAND_SEARCH, OptimizeSettings, RetargetInputs, initial_latent, optimize_latent, retime_times
from nlo_lab.model import encoder_input, load_pretrained
from nlo_lab.objective import LossWeights, targets_from_demonstration
from nlo_lab.pipeline import RetargetConfig, Retargeter, hand_search, retarget
from nlo_lab.threads import single_thread

SETTINGS = OptimizeSettings(iterations=8)


@pytest.fixture(scope="module")
def demo():
    return corpus_clip("introduction_12").slice(0, 30)


@pytest.fixture(scope="module")
def model(nao):
    return load_pretrained(nao)


def test_retarget_is_the_built_config(nao, model, demo):
    a = retarget(demo, nao, settings=SETTINGS, model=model)
    b = RetargetConfig(nao, SETTINGS, model=model).build()(demo)
    np.testing.assert_array_equal(a.trajectory.angles, b.trajectory.angles)
    np.testing.assert_array_equal(a.trajectory.times, b.trajectory.times)
    assert {k: v for k, v in a.summary.items() if k != "seconds"} == {k: v for k, v in b.summary.items() if k != "seconds"}


def test_the_pipeline_gives_the_numbers_of_its_parts(nao, model, demo):
    weights = LossWeights(ee=500.0)
    result = RetargetConfig(nao, SETTINGS, weights, model=model).build()(demo)
    targets = targets_from_demonstration(demo, dtype=nao.lower_limits.dtype)
    by_hand = optimize_latent(model, nao, targets, SETTINGS, weights=weights, encoder_input=encoder_input(demo), fast=True)
    angles = by_hand.q.detach().numpy().astype(np.float64)
    np.testing.assert_array_equal(result.trajectory.angles, angles)
    np.testing.assert_array_equal(result.trajectory.times, retime_times(angles, demo.fps, nao.velocity_limits.double().numpy()))
    assert result.optimization.history == by_hand.history


def test_chunks_are_anchored_and_joined(nao, model, demo):
    retargeter = RetargetConfig(nao, SETTINGS, model=model, chunk_frames=12).build()
    assert retargeter.chunks(30) == 3 and retargeter.chunks(12) == 1
    inputs = retargeter.inputs(demo)
    joined = retargeter.optimize(inputs)
    assert joined.q.shape == (30, nao.n_joints) and joined.z.shape[0] == 30
    # the third chunk is the direct optimisation of its frames, anchored at the second chunk's last angles
    part = inputs.index(slice(24, 30))
    with single_thread():  # as the retargeter runs it (the sums' order follows the thread count)
        third = optimize_latent(model, nao, part.targets, SETTINGS, z0=initial_latent(model, part.encoder, SETTINGS), anchor=joined.q[23], fast=True)
    torch.testing.assert_close(joined.q[24:], third.q, rtol=0, atol=0)


def test_one_frame_warm_started(nao, model, demo):
    retargeter = RetargetConfig(nao, OptimizeSettings(iterations=4), model=model, chunk_frames=None).build()
    inputs = retargeter.inputs(demo)
    z = retargeter.start(inputs)
    warm = retargeter.optimize_frame(inputs, 7, z[7:8] + 0.1)
    direct = optimize_latent(model, nao, inputs.targets.index(slice(7, 8)), OptimizeSettings(iterations=4), z0=z[7:8] + 0.1, fast=True)
    torch.testing.assert_close(warm.q, direct.q, rtol=0, atol=0)
    assert warm.init == "given"
    cold = retargeter.optimize_frame(inputs, 7)  # from the encoder's latent of that frame
    one = inputs.index(slice(7, 8))
    direct = optimize_latent(model, nao, one.targets, OptimizeSettings(iterations=4), encoder_input=one.encoder, fast=True)
    assert cold.init == "encoder"
    torch.testing.assert_close(cold.q, direct.q, rtol=0, atol=0)
    torch.testing.assert_close(retargeter.start(one), z[7:8])


def test_inputs_keep_targets_and_encoder_input_together(demo):
    x = RetargetInputs.from_demonstration(demo)
    assert len(x) == len(x.targets) == len(x.encoder) == len(demo)
    halves = RetargetInputs.cat([x.index(slice(0, 10)), x.index(slice(10, None))])
    torch.testing.assert_close(halves.encoder.node_features, x.encoder.node_features)
    torch.testing.assert_close(halves.targets.wrist, x.targets.wrist)
    assert x.to(dtype=torch.float64).targets.dtype == torch.float64


@pytest.mark.parametrize("chunk", [0, -1, 2.5, True])
def test_bad_chunk_frames_are_refused_when_built(nao, model, chunk):
    with pytest.raises(SettingsError, match="chunk_frames"):
        RetargetConfig(nao, model=model, chunk_frames=chunk).build()


def test_a_finger_search_on_a_robot_without_fingers_is_refused_when_built(nao, model):
    settings = OptimizeSettings(iterations=8, hand_search=("ring",))
    with pytest.raises(SettingsError, match=r"hand_search \(ring\): nao has no finger joints"):
        RetargetConfig(nao, settings, model=model).build()
    assert not RetargetConfig(nao, SETTINGS, model=model).build().has_hand_joints  # without the search: built


def test_a_hand_slowdown_on_a_robot_without_hands_is_refused_when_built(nao, model):
    from nlo_lab.robot import load_robot

    with pytest.raises(SettingsError, match=r"hand_slowdown \(2\): nao has no hand joints"):
        RetargetConfig(nao, OptimizeSettings(iterations=8, hand_slowdown=2.0), model=model).build()
    with pytest.raises(SettingsError, match=r"hand_search \(ring\): nao has no finger joints"):  # the search's message first
        RetargetConfig(nao, OptimizeSettings(iterations=8, hand_search=("ring",), hand_slowdown=2.0), model=model).build()
    RetargetConfig(load_robot("yumi"), OptimizeSettings(hand_slowdown=2.0))._check_hand_search()  # a robot with hands: accepted


def test_a_searched_finger_the_hands_do_not_have_is_refused_when_built(tmp_path):
    import json
    from pathlib import Path

    from nlo_lab.robot import load_robot

    assets = Path(__file__).resolve().parents[2] / "assets" / "robots"
    spec = json.loads((assets / "yumi.json").read_text())
    spec["urdf"] = str(assets / "yumi.urdf")
    for arm in spec["arms"].values():
        del arm["fingers"]["pinky"]  # a four-finger hand: the pinky's joint moves a link no finger names
    (tmp_path / "four.json").write_text(json.dumps(spec))
    four = load_robot(tmp_path / "four.json")
    with pytest.raises(SettingsError, match=r"moves pinky alone.*thumb, index, middle, ring\)"):
        RetargetConfig(four, OptimizeSettings(hand_search=("ring", "pinky"))).build()
    RetargetConfig(four, OptimizeSettings(hand_search=("ring",)))._check_hand_search()  # a finger it has: accepted
    assert hand_search(four, OptimizeSettings()) == ("middle", "ring")  # the default: the fingers of HAND_SEARCH it has


def test_the_default_search_is_the_robots_fingers_of_hand_search(nao, model):
    from nlo_lab.robot import load_robot

    yumi = load_robot("yumi")
    assert OptimizeSettings().hand_search is None
    assert hand_search(yumi, OptimizeSettings()) == HAND_SEARCH == ("middle", "ring", "pinky")
    assert hand_search(nao, OptimizeSettings()) == ()  # no hand joints: nothing to search, and not refused
    assert hand_search(yumi, OptimizeSettings(hand_search=())) == ()  # none, when asked
    assert hand_search(yumi, OptimizeSettings(hand_search=("ring",))) == ("ring",)
    assert RetargetConfig(nao, OptimizeSettings(iterations=2), model=model).build().hand_search == ()


def test_the_default_pipeline_runs_the_finger_search(robots):
    """Without a setting the hand stage searches HAND_SEARCH: the same angles as naming those fingers, not those of no search."""
    yumi = robots["yumi"]
    demo = corpus_clip("introduction_06").slice(0, 12)
    model = load_pretrained(yumi)

    def angles(**hand):
        settings = OptimizeSettings(iterations=3, **hand)
        return np.asarray(RetargetConfig(yumi, settings, model=model).build()(demo).trajectory.angles)

    default = angles()
    np.testing.assert_array_equal(default, angles(hand_search=HAND_SEARCH))
    assert np.abs(default - angles(hand_search=())).max() > 1e-3


def test_the_evaluation_runs_the_pipeline(nao, model, demo, monkeypatch):
    s = BaselineSettings(iterations=5)
    ours = run_method("latent_encoder", nao, demo, s, model=model)
    targets = targets_from_demonstration(demo, dtype=nao.lower_limits.dtype)
    opt = OptimizeSettings(init="encoder", iterations=5, patience=s.patience, latent_sigma=s.random_sigma, seed=s.seed)
    direct = optimize_latent(model, nao, targets, opt, encoder_input=encoder_input(demo), fast=True)
    np.testing.assert_array_equal(ours.angles, direct.q.detach().double().numpy())

    def elsewhere(*args, **kwargs):
        raise RuntimeError("the pipeline ran")

    monkeypatch.setattr(Retargeter, "optimize", elsewhere)
    for method in ("latent_encoder", "encoder_only", "latent_random"):
        with pytest.raises(RuntimeError, match="the pipeline ran"):
            run_method(method, nao, demo, s, model=model)


def test_the_summary_counts_self_collisions_as_the_readable_metric(nao, model, demo, monkeypatch):
    """The retargeting's summary counts the self-collision frames by the culled check (its fast paths), the readable
    metric's count; on poses that collide, since the retargeted clip has none."""
    import dataclasses

    import nlo_lab.pipeline as pipeline
    from nlo_lab.metrics import self_collision_frames

    asked = []
    real = pipeline.self_collision_frames
    monkeypatch.setattr(pipeline, "self_collision_frames", lambda robot, angles, cull=False: asked.append(cull) or real(robot, angles, cull))
    result = RetargetConfig(nao, SETTINGS, model=model).build()(demo)
    readable = RetargetConfig(nao, SETTINGS, model=model, fast=False).build()(demo)
    assert asked == [True, False]  # the fast paths' check, and the readable one with fast=False
    assert result.summary["self_collision_frames"] == readable.summary["self_collision_frames"]
    g = torch.Generator().manual_seed(27)
    lo, hi = nao.lower_limits.double(), nao.upper_limits.double()
    q = (lo + (hi - lo) * torch.rand(len(demo), lo.shape[0], generator=g, dtype=torch.float64)).numpy()
    posed = dataclasses.replace(result, trajectory=dataclasses.replace(result.trajectory, angles=q))
    count = pipeline.summary(demo, nao, posed, cull=True)["self_collision_frames"]
    assert 0 < count < len(demo)
    assert count == pipeline.summary(demo, nao, posed)["self_collision_frames"] == self_collision_frames(nao, q)

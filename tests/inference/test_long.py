"""Long recordings: linear-memory Fréchet, chunked retargeting, a small viewer page."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
import umsgpack

from nlo_lab.inference import OptimizeSettings
from nlo_lab.metrics import frechet_distance, frechet_distance_reference
from nlo_lab.objective import LossWeights
from nlo_lab.pipeline import retarget
from nlo_lab.robot import load_robot
from nlo_lab.viz import _packing
from nlo_lab.viz.export import VIEWER_MAX_FRAMES, decimate, recording_visualizer, static_html


@pytest.mark.parametrize("n,m", [(2, 2), (63, 64), (64, 65), (65, 200), (130, 129), (300, 7), (1, 90), (90, 1)])
def test_frechet_equals_the_brute_force_across_block_edges(n, m):
    rng = np.random.default_rng(n * 1000 + m)
    P = np.cumsum(rng.normal(size=(n, 3)), 0)
    Q = np.cumsum(rng.normal(size=(m, 3)), 0)
    assert frechet_distance(P, Q) == pytest.approx(frechet_distance_reference(P, Q), abs=1e-12)
    assert frechet_distance(Q, P) == pytest.approx(frechet_distance_reference(P, Q), abs=1e-12)


def test_frechet_memory_is_linear():
    rng = np.random.default_rng(0)
    P, Q = rng.normal(size=(3000, 3)), rng.normal(size=(3000, 3))
    tracemalloc.start()
    try:
        frechet_distance(P, Q)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 8e6, peak  # the full 3000 x 3000 table alone is 72 MB


def test_chunked_retargeting_equals_one_batch(make_demo):
    robot = load_robot("nao")
    demo = make_demo(T=23)
    settings = OptimizeSettings(iterations=6, patience=100, init="random", seed=3)  # no early stop: chunks are exact
    # frames independent (no smoothness term, which couples neighbours across a chunk boundary)
    weights = LossWeights(smooth=0.0)
    whole = retarget(demo, robot, settings=settings, weights=weights, chunk_frames=None)
    chunked = retarget(demo, robot, settings=settings, weights=weights, chunk_frames=5)
    # the decoder computes in float32 and BLAS rounds differently per batch size: equal to
    # float32 rounding carried through six Adam steps (measured: at most 7e-6 rad)
    np.testing.assert_allclose(chunked.trajectory.angles, whole.trajectory.angles, atol=1e-4)
    np.testing.assert_allclose(chunked.optimization.history, whole.optimization.history, rtol=1e-4)
    assert chunked.optimization.iterations == whole.optimization.iterations == 6
    assert len(chunked.optimization.loss) == 23


def test_decimate_keeps_the_duration_and_short_clips_whole(make_demo):
    demo = make_demo(T=50, fps=10.0)
    q = np.arange(50.0)[:, None]
    assert decimate(q, demo, None, max_frames=50)[0] is q
    q2, d2, fps2 = decimate(q, demo, None, max_frames=20)  # every 3rd frame
    assert q2[:, 0].tolist() == list(range(0, 50, 3)) and len(d2) == len(q2)
    assert fps2 == pytest.approx(10.0 / 3)
    np.testing.assert_array_equal(d2.arm_positions, demo.arm_positions[::3])
    assert len(q2) / fps2 == pytest.approx(len(q) / 10.0, rel=0.05)


def test_viewer_page_of_a_long_recording_stays_small():
    robot = load_robot("nao")
    short = static_html(robot, np.zeros((VIEWER_MAX_FRAMES, robot.n_joints)), fps=20.0)
    long = static_html(robot, np.zeros((3 * VIEWER_MAX_FRAMES + 1, robot.n_joints)), fps=20.0)
    assert len(long) <= 1.01 * len(short)  # decimated to at most VIEWER_MAX_FRAMES keys


def test_single_precision_packing_equals_umsgpack(monkeypatch, make_demo):
    import meshcat.commands as mc

    from nlo_lab.viz.scene import RetargetScene

    robot = load_robot("nao")
    demo = make_demo(T=300, fps=20.0)
    scene = RetargetScene(recording_visualizer(single_precision=True), robot, np.random.default_rng(0).normal(size=(300, robot.n_joints)), demo=demo)
    command = mc.SetAnimation(scene.animation(), play=True, repetitions=0).lower()
    reference = umsgpack.packb(command, force_float_precision="single")
    assert _packing.packb_single(command) == reference
    monkeypatch.setattr(_packing, "FAST", False)
    assert _packing.packb_single(command) == reference
    keys = {"keys": [{"time": t, "value": [t * 0.5, -1.0, 3e-7]} for t in (*range(0, 300), 65535, 65536, 70000)]}
    monkeypatch.setattr(_packing, "FAST", True)
    assert _packing.packb_single(keys) == umsgpack.packb(keys, force_float_precision="single")


def test_retimed_animation_packs_equal_and_by_the_fast_path(monkeypatch, make_demo):
    """A retimed trajectory's keys have float times: they pack as umsgpack does, without one call per float
    (that fallback held ~400 MB of small byte strings for a 20,000-frame recording's viewer page)."""
    import meshcat.commands as mc

    from nlo_lab.viz.scene import RetargetScene
    from nlo_lab.viz.tracks import set_key_times

    robot = load_robot("nao")
    demo = make_demo(T=300, fps=20.0)
    scene = RetargetScene(recording_visualizer(single_precision=True), robot, np.random.default_rng(1).normal(size=(300, robot.n_joints)), demo=demo)
    leaves = []
    leaf = _packing._leaf
    monkeypatch.setattr(_packing, "_leaf", lambda obj: leaves.append(obj) or leaf(obj))
    counts = []
    for retimed in (False, True):
        anim = scene.animation()
        if retimed:
            set_key_times(anim, np.cumsum(np.random.default_rng(2).uniform(0.01, 0.2, size=300)))
        command = mc.SetAnimation(anim, play=True, repetitions=0).lower()
        leaves.clear()
        assert _packing.packb_single(command) == umsgpack.packb(command, force_float_precision="single")
        counts.append(len(leaves))
    assert counts[1] <= counts[0]  # retimed keys take the numpy path too, not one leaf per float (was 230x as many)
    mixed = {"keys": [{"time": 0, "value": [1.0]}, {"time": 0.5, "value": [2.0]}]}  # int and float times: the plain path
    assert _packing.packb_single(mixed) == umsgpack.packb(mixed, force_float_precision="single")


def _steps(angles: np.ndarray, robot) -> np.ndarray:
    """``(T-1,)`` the largest joint step between consecutive frames, in units of its velocity limit."""
    return (np.abs(np.diff(angles, axis=0)) / robot.velocity_limits.double().numpy()).max(1)


@pytest.mark.slow
def test_chunk_edges_are_as_smooth_as_the_inside():
    """With the smoothness term, a chunk starts anchored at the previous chunk's last frame:
    no step across a chunk edge is larger than the largest step inside the chunks."""
    from nlo_lab.corpus import sign_corpus

    robot = load_robot("yumi")
    demo = sign_corpus("test")[0]
    size = 12
    settings = OptimizeSettings(iterations=30)
    chunked = retarget(demo, robot, settings=settings, chunk_frames=size, retime=False)
    steps = _steps(chunked.trajectory.angles, robot)
    edge = np.zeros(len(steps), dtype=bool)
    edge[size - 1 :: size] = True  # step from frame k*size - 1 to k*size
    assert edge.sum() >= 3
    assert steps[edge].max() <= steps[~edge].max(), (steps[edge], steps[~edge].max())


def test_anchor_enters_the_smoothness_term(make_demo):
    """optimize_latent(anchor=q) charges frame 0 its step from q: far from the anchor costs more."""
    import torch

    from nlo_lab.inference import smoothness_term as _smoothness
    from nlo_lab.objective import smoothness_loss, targets_from_demonstration

    robot = load_robot("nao")
    t = targets_from_demonstration(make_demo(T=4), dtype=robot.lower_limits.dtype)
    weights = LossWeights()
    q = robot.neutral_q.expand(4, -1).clone()
    anchor = q[0] + 0.1
    smooth = _smoothness(robot, t, weights, anchor)
    expected = weights.smooth * smoothness_loss(torch.cat([anchor[None], q]), t.fps, robot.velocity_limits)[1:]
    torch.testing.assert_close(smooth(q), expected)
    assert float(smooth(q)[0]) > 0 and float(_smoothness(robot, t, weights)(q)[0]) == 0
    assert _smoothness(robot, t.index(slice(0, 1)), weights) is None
    assert _smoothness(robot, t.index(slice(0, 1)), weights, anchor) is not None

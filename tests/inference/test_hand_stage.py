"""The hand stage (issue 27): after the latent optimisation, the hand joints alone on the same objective.

It must lower the objective, move nothing but the hand joints (so the wrists, and Table I, stay),
keep the limits, and be what ``retarget`` runs on a robot with hands; the one-frame path
(``optimize_frame``: live, the lab's sliders) and robots without fingers skip it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from nlo_lab.errors import SettingsError
from nlo_lab.inference import HANDSHAPE_SEARCH, HANDSHAPE_SLOWDOWN, OptimizeSettings, smoothness_term
from nlo_lab.inference.hand_stage import (
    finger_joints,
    hand_joint_mask,
    path_within_caps,
    penetrating,
    refine_hands,
    searched_start,
    step_caps,
    within_speed,
)
from nlo_lab.inference.retime import segment_durations
from nlo_lab.model import load_pretrained
from nlo_lab.objective import LossWeights, Objective, point_plan, targets_from_demonstration
from nlo_lab.pipeline import RetargetConfig
from nlo_lab.robot import load_robot


@pytest.fixture(scope="module")
def yumi():
    return load_robot("yumi")


def test_hand_joint_mask_is_the_fingers_actuated_joints(yumi):
    names = [yumi.joint_names[i] for i in hand_joint_mask(yumi).nonzero().flatten()]
    assert names == [n for n in yumi.joint_names if "_hand_" in n] and len(names) == 12
    assert not hand_joint_mask(load_robot("nao")).any()


def test_refine_hands_lowers_the_objective_moving_only_the_hands_inside_their_limits(yumi, demonstration_from_robot, random_feasible_pose):
    q = random_feasible_pose(yumi, 6, seed=21).to(yumi.lower_limits.dtype)
    t = targets_from_demonstration(demonstration_from_robot(yumi, q), dtype=yumi.lower_limits.dtype)
    hand = hand_joint_mask(yumi)
    start = q.clone()
    start[:, hand] = yumi.lower_limits[hand]  # every hand open at its lower limits: far from the human's shape
    weights = LossWeights()
    loss = Objective(yumi, t, weights)
    out = refine_hands(yumi, start, t, weights, iterations=40)
    assert out.steps > 0
    assert float(loss(out.q)[0].sum()) < 0.5 * float(loss(start)[0].sum())
    torch.testing.assert_close(out.q[:, ~hand], start[:, ~hand], rtol=0, atol=0)  # the arms exactly where they were
    assert bool((out.q >= yumi.lower_limits).all() and (out.q <= yumi.upper_limits).all())
    plan = point_plan(yumi, out.q.dtype)
    with torch.no_grad():
        before, after = plan(start), plan(out.q)
    torch.testing.assert_close(after.wrist, before.wrist)  # what Table I scores does not move
    torch.testing.assert_close(after.elbow, before.elbow)
    assert float((after.finger_tip - before.finger_tip).norm(dim=-1).max()) > 0.01


def _opened_hands(yumi, demonstration_from_robot, random_feasible_pose, frames: int, seed: int):
    """float64 YuMi, a start with every hand joint at 0.4 rad, and the targets of a feasible pose's demonstration."""
    q = random_feasible_pose(yumi, frames, seed=seed).to(torch.float64)
    y64 = yumi.to(dtype=torch.float64)
    t = targets_from_demonstration(demonstration_from_robot(y64, q), dtype=torch.float64)
    start = q.clone()
    start[:, hand_joint_mask(y64)] = 0.4
    return y64, start, t


def test_fast_and_readable_hand_stage_agree(yumi, demonstration_from_robot, random_feasible_pose):
    y64, start, t = _opened_hands(yumi, demonstration_from_robot, random_feasible_pose, 3, 22)
    a = refine_hands(y64, start, t, iterations=5, fast=True)
    b = refine_hands(y64, start, t, iterations=5, fast=False)
    torch.testing.assert_close(a.q, b.q, rtol=1e-7, atol=1e-9)
    torch.testing.assert_close(a.loss, b.loss, rtol=1e-7, atol=1e-9)


def test_retarget_runs_the_hand_stage_on_a_robot_with_hands(yumi, demonstration_from_robot, random_feasible_pose):
    q = random_feasible_pose(yumi, 8, seed=23).to(yumi.lower_limits.dtype)
    demo = demonstration_from_robot(yumi, q)
    model = load_pretrained(yumi)
    hand = hand_joint_mask(yumi)
    retargeter = RetargetConfig(yumi, OptimizeSettings(iterations=5), model=model, retime=False).build()
    inputs = retargeter.inputs(demo)
    result = retargeter.optimize(inputs)
    assert result.extra["hand_steps"] > 0 and 0 < result.extra["hand_seconds"] < result.seconds
    chunked = RetargetConfig(yumi, OptimizeSettings(iterations=5), model=model, retime=False, chunk_frames=3).build().optimize(inputs)
    assert chunked.extra["hand_steps"] > 0 and chunked.extra["hand_seconds"] > 0 and chunked.q.shape == result.q.shape
    with torch.no_grad():
        decoded = model.decode(result.z).to(result.q.dtype)
    torch.testing.assert_close(result.q[:, ~hand], decoded[:, ~hand])  # the latent optimisation's arms
    assert float((result.q[:, hand] - decoded[:, hand]).abs().max()) > 1e-4  # the stage's hands
    # the stage's weights count in the loss it reports; the latent optimisation ran without its direction terms
    targets = inputs.targets.to(dtype=result.q.dtype)
    total, _ = Objective(yumi, targets, LossWeights())(result.q)
    total = total + smoothness_term(yumi, targets, LossWeights())(result.q) + result.z.pow(2).flatten(1).sum(1).to(total.dtype)
    assert float(result.terms["tip_dir"].sum()) > 0
    torch.testing.assert_close(total, result.loss.to(total.dtype), rtol=1e-4, atol=1e-3)
    # off: the decoder's angles
    off = RetargetConfig(yumi, OptimizeSettings(iterations=5, hand_iterations=0), model=model, retime=False).build().optimize(inputs)
    assert "hand_steps" not in off.extra
    with torch.no_grad():
        torch.testing.assert_close(off.q, model.decode(off.z).to(off.q.dtype))
    # one frame (live, the lab's sliders): latent optimisation only
    one = retargeter.optimize_frame(inputs, 0)
    assert "hand_steps" not in one.extra


def test_robots_without_fingers_skip_the_hand_stage(demonstration_from_robot, random_feasible_pose):
    nao = load_robot("nao")
    demo = demonstration_from_robot(nao, random_feasible_pose(nao, 4, seed=24).to(nao.lower_limits.dtype))
    retargeter = RetargetConfig(nao, OptimizeSettings(iterations=3), retime=False).build()
    assert not retargeter.has_hand_joints
    assert "hand_steps" not in retargeter.optimize(retargeter.inputs(demo)).extra


@pytest.mark.parametrize("field, value", [("hand_iterations", -1), ("hand_iterations", 1.5), ("hand_lr", 0.0), ("hand_lr", float("nan")),
                                          ("hand_search", ("ring", "toe")), ("hand_search", "ring"), ("hand_search", 3),
                                          ("hand_search", ("ring", "middle", "ring")),
                                          ("hand_grid", 1), ("hand_grid", 2.5), ("hand_slowdown", 0.5),
                                          ("hand_slowdown", float("nan")), ("hand_slowdown", 11.0), ("hand_slowdown", "2")])
def test_bad_hand_stage_settings_are_refused(field, value):
    with pytest.raises(SettingsError, match=field):
        dataclasses.replace(OptimizeSettings(), **{field: value})


def test_the_hand_stage_never_adds_a_self_collision(yumi, demonstration_from_robot):
    """Targets of a fist with the thumb through the index (the capsules penetrate) and no collision term: the
    stage would follow them into the collision; those frames keep the start's (collision-free) hands."""
    hand = hand_joint_mask(yumi)
    open_hand = yumi.neutral_q[None].repeat(3, 1)
    fist = open_hand.clone()
    fist[:, hand] = yumi.upper_limits[hand]
    assert bool(penetrating(yumi, fist).all()) and not bool(penetrating(yumi, open_hand).any())
    t = targets_from_demonstration(demonstration_from_robot(yumi, fist), dtype=yumi.lower_limits.dtype)
    weights = dataclasses.replace(LossWeights(), collision=0.0)
    out = refine_hands(yumi, open_hand, t, weights, iterations=60, lr=0.1)
    assert not bool(penetrating(yumi, out.q).any())
    assert bool(out.kept.any())
    torch.testing.assert_close(out.q[out.kept], open_hand[out.kept])
    fast = refine_hands(yumi, open_hand, t, weights, iterations=60, lr=0.1, fast=True)  # the start's points from the hand chains
    assert not bool(penetrating(yumi, fast.q).any()) and bool(fast.kept.any())
    # with the collision term the stage moves towards the fist as far as the capsules allow
    guarded = refine_hands(yumi, open_hand, t, LossWeights(), iterations=60, lr=0.1)
    assert not bool(penetrating(yumi, guarded.q).any())
    assert float((guarded.q[:, hand] - open_hand[:, hand]).abs().max()) > 0.1


def test_within_speed_never_steps_beyond_its_cap():
    x = torch.tensor([[0.0, 0.0], [0.4, 0.9], [0.4, 1.0]])
    cap = torch.tensor([[0.1, 0.5], [0.1, 0.5]])
    out = within_speed(x, cap)
    torch.testing.assert_close(out, torch.tensor([[0.0, 0.0], [0.1, 0.5], [0.2, 1.0]]))


def test_step_caps_give_every_joint_the_time_the_start_s_segment_takes():
    """A segment the start's fast joint 0 (1 rad/s) stretches to 0.5 s lets joint 1 (2 rad/s) step 1 rad there; a still
    segment 1/fps = 0.1 s: 0.2 rad; an unlimited joint neither stretches a segment nor is held."""
    start = torch.tensor([[0.0, 0.0, 0.0], [0.5, 0.0, 5.0], [0.5, 0.0, 5.0]])
    limits = torch.tensor([1.0, 2.0, float("inf")])
    caps = step_caps(start, limits, fps=10.0)
    torch.testing.assert_close(caps[:, :2], torch.tensor([[0.5, 1.0], [0.1, 0.2]]))
    assert bool(torch.isinf(caps[:, 2]).all())


def test_the_hand_stage_does_not_slow_the_robot(yumi, demonstration_from_robot, random_feasible_pose):
    """Targets whose hands jump between frames: the retimed segments of the stage's output are never longer than
    the start's (where the start is still, the hands step within their velocity limit at the recorded rate)."""
    q = random_feasible_pose(yumi, 6, seed=25).to(yumi.lower_limits.dtype)
    demo = demonstration_from_robot(yumi, q)
    t = targets_from_demonstration(demo, dtype=yumi.lower_limits.dtype)
    hand = hand_joint_mask(yumi)
    limits = yumi.velocity_limits.double().numpy()
    start = q.clone()
    start[:, hand] = yumi.lower_limits[hand]  # a still hand
    start[3:] = start[3]  # and a still robot from frame 3 on
    out = refine_hands(yumi, start, t, iterations=40, lr=0.1)
    before = segment_durations(start.double().numpy(), float(t.fps), limits)
    after = segment_durations(out.q.double().numpy(), float(t.fps), limits)
    assert (after <= before * (1 + 1e-6)).all(), (before, after)
    step = (out.q[4:, hand] - out.q[3:-1, hand]).abs()  # where the start stands still
    assert bool((step <= yumi.velocity_limits[hand] / float(t.fps) + 1e-6).all())
    assert float((out.q[:, hand] - start[:, hand]).abs().max()) > 0.05  # and the hands still moved
    assert bool((after[:2] > 1.0 / float(t.fps)).all())  # the arm's jumps are slow segments: the hands may use them


def test_penetrating_with_culling_gives_the_readable_verdicts(yumi):
    """Random poses over the whole joint ranges (many collide, many do not), and the fist of the test above."""
    g = torch.Generator().manual_seed(26)
    lo, hi = yumi.lower_limits, yumi.upper_limits
    q = lo + (hi - lo) * torch.rand(400, lo.shape[0], generator=g, dtype=lo.dtype)
    hand = hand_joint_mask(yumi)
    fist = yumi.neutral_q[None].repeat(2, 1)
    fist[:, hand] = hi[hand]
    q = torch.cat([q, fist, yumi.neutral_q[None]])
    readable = penetrating(yumi, q)
    assert 20 < int(readable.sum()) < len(q) - 20  # both verdicts occur
    assert torch.equal(penetrating(yumi, q, cull=True), readable)


def test_hand_chains_map_the_points_and_their_gradient_as_the_whole_tree(yumi):
    """FK from the wrists down with the arms fixed: the points plan.map gives for the whole q, and the same
    gradient in the hand joints (float64; random poses over the joint ranges)."""
    from nlo_lab.inference.hand_stage import HandChains

    y64 = yumi.to(dtype=torch.float64)
    plan = point_plan(y64, torch.float64)
    index = hand_joint_mask(y64).nonzero().flatten()
    chains = HandChains.build(y64, plan, index)
    assert chains is not None and 0 < len(chains.rows) < plan.vectors.shape[0]
    assert HandChains.build(y64, plan, index) is chains  # built once per plan and hands
    g = torch.Generator().manual_seed(27)
    lo, hi = y64.lower_limits, y64.upper_limits
    q0 = lo + (hi - lo) * torch.rand(6, lo.shape[0], generator=g, dtype=lo.dtype)
    x = (lo + (hi - lo) * torch.rand(6, lo.shape[0], generator=g, dtype=lo.dtype))[:, index]
    weight = torch.randn(6, plan.vectors.shape[0], 3, generator=g, dtype=lo.dtype)
    grads, points = [], []
    for fast in (True, False):
        xx = x.clone().requires_grad_(True)
        if fast:
            with torch.no_grad():
                fixed, wrists = plan.map(q0), y64.forward_kinematics_links(q0, chains.wrists)[..., :3, :]
            p = chains(xx, fixed, wrists)
        else:
            p = plan.map(q0.index_copy(1, index, xx))
        (grad,) = torch.autograd.grad((p * weight).sum(), xx)
        points.append(p.detach())
        grads.append(grad)
    torch.testing.assert_close(points[0], points[1], rtol=0, atol=1e-12)
    torch.testing.assert_close(grads[0], grads[1], rtol=1e-10, atol=1e-10)
    assert float(grads[1].abs().min()) > 0  # every hand joint moves some point


def test_held_terms_give_the_terms_and_hand_gradient_of_the_whole_objective(yumi, demonstration_from_robot, random_angles):
    """PointTerms.held (the hand stage's numpy terms, the arms' capsule pairs measured once): for points that
    differ from the held ones only below the wrists, the same terms and the same gradient onto the moving points."""
    import numpy as np

    from nlo_lab.inference.hand_stage import HandChains

    y64 = yumi.to(dtype=torch.float64)
    q0 = random_angles(y64, 8, seed=28).to(torch.float64)  # arms anywhere in their ranges: some arm pairs within their margins
    t = targets_from_demonstration(demonstration_from_robot(y64, random_angles(y64, 8, seed=30)), dtype=torch.float64)
    index = hand_joint_mask(y64).nonzero().flatten()
    loss = Objective(y64, t, LossWeights(), fused=True)
    chains = HandChains.build(y64, loss.plan, index)
    moving = np.zeros(loss.plan.vectors.shape[0], dtype=bool)
    moving[chains.rows.numpy()] = True
    with torch.no_grad():
        fixed = loss.plan.map(q0)
    held = loss.numpy_terms.held(moving, fixed.numpy())
    assert 0 < len(held.radii) < len(loss.numpy_terms.radii)
    assert float(held.collision_held.max()) > 0  # some arm pairs within their margin: the held share counts
    g = torch.Generator().manual_seed(29)
    for _ in range(3):
        q = q0.clone()
        q[:, index] = (yumi.lower_limits[index] + (yumi.upper_limits[index] - yumi.lower_limits[index])
                       * torch.rand(8, len(index), generator=g, dtype=torch.float64))  # any hand, some closed on themselves
        with torch.no_grad():
            P = loss.plan.map(q).numpy()
        a, b = held.forward(P), loss.numpy_terms.forward(P)
        np.testing.assert_allclose(a[0], b[0], rtol=1e-12, atol=1e-12)
        G = np.linspace(0.5, 1.5, a[0].size).reshape(a[0].shape)
        np.testing.assert_allclose(held.backward(G, a[1])[:, moving], loss.numpy_terms.backward(G, b[1])[:, moving], rtol=1e-12, atol=1e-12)
    assert float(b[0][:, 4].max()) > 0  # the collision term acts


def test_penetrating_takes_the_points_mapped_already(yumi):
    """The hand stage passes the start's points it mapped once: the same verdicts as mapping them here."""
    g = torch.Generator().manual_seed(28)
    lo, hi = yumi.lower_limits, yumi.upper_limits
    q = lo + (hi - lo) * torch.rand(200, lo.shape[0], generator=g, dtype=lo.dtype)
    with torch.no_grad():
        points = point_plan(yumi, q.dtype).map(q)
    verdicts = penetrating(yumi, q, cull=True)
    assert 10 < int(verdicts.sum()) < len(q) - 10
    assert torch.equal(penetrating(yumi, q, cull=True, points=points), verdicts)


def test_the_start_s_collisions_are_measured_only_when_the_stage_s_hands_collide(yumi, demonstration_from_robot, random_feasible_pose,
                                                                                   monkeypatch):
    """A stage whose hands stay free of collision asks ``penetrating`` once (its own output), not for the start too."""
    import nlo_lab.inference.hand_stage as stage

    q = random_feasible_pose(yumi, 4, seed=29).to(yumi.lower_limits.dtype)
    t = targets_from_demonstration(demonstration_from_robot(yumi, q), dtype=yumi.lower_limits.dtype)
    calls = []
    real = stage.penetrating

    def counted(robot, angles, cull=False, points=None):
        calls.append(points is not None)
        return real(robot, angles, cull, points=points)

    monkeypatch.setattr(stage, "penetrating", counted)
    for fast in (False, True):
        calls.clear()
        out = refine_hands(yumi, q, t, iterations=5, fast=fast)
        assert not bool(penetrating(yumi, out.q).any())
        assert calls == [False]


def test_a_hand_never_seen_keeps_the_start_joints_and_the_seen_hand_is_refined_alike_fast_and_readable(yumi, demonstration_from_robot,
                                                                                                       random_feasible_pose):
    """A clip that shows only the right hand: the left hand's joints come back bit for bit the start's (nothing
    to follow: only the latent stage moves it), the right hand's are refined, and the fast stage (the hand chains
    of the right hand alone, the numpy terms without the left hand's items) gives the readable stage's result."""
    y64 = yumi.to(dtype=torch.float64)
    q = random_feasible_pose(yumi, 5, seed=32).to(torch.float64)
    t = targets_from_demonstration(demonstration_from_robot(y64, q), dtype=torch.float64)
    mask = t.finger_mask.clone()
    mask[:, 0] = False  # the left hand unseen in every frame
    t = dataclasses.replace(t, finger_mask=mask)
    left, right = hand_joint_mask(y64, ["left"]), hand_joint_mask(y64, ["right"])
    assert left.sum() == right.sum() == 6 and not bool((left & right).any())
    start = q.clone()
    start[:, left | right] = 0.4
    a = refine_hands(y64, start, t, iterations=8, fast=True)
    b = refine_hands(y64, start, t, iterations=8, fast=False)
    for out in (a, b):
        assert out.steps > 0 and torch.equal(out.q[:, ~right], start[:, ~right])  # the left hand and the arms: the start's
        assert float((out.q[:, right] - start[:, right]).abs().max()) > 0.05
    torch.testing.assert_close(a.q, b.q, rtol=1e-7, atol=1e-9)
    torch.testing.assert_close(a.loss, b.loss, rtol=1e-7, atol=1e-9)
    none = dataclasses.replace(t, finger_mask=torch.zeros_like(mask))
    assert torch.equal(refine_hands(y64, start, none, iterations=8, fast=True).q, start)  # no hand seen: nothing moves


@pytest.mark.parametrize("anchored", [False, True])
def test_hand_stage_loss_written_out_equals_the_readable_loss_and_gradient(yumi, demonstration_from_robot, random_angles, anchored):
    """HandStageLoss (FastPaths.written_gradient: FK of the hand chains, the held numpy terms and the smoothness
    term chained by hand) against autograd through the readable objective and smoothness term (float64)."""
    import numpy as np

    from nlo_lab.inference.hand_stage import HandChains, HandStageLoss
    from nlo_lab.objective.numpy_backend import SmoothTerm

    y64 = yumi.to(dtype=torch.float64)
    q0 = random_angles(y64, 7, seed=33).to(torch.float64)  # arms anywhere: some pairs within their margins
    t = targets_from_demonstration(demonstration_from_robot(y64, random_angles(y64, 7, seed=34)), dtype=torch.float64)
    weights = LossWeights()
    anchor = random_angles(y64, 1, seed=35)[0].to(torch.float64) if anchored else None
    index = hand_joint_mask(y64).nonzero().flatten()
    fused = Objective(y64, t, weights, fused=True)
    chains = HandChains.build(y64, fused.plan, index)
    moving = np.zeros(fused.plan.vectors.shape[0], dtype=bool)
    moving[chains.rows.numpy()] = True
    with torch.no_grad():
        fixed = fused.plan.map(q0)
        wrists = y64.forward_kinematics_links(q0, chains.wrists)[..., :3, :]
    smooth = SmoothTerm(float(t.fps), y64.velocity_limits, weights.smooth, anchor, torch.float64)
    written = HandStageLoss(chains, fused.numpy_terms.held(moving, fixed.numpy()), fused.weights, fixed, wrists, q0, index, smooth)
    readable, smooth_torch = Objective(y64, t, weights), smoothness_term(y64, t, weights, anchor)
    g = torch.Generator().manual_seed(36)
    lo, hi = y64.lower_limits[index], y64.upper_limits[index]
    for _ in range(2):
        x = (lo + (hi - lo) * torch.rand(7, len(index), generator=g, dtype=torch.float64)).requires_grad_(True)
        full = q0.index_copy(1, index, x)
        total, terms = readable(full)
        total = total + smooth_torch(full)
        (grad,) = torch.autograd.grad(total.sum(), x)
        loss, q, terms_w, grad_w = written(x.detach())
        torch.testing.assert_close(loss, total.detach(), rtol=1e-10, atol=1e-10)
        torch.testing.assert_close(terms_w, terms.detach(), rtol=1e-10, atol=1e-10)
        torch.testing.assert_close(q, full.detach(), rtol=0, atol=0)
        torch.testing.assert_close(grad_w, grad, rtol=1e-9, atol=1e-9)
        value = written.value(x.detach())  # the result's evaluation after the clamp: the same, without the gradient
        for a, b in zip(value, (loss, q, terms_w), strict=True):
            torch.testing.assert_close(a, b, rtol=0, atol=0)
        assert float(grad.abs().min()) > 0 and float(terms.detach()[:, 4].max()) > 0  # every hand joint pulled; the collision term acts


def test_the_fast_hand_stage_takes_the_written_gradient(yumi, demonstration_from_robot, random_feasible_pose, monkeypatch):
    """refine_hands(fast=True) descends on HandStageLoss, and its result is the readable stage's (float64)."""
    import nlo_lab.inference.hand_stage as hand_stage

    calls = []
    original = hand_stage.HandStageLoss.__call__
    monkeypatch.setattr(hand_stage.HandStageLoss, "__call__", lambda self, x: calls.append(1) or original(self, x))
    y64, start, t = _opened_hands(yumi, demonstration_from_robot, random_feasible_pose, 6, 37)
    a = refine_hands(y64, start, t, iterations=10, fast=True)
    assert len(calls) == a.steps + 1 > 1  # every evaluation of the descent
    b = refine_hands(y64, start, t, iterations=10, fast=False)
    torch.testing.assert_close(a.q, b.q, rtol=1e-7, atol=1e-9)
    torch.testing.assert_close(a.loss, b.loss, rtol=1e-7, atol=1e-9)


def test_compact_terms_keep_only_what_reaches_a_moving_point(yumi, demonstration_from_robot, random_angles):
    """The hand stage's terms over the points it needs: every moving point, no arm row (ee, ori, elbow: a
    constant per frame), and the whole held terms' values at the start (the held rows' share as that constant)."""
    import numpy as np

    from nlo_lab.inference.hand_stage import HandChains, compact_terms

    y64 = yumi.to(dtype=torch.float64)
    q0 = random_angles(y64, 5, seed=40).to(torch.float64)
    t = targets_from_demonstration(demonstration_from_robot(y64, random_angles(y64, 5, seed=41)), dtype=torch.float64)
    index = hand_joint_mask(y64).nonzero().flatten()
    loss = Objective(y64, t, LossWeights(), fused=True)
    chains = HandChains.build(y64, loss.plan, index)
    rows = chains.rows.numpy()
    moving = np.zeros(loss.plan.vectors.shape[0], dtype=bool)
    moving[rows] = True
    with torch.no_grad():
        fixed = loss.plan.map(q0).numpy()
    held = loss.numpy_terms.held(moving, fixed)
    compact, keep, at, constant = compact_terms(held, rows, fixed)
    assert np.array_equal(keep[at], rows) and len(keep) < fixed.shape[1]
    assert np.array_equal(at, np.arange(len(keep) - len(rows), len(keep)))  # the moving points: the last block, in order
    assert compact.rows.shape[0] == len(compact.fingers) < held.rows.shape[0]  # only the finger rows move
    assert float(constant[:, :3].min()) > 0  # ee, ori, elbow: held, and not zero for random arms
    whole, part = held.forward(fixed)[0], compact.forward(np.ascontiguousarray(fixed[:, keep]))[0]
    part[:, :4] += constant
    np.testing.assert_allclose(part, whole, rtol=1e-12, atol=1e-12)


def test_a_frame_that_keeps_the_start_s_hands_is_not_jumped_into(yumi, demonstration_from_robot):
    """Frames 0-1 and 3-4 ask for curled fingers with the thumb turned in but not bent (no collision), frame 2 for the
    fist with the thumb through the index; the start is an open hand at rest, 2 frames a second (caps of 1 rad). Frame
    2 keeps the start's hands (the collision rule); its neighbours, which the stage curled, must then come back within
    the speed clamp's caps of it: a jump into the kept frame would stretch its retimed segment beyond the start's (one
    held-out clip of the synthetic corpus's test split, 2026-11-27: 0.21 rad over the cap)."""
    hand = hand_joint_mask(yumi)
    names = [yumi.joint_names[j] for j in hand.nonzero().flatten().tolist()]
    pitch = torch.tensor(["thumb_proximal_pitch" in n for n in names])
    open_hand = yumi.neutral_q[None].repeat(5, 1)
    curled, fist = open_hand.clone(), open_hand.clone()
    curled[:, hand] = torch.where(pitch, yumi.lower_limits[hand], yumi.upper_limits[hand])
    fist[:, hand] = yumi.upper_limits[hand]
    goal = torch.cat([curled[:2], fist[2:3], curled[3:]])
    assert not bool(penetrating(yumi, curled).any()) and bool(penetrating(yumi, fist).all())
    t = targets_from_demonstration(demonstration_from_robot(yumi, goal, fps=2.0), dtype=yumi.lower_limits.dtype)
    caps = step_caps(open_hand, yumi.velocity_limits, float(t.fps))[:, hand]
    for fast in (False, True):
        out = refine_hands(yumi, open_hand, t, dataclasses.replace(LossWeights(), collision=0.0), iterations=60, lr=0.1, fast=fast)
        assert out.kept.tolist() == [False, False, True, False, False]
        torch.testing.assert_close(out.q[2], open_hand[2])
        assert not bool(penetrating(yumi, out.q).any())
        over = (out.q[1:, hand] - out.q[:-1, hand]).abs() - caps
        assert float(over.max()) <= 1e-6, float(over.max())
        assert float((out.q[:, hand] - open_hand[:, hand]).abs().max()) > 0.1  # the other frames still curled


@settings(max_examples=300, deadline=None)
@given(st.integers(2, 12), st.integers(1, 3), st.integers(0, 2**32 - 1))
def test_within_speed_keeps_pinned_frames_and_every_cap(frames, joints, seed):
    """Pinned frames within the caps of one another (as the start's are) stay bit for bit; every step ends within its
    cap, wherever the free frames were."""
    g = np.random.default_rng(seed)
    cap = torch.tensor(g.uniform(0.01, 0.5, (frames - 1, joints)))
    start = torch.tensor(np.cumsum(np.concatenate([g.uniform(-1, 1, (1, joints)), g.uniform(-1, 1, (frames - 1, joints)) * cap.numpy()]), 0))
    pinned = torch.tensor(g.random(frames) < 0.4)
    x = torch.where(pinned[:, None], start, torch.tensor(g.uniform(-3, 3, (frames, joints))))
    out = within_speed(x, cap, pinned)
    assert torch.equal(out[pinned], x[pinned])
    assert float(((out[1:] - out[:-1]).abs() - cap).max()) <= 1e-12
    if not bool(pinned.any()):
        torch.testing.assert_close(out, within_speed(x, cap))


# --- the finger search (refine_hands' ``search``): a path of least objective through each finger joint's grid


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 4), st.integers(1, 5), st.booleans())
def test_the_path_within_caps_is_the_cheapest_of_all_paths_that_keep_the_caps(seed, G, T, capped):
    """Against every one of the G^T paths: the same least total, and the path found keeps every cap."""
    import itertools

    rng = np.random.default_rng(seed)
    cost, values = rng.random((G, T)), np.sort(rng.uniform(-1, 1, G))
    caps = rng.uniform(0, 1.5, T - 1) if capped else None
    path, total = path_within_caps(cost, values, caps)
    feasible = [p for p in itertools.product(range(G), repeat=T)
                if caps is None or all(abs(values[p[t]] - values[p[t - 1]]) <= caps[t - 1] + 1e-9 for t in range(1, T))]
    best = min(sum(cost[i, t] for t, i in enumerate(p)) for p in feasible)
    assert total == pytest.approx(best, abs=1e-12) and total == pytest.approx(cost[path, np.arange(T)].sum(), abs=1e-12)
    if caps is not None:
        assert (np.abs(np.diff(values[path])) <= caps + 1e-9).all()


def test_the_search_leaves_a_basin_that_descent_stays_in_and_never_costs_more_than_the_start():
    """One joint of two basins (a local minimum at 0.8, the global at -0.6) started in the local one, frames free
    to move 0.3 per step: the search crosses to the global minimum; where no grid path beats the start it keeps
    the start."""
    T, lo, hi = 6, torch.tensor([-1.0, -1.0]), torch.tensor([1.0, 1.0])

    def two_basins(x):  # (T,): column 0 matters; column 1 is carried along untouched
        a = x[:, 0]
        return torch.minimum((a - 0.8) ** 2 + 0.2, (a + 0.6) ** 2)

    start = torch.tensor([[0.8, 0.5]] * T, dtype=torch.float64)
    caps = torch.full((T - 1, 2), 0.3, dtype=torch.float64)
    out = searched_start(start, two_basins, [0], lo, hi, caps, grid=21)
    assert float(two_basins(out).sum()) < float(two_basins(start).sum())
    assert abs(float(out[-1, 0]) + 0.6) < 0.051 and (out[:, 1] == 0.5).all()
    assert (out[1:, 0] - out[:-1, 0]).abs().max() <= 0.3 + 1e-9  # the way there within the caps
    best_start = torch.tensor([[-0.6, 0.5]] * T, dtype=torch.float64)  # not on the grid of 4 values
    torch.testing.assert_close(searched_start(best_start, two_basins, [0], lo, hi, caps, grid=4), best_start)


def test_finger_joints_are_the_joints_that_move_that_finger_alone(yumi):
    for side, c in (("left", "l"), ("right", "r")):
        for finger, own in (("index", "index_proximal"), ("middle", "middle_proximal"), ("ring", "ring_proximal"),
                            ("pinky", "pinky_proximal")):
            assert [yumi.joint_names[j] for j in finger_joints(yumi, side, finger)] == [f"yumi_hand_{c}_{own}_joint"]
        thumb = {yumi.joint_names[j] for j in finger_joints(yumi, side, "thumb")}
        assert thumb == {f"yumi_hand_{c}_thumb_proximal_yaw_joint", f"yumi_hand_{c}_thumb_proximal_pitch_joint"}
    assert finger_joints(load_robot("nao"), "left", "ring") == []


def test_a_searched_hand_stage_is_the_same_fast_and_readable_and_moves_the_searched_fingers(yumi, demonstration_from_robot,
                                                                                          random_feasible_pose):
    """The search's table comes from either form of the objective: the same hands. Started with the ring and the
    little finger curled at their upper limit where the targets' are open, the search opens them."""
    y64, start, t = _opened_hands(yumi, demonstration_from_robot, random_feasible_pose, 4, 31)
    curled = start.clone()
    ring_little = [y64.joint_names.index(f"yumi_hand_{c}_{f}_proximal_joint") for c in "lr" for f in ("ring", "pinky")]
    curled[:, ring_little] = y64.upper_limits[ring_little]
    a = refine_hands(y64, curled, t, iterations=3, fast=True, search=("ring", "pinky"))
    b = refine_hands(y64, curled, t, iterations=3, fast=False, search=("ring", "pinky"))
    torch.testing.assert_close(a.q, b.q, rtol=1e-7, atol=1e-9)
    plain = refine_hands(y64, curled, t, iterations=3, fast=True)
    assert float(a.loss.sum()) < float(plain.loss.sum())
    assert (a.q[:, ring_little] < plain.q[:, ring_little] - 0.1).any()


def test_the_hand_stage_slows_the_robot_at_most_by_its_slowdown(yumi, demonstration_from_robot, random_feasible_pose):
    """The same jumping targets with ``slowdown=2``: every retimed segment at most twice the start's, and some longer
    than the start's (the clamp of slowdown 1 would not allow it)."""
    q = random_feasible_pose(yumi, 6, seed=25).to(yumi.lower_limits.dtype)
    t = targets_from_demonstration(demonstration_from_robot(yumi, q), dtype=yumi.lower_limits.dtype)
    hand = hand_joint_mask(yumi)
    limits = yumi.velocity_limits.double().numpy()
    start = q.clone()
    start[:, hand] = yumi.lower_limits[hand]
    start[3:] = start[3]
    before = segment_durations(start.double().numpy(), float(t.fps), limits)
    after = segment_durations(refine_hands(yumi, start, t, iterations=40, lr=0.1, slowdown=2.0).q.double().numpy(), float(t.fps), limits)
    assert (after <= 2.0 * before * (1 + 1e-6)).all(), (before, after)
    assert (after > before * (1 + 1e-3)).any(), (before, after)
    with pytest.raises(SettingsError, match="slowdown"):
        refine_hands(yumi, start, t, iterations=1, slowdown=0.9)


def test_the_handshape_settings_are_the_preset_s():
    preset = OptimizeSettings.handshape()
    assert (preset.hand_search, preset.hand_slowdown) == (HANDSHAPE_SEARCH, HANDSHAPE_SLOWDOWN)
    assert OptimizeSettings.handshape(hand_slowdown=1.0, iterations=3) == dataclasses.replace(preset, hand_slowdown=1.0, iterations=3)
    assert OptimizeSettings().hand_slowdown == 1.0


def test_retarget_passes_the_slowdown_to_the_stage(yumi, demonstration_from_robot, random_feasible_pose, monkeypatch):
    import nlo_lab.pipeline as pipeline

    seen = []
    real = pipeline.refine_hands
    monkeypatch.setattr(pipeline, "refine_hands", lambda *a, **k: seen.append(k["slowdown"]) or real(*a, **k))
    q = random_feasible_pose(yumi, 3, seed=5).to(yumi.lower_limits.dtype)
    RetargetConfig(yumi, OptimizeSettings(iterations=1, hand_iterations=1, hand_slowdown=3.5), retime=False).build()(demonstration_from_robot(yumi, q))
    assert seen == [3.5]


def test_retarget_passes_the_hand_search_to_the_stage(yumi, demonstration_from_robot, random_feasible_pose, monkeypatch):
    import nlo_lab.inference.hand_stage as stage

    seen = []
    real = stage.searched_start
    monkeypatch.setattr(stage, "searched_start", lambda x, f, columns, *a, **k: seen.append(len(columns)) or real(x, f, columns, *a, **k))
    q = random_feasible_pose(yumi, 4, seed=5).to(yumi.lower_limits.dtype)
    settings_ = OptimizeSettings(iterations=2, hand_iterations=2, hand_search=("middle", "ring"), hand_grid=4)
    RetargetConfig(yumi, settings_, retime=False).build()(demonstration_from_robot(yumi, q))
    assert seen == [4]  # both hands shown: their middle and ring joints

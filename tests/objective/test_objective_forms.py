"""The objective's faster forms (numpy terms, culled capsule pairs, FK's closed-form gradient)
equal the term functions, values and gradients; called without asking, Objective runs the
term functions (what a learner reads), every capsule pair, autograd through FK."""

from __future__ import annotations

import pytest
import torch

from nlo_lab.objective import Objective, targets_from_demonstration


@pytest.fixture(scope="module")
def robot(each_robot64):
    return each_robot64


@pytest.fixture(scope="module")
def case(robot, random_angles, demonstration_from_robot):
    """``case(frames)``: targets the robot meets at one pose, and other (random, some colliding) poses to score."""

    def make(frames: int):
        t = targets_from_demonstration(demonstration_from_robot(robot, random_angles(robot, frames, seed=9)), dtype=torch.float64)
        return t, random_angles(robot, frames, seed=7)

    return make


def _terms_and_grad(objective: Objective, q: torch.Tensor):
    x = q.detach().clone().requires_grad_(True)
    terms = objective(x)[1]
    w = torch.linspace(0.5, 1.5, terms.numel(), dtype=terms.dtype).view_as(terms)  # every term counts, differently
    (g,) = torch.autograd.grad((terms * w).sum(), x)
    return terms.detach(), g


@pytest.mark.parametrize("options", [
    {"fused": True}, {"cull": True}, {"analytic_fk": True}, {"fused": True, "cull": True, "analytic_fk": True},
], ids=lambda o: "+".join(o))
def test_each_faster_form_equals_the_term_functions(robot, case, options):
    t, q = case(48)
    for form in ("hinge", "paper"):
        fast = _terms_and_grad(Objective(robot, t, collision_form=form, **options), q)
        ref = _terms_and_grad(Objective(robot, t, collision_form=form), q)
        for a, b in zip(fast, ref, strict=True):
            torch.testing.assert_close(a, b, atol=1e-9, rtol=1e-10)
        assert float(ref[0][:, 4].max()) > 0, "some random poses should bring capsules within their margin"


def test_objective_called_directly_runs_the_term_functions(robot, case, monkeypatch):
    """Without an argument every term function of nlo_lab.objective.terms runs (all capsule
    pairs measured, autograd through FK); asked for, the numpy terms run instead."""
    from nlo_lab.objective import terms, total
    from nlo_lab.robot import point_gradient

    def _raise(*args, **kwargs):
        raise AssertionError("a fast path ran")

    names = ("end_effector_loss", "orientation_loss", "elbow_loss", "finger_loss", "collision_loss", "capsule_distances")
    calls = []
    for name in names:
        fn = getattr(terms, name)
        monkeypatch.setattr(total, name, lambda *a, _fn=fn, **k: calls.append(_fn.__name__) or _fn(*a, **k))
    for name in ("point_terms", "near_pair_distances"):
        monkeypatch.setattr(total, name, _raise)
    monkeypatch.setattr(point_gradient.MapPoints, "apply", _raise)
    t, q = case(4)
    total.Objective(robot, t)(q.requires_grad_(True))[0].sum().backward()
    assert sorted(calls) == sorted(names)
    for options in ({"fused": True}, {"cull": True}, {"analytic_fk": True}):
        with pytest.raises(AssertionError, match="fast path"):
            total.Objective(robot, t, **options)(q)


def test_objective_function_passes_the_faster_forms_on(robot, case):
    from nlo_lab.objective import objective

    t, q = case(6)
    fast = objective(robot, q, t, fused=True, cull=True, analytic_fk=True)
    ref = objective(robot, q, t)
    torch.testing.assert_close(fast[0], ref[0], atol=1e-9, rtol=1e-10)


def test_numpy_hand_terms_equal_the_term_functions_with_masks_and_pinches(robot, case):
    """The hand terms' numpy form (HandTerms): fingers and wrist frames unobserved, thumbs touching fingertips."""
    import dataclasses

    from nlo_lab.objective import HAND_TERMS, TERMS

    t, q = case(6)
    tip, finger_mask, wrist_mask = t.finger_tip.clone(), t.finger_mask.clone(), t.wrist_mask.clone()
    tip[:, :, 0] = tip[:, :, 1] + 0.004  # every thumb on its index fingertip: a pinch
    finger_mask[1, 0, 3], finger_mask[2, 1, :] = False, False  # a ring finger, then a whole hand unseen
    wrist_mask[3, 0] = False  # a wrist frame unseen: that hand's tip and thumb vectors do not count
    t = dataclasses.replace(t, finger_tip=tip, finger_mask=finger_mask, wrist_mask=wrist_mask)
    fast = _terms_and_grad(Objective(robot, t, fused=True), q)
    ref = _terms_and_grad(Objective(robot, t), q)
    for a, b in zip(fast, ref, strict=True):
        torch.testing.assert_close(a, b, atol=1e-9, rtol=1e-10)
    hand = ref[0][:, [TERMS.index(n) for n in HAND_TERMS]]
    if robot.has_fingers:
        assert float(hand[:, 2].max()) > 0, "the pinch should act"
        assert float(hand[:, :2].min()) > 0
    else:
        assert float(hand.abs().max()) == 0


def test_the_numpy_culling_bound_never_leaves_out_a_near_pair():
    """maybe_near keeps every pair of segments closer than the clearance (random segments, some
    crossing at their midpoints, parallel, touching, of any length), and leaves out far ones."""
    import numpy as np

    from nlo_lab.objective.numpy_backend import maybe_near
    from nlo_lab.robot.collision import segment_closest_points

    rng = np.random.default_rng(0)
    B, C = 400, 6
    centre = rng.normal(scale=0.15, size=(B, C, 1, 3))
    half = rng.normal(size=(B, C, 1, 3)) * rng.uniform(0, 0.3, size=(B, C, 1, 1))
    caps = np.concatenate([centre - half, centre + half], 2)
    caps[:50, 1] = caps[:50, 0][:, ::-1]  # capsule 1 = capsule 0 reversed: the same midpoint, crossing
    caps[50:100, 2] = caps[50:100, 0] + [0.0, 0.05, 0.0]  # parallel copies 5 cm apart
    pairs = np.array([(i, j) for i in range(C) for j in range(i + 1, C)])
    clearance = rng.uniform(0.0, 0.1, size=len(pairs))
    ends = np.concatenate([caps[:, pairs[:, 0]], caps[:, pairs[:, 1]]], 2).reshape(-1, 4, 3)  # (B P, 4, 3)
    dist = segment_closest_points(ends.transpose(1, 2, 0).copy())[3]
    kept = np.zeros(len(dist), dtype=bool)
    kept[maybe_near(caps.astype(np.float32), pairs, clearance)] = True
    close = dist < np.tile(clearance, B)
    assert close.sum() > 100 and (~close).sum() > 100
    assert kept[close].all(), "a pair within the clearance was left out"
    assert (~kept[~close]).mean() > 0.5  # and it does cull


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_the_culling_search_keeps_exactly_the_pairs_of_the_separating_axis_bound(dtype):
    """maybe_near takes the separating-axis bound only where the spheres around the segments may be near: the
    pairs it keeps, in their order, are those of the bound taken on every pair (random segments, crossing,
    parallel, of any length)."""
    import numpy as np

    from nlo_lab.objective.numpy_backend import _bound_below, maybe_near

    rng = np.random.default_rng(5)
    B, C = 300, 7
    centre = rng.normal(scale=0.15, size=(B, C, 1, 3))
    direction = rng.normal(size=(B, C, 1, 3))
    half = direction / np.linalg.norm(direction, axis=-1, keepdims=True) * rng.uniform(0, 0.3, size=(1, C, 1, 1))  # rigid
    caps = np.concatenate([centre - half, centre + half], 2).astype(dtype)
    caps[:40, 1] = caps[:40, 0][:, ::-1]  # crossing at their midpoints
    caps[40:80, 2] = caps[40:80, 0] + np.array([0.0, 0.05, 0.0], dtype=dtype)  # parallel, 5 cm apart
    axis = caps[80:160, 0, 1] - caps[80:160, 0, 0]  # in line, end to end, 0 to 10 cm apart: there the spheres'
    shift = 1.0 + rng.uniform(0.0, 0.1, size=(80, 1)) / np.linalg.norm(axis, axis=-1, keepdims=True)  # bound is the bound
    caps[80:160, 3] = caps[80:160, 0] + (shift * axis)[:, None].astype(dtype)
    pairs = np.array([(i, j) for i in range(C) for j in range(i + 1, C)])
    clearance = rng.uniform(0.0, 0.1, size=len(pairs))
    a, b = caps[:, pairs[:, 0]], caps[:, pairs[:, 1]]  # (B, P, 2, 3)
    planes = lambda x: np.moveaxis(x, -1, 0)  # noqa: E731  (3, B, P)
    gap = planes(b[:, :, 0] + b[:, :, 1] - a[:, :, 0] - a[:, :, 1])
    every = _bound_below(gap, planes(a[:, :, 1] - a[:, :, 0]), planes(b[:, :, 1] - b[:, :, 0]), (2.0 * clearance).astype(dtype))
    expected = np.flatnonzero(every)  # (B, P): frame-major
    kept = maybe_near(caps, pairs, clearance)
    assert 100 < len(expected) < every.size / 2
    np.testing.assert_array_equal(kept, expected)
    few = expected[expected < 8 * len(pairs)]  # a few frames: the bound on every pair, no sphere test
    assert len(few) > 0
    np.testing.assert_array_equal(maybe_near(caps[:8], pairs, clearance), few)


def test_near_pairs_kept_across_calls_give_bit_for_bit_the_terms_of_a_search_every_call(random_angles, demonstration_from_robot):
    """An optimisation's calls (small steps, and some frames that jump): PointTerms with NearPairs' candidates
    kept across calls against one that searches every pair every call: the same terms and point gradients to
    the bit; the pairs it measures are maybe_near's, less some at least their clearance apart."""
    import numpy as np

    from nlo_lab.objective.numpy_backend import maybe_near
    from nlo_lab.robot import load_robot
    from nlo_lab.robot.collision import segment_closest_points

    yumi = load_robot("yumi")  # float32, as the pipeline runs it
    q0 = random_angles(yumi, 24, seed=31).to(yumi.lower_limits.dtype)
    t = targets_from_demonstration(demonstration_from_robot(yumi, random_angles(yumi, 24, seed=32)), dtype=q0.dtype)
    kept, searched = (Objective(yumi, t, fused=True).numpy_terms for _ in range(2))
    searched = searched.with_near_slack(0.0)  # every frame searched every call
    g = torch.Generator().manual_seed(33)
    q, reused = q0.clone(), 0
    for step in range(12):
        q = q + 0.002 * torch.randn(q.shape, generator=g, dtype=q.dtype)  # about an Adam step of the optimisation
        if step % 4 == 3:
            q[::5] += 0.3  # some frames jump: searched again
        P = Objective(yumi, t).plan.map(q).numpy()
        reference = None if kept.near_pairs.reference is None else kept.near_pairs.reference.copy()
        a, b = kept.forward(P), searched.forward(P)
        assert np.array_equal(a[0], b[0])
        G = np.linspace(0.5, 1.5, a[0].size, dtype=P.dtype).reshape(a[0].shape)
        assert np.array_equal(kept.backward(G, a[1]), searched.backward(G, b[1]))
        if reference is not None:
            reused += int((kept.near_pairs.reference == reference).all(axis=(1, 2)).sum())  # frames not searched again
        near, full = kept.near_pairs(P), maybe_near(P[:, kept.capsule_rows].reshape(24, -1, 2, 3), kept.pair_capsules, kept.clearance)
        assert set(near.tolist()) <= set(full.tolist())
        left = np.setdiff1d(full, near)
        frame, pair = np.divmod(left, len(kept.pair_capsules))
        ends = P[frame[:, None], kept.pair_points.reshape(-1, 4)[pair]]
        dist = segment_closest_points(ends.transpose(1, 2, 0).astype(np.float64))[3]
        assert bool((dist >= kept.clearance[pair]).all())
        assert float(a[0][:, 4].max()) > 0  # the collision term acts
    assert reused > 100  # most frames kept their candidates between calls


def test_the_points_the_numpy_terms_reach_hold_every_non_zero_gradient(random_angles, demonstration_from_robot):
    """PointTerms.reached: the backward's point gradient is 0 outside those points (the FK gradient sums over them
    alone), and they are fewer than all (some capsule pairs far apart)."""
    import numpy as np

    from nlo_lab.robot import load_robot

    yumi = load_robot("yumi")
    q = random_angles(yumi, 16, seed=41).to(yumi.lower_limits.dtype)
    t = targets_from_demonstration(demonstration_from_robot(yumi, random_angles(yumi, 16, seed=42)), dtype=q.dtype)
    fused = Objective(yumi, t, fused=True)
    P = fused.plan.map(q).numpy()
    terms, saved = fused.numpy_terms.forward(P)
    G = np.linspace(0.5, 1.5, terms.size, dtype=P.dtype).reshape(terms.shape)
    g = fused.numpy_terms.backward(G, saved)
    reached = fused.numpy_terms.reached(saved)
    outside = np.setdiff1d(np.arange(P.shape[1]), reached)
    assert float(terms[:, 4].max()) > 0 and len(outside) > 0
    assert not g[:, outside].any()
    assert np.abs(g[:, reached]).max() > 0

"""The objective: weights, each term, masks."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.objective import (
    CONTACT_SCALE,
    TERMS,
    LossWeights,
    Targets,
    collision_loss,
    collision_scale,
    latent_loss,
    objective,
    point_plan,
    targets_from_demonstration,
)
from nlo_lab.robot import load_robot

ROBOTS = ("yumi", "nao", "pepper")


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request):
    return load_robot(request.param).to(dtype=torch.float64)


@pytest.fixture(scope="session")
def exact_targets(demonstration_from_robot):
    def build(robot, q) -> Targets:
        """Targets the robot meets exactly at q, with the robot's own arm lengths."""
        t = targets_from_demonstration(demonstration_from_robot(robot, q), dtype=torch.float64)
        c = point_plan(robot, torch.float64, q.device)
        T = len(t)
        return dataclasses.replace(t, arm_length=c.arm_length.expand(T, 2).clone(), fore_length=c.fore_length.expand(T, 2).clone(),
                                   hand_length=c.hand_length.expand(T, 2).clone())

    return build


# ------------------------------------------------------------------ weights
def test_loss_weights_defaults_are_the_papers():
    w = LossWeights()
    assert (w.ee, w.ori, w.elbow, w.finger, w.collision, w.latent) == (1000, 100, 100, 100, 1000, 1)


def test_the_papers_objective_keeps_its_terms_and_drops_ours():
    paper, ours = LossWeights.paper(), LossWeights()
    assert (paper.smooth, paper.tip, paper.thumb, paper.pinch) == (0, 0, 0, 0)  # not in the paper
    assert ours.smooth > 0 and ours.tip > 0 and ours.thumb > 0 and ours.pinch > 0
    for name in ("ee", "ori", "elbow", "finger", "collision", "latent"):  # the paper's terms, the paper's weights
        assert getattr(paper, name) == getattr(ours, name)


@pytest.mark.parametrize("bad", [-1.0, math.nan, math.inf, "abc", None])
def test_loss_weights_reject_bad_values(bad):
    with pytest.raises(SettingsError, match="ori"):
        LossWeights(ori=bad)


def test_loss_weights_from_string():
    w = LossWeights.from_string("ee=10, collision=0,latent=0.5")
    assert (w.ee, w.collision, w.latent, w.ori) == (10.0, 0.0, 0.5, 100.0)
    assert LossWeights.from_string("") == LossWeights()


@pytest.mark.parametrize(
    "text, names",
    [("eee=1", "eee"), ("ee=abc", "ee=.abc"), ("ee", "ee"), ("ori=-3", "ori"), ("ee=1,ee=2", "ee"), ("finger=nan", "finger")],
)
def test_loss_weights_from_string_names_the_problem(text, names):
    with pytest.raises(SettingsError, match=names):
        LossWeights.from_string(text)


# ------------------------------------------------------------------ terms
def test_each_term_is_zero_when_the_robot_matches_its_targets(robot, random_feasible_pose, exact_targets):
    q = random_feasible_pose(robot, 6, seed=1)
    total, terms = objective(robot, q, exact_targets(robot, q))
    assert set(terms) == set(TERMS)
    for name, value in terms.items():
        assert value.shape == (6,)
        assert float(value.abs().max()) < 1e-10, name
    assert float(total.abs().max()) < 1e-7


def test_terms_grow_when_the_robot_moves_away(robot, random_feasible_pose, exact_targets):
    q = random_feasible_pose(robot, 4, seed=2)
    t = exact_targets(robot, q)
    moved = (q + 0.3).clamp(robot.lower_limits, robot.upper_limits)
    _, terms = objective(robot, moved, t)
    assert (terms["ee"] > 1e-4).all() and (terms["ori"] > 1e-4).all() and (terms["elbow"] > 0).any()
    if robot.has_fingers:
        assert (terms["finger"] > 1e-4).all()
    else:
        assert float(terms["finger"].abs().max()) == 0.0


def test_masked_targets_contribute_nothing_and_are_not_zero_targets(robot, demonstration_from_robot, random_feasible_pose):
    q = random_feasible_pose(robot, 3, seed=3)
    demo = demonstration_from_robot(robot, q)
    moved = (q + 0.4).clamp(robot.lower_limits, robot.upper_limits).requires_grad_(True)
    demo.wrist_mask[1, 0] = False  # left wrist orientation of frame 1
    demo.arm_mask[2, 1, 1] = False  # right elbow of frame 2
    demo.finger_mask[0, 1, 2] = False  # right middle finger of frame 0
    demo.validate()
    t = targets_from_demonstration(demo, dtype=torch.float64)
    total, terms = objective(robot, moved, t)
    total.sum().backward()
    assert torch.isfinite(moved.grad).all()
    # Changing the masked values changes nothing.
    t2 = dataclasses.replace(
        t,
        wrist_rotation=t.wrist_rotation.clone().index_put_((torch.tensor([1]), torch.tensor([0])), torch.full((3, 3), 7.0, dtype=torch.float64)),
        elbow=t.elbow.clone().index_put_((torch.tensor([2]), torch.tensor([1])), torch.full((3,), -5.0, dtype=torch.float64)),
        finger_tip=t.finger_tip.clone().index_put_((torch.tensor([0]), torch.tensor([1]), torch.tensor([2])), torch.full((3,), 9.0, dtype=torch.float64)),
    )
    total2, terms2 = objective(robot, moved, t2)
    torch.testing.assert_close(total2, total)
    # A masked target is not a zero target: unmasking the placeholder changes the loss.
    t3 = dataclasses.replace(t, wrist_mask=torch.ones_like(t.wrist_mask), arm_mask=torch.ones_like(t.arm_mask))
    _, terms3 = objective(robot, moved.detach(), t3)
    terms = {k: v.detach() for k, v in terms.items()}
    assert float(terms3["ori"][1]) != pytest.approx(float(terms["ori"][1]))
    assert float(terms3["elbow"][2]) != pytest.approx(float(terms["elbow"][2]))


def test_fully_masked_frame_has_zero_tracking_terms(robot, demonstration_from_robot, random_feasible_pose):
    q = random_feasible_pose(robot, 2, seed=4)
    demo = demonstration_from_robot(robot, q)
    demo.arm_mask[0] = False
    demo.wrist_mask[0] = False
    demo.finger_mask[0] = False
    demo.validate()
    _, terms = objective(robot, (q + 0.5).clamp(robot.lower_limits, robot.upper_limits), targets_from_demonstration(demo, dtype=torch.float64))
    for name in ("ee", "ori", "elbow", "finger"):
        assert float(terms[name][0]) == 0.0
    assert float(terms["ee"][1]) > 0


def test_objective_gradient_matches_finite_differences(demonstration_from_robot, random_feasible_pose):
    robot = load_robot("nao").to(dtype=torch.float64)
    q = random_feasible_pose(robot, 2, seed=5)
    t = targets_from_demonstration(demonstration_from_robot(robot, q), dtype=torch.float64)
    start = (q + 0.2).clamp(robot.lower_limits, robot.upper_limits).requires_grad_(True)
    torch.autograd.gradcheck(lambda x: objective(robot, x, t, LossWeights(collision=0))[0], (start,), eps=1e-6, atol=1e-4)


# ------------------------------------------------------------------ collision and latent
def test_collision_loss_is_zero_above_the_margin_and_grows_inside():
    margins = torch.tensor([0.1, 0.15], dtype=torch.float64)
    d = torch.tensor([[0.2, 0.16], [0.05, 0.16], [0.0, 0.16], [-0.02, 0.1]], dtype=torch.float64)
    hinge = collision_loss(d, margins)
    assert hinge[0] == 0.0 and 0 < hinge[1] < hinge[2] < hinge[3]
    torch.testing.assert_close(hinge[2], torch.tensor(1.0, dtype=torch.float64))
    paper = collision_loss(d, margins, form="paper")
    assert paper[0] == 0.0
    torch.testing.assert_close(paper[1], torch.exp(torch.tensor(-0.05**2, dtype=torch.float64)))
    with pytest.raises(SettingsError, match="collision form"):
        collision_loss(d, margins, form="soft")


def test_a_margin_0_pair_costs_only_penetration_in_contact_scale_units():
    # a pair allowed to touch (a spec may give margin 0): only penetration costs
    margins = torch.tensor([0.0, 0.005], dtype=torch.float64)
    d = torch.tensor([[0.001, 0.001], [0.0, 0.0], [-CONTACT_SCALE, -0.001]], dtype=torch.float64, requires_grad=True)
    hinge = collision_loss(d, margins)
    assert float(hinge[0].detach()) == pytest.approx(0.8**2) and float(hinge[1].detach()) == 1.0  # only the 5 mm pair counts
    assert float(hinge[2].detach()) == pytest.approx(1.0 + 1.2**2)  # the margin-0 pair: 1 per CONTACT_SCALE of depth
    hinge.sum().backward()
    assert d.grad[0, 0] == 0 and d.grad[1, 0] == 0 and d.grad[2, 0] < 0
    torch.testing.assert_close(collision_scale(margins), torch.tensor([CONTACT_SCALE, 0.005], dtype=torch.float64))


def test_yumi_lets_the_thumb_touch_the_fingers_of_its_own_hand_only():
    robot = load_robot("yumi")
    margins = dict(zip(robot.spec.collision_pairs, robot.spec.pair_margins, strict=True))
    link = {c.name: c.link for c in robot.spec.capsules}
    thin = {(link[a], link[b]) for (a, b), m in margins.items() if m < 0.005}
    assert thin and all("thumb" in a + b and a.split("_")[2] == b.split("_")[2] for a, b in thin), thin
    assert {m for m in margins.values() if m < 0.005} == {0.001}
    assert ("yumi_hand_l_index_intermediate", "yumi_hand_l_thumb_distal") in thin
    # no pair between two of the four fingers of one hand (they flex in parallel planes)
    assert not any("thumb" not in link[a] + link[b] and "_hand_" in link[a] and "_hand_" in link[b]
                   and "base" not in link[a] + link[b] for a, b in margins)


def test_collision_hinge_pushes_capsules_apart_even_when_penetrating():
    d = torch.tensor([[-0.03, 0.02]], dtype=torch.float64, requires_grad=True)
    collision_loss(d, torch.tensor([0.1, 0.1], dtype=torch.float64)).sum().backward()
    assert (d.grad < 0).all()  # descent increases the distance


def test_latent_loss():
    z = torch.tensor([[[1.0, 2.0]], [[0.0, -3.0]]])
    torch.testing.assert_close(latent_loss(z), torch.tensor([5.0, 9.0]))
    torch.testing.assert_close(latent_loss(z, sigma=2.0), torch.tensor([1.25, 2.25]))


def test_targets_from_demonstration_has_no_nan_and_keeps_masks(robot, demonstration_from_robot, random_feasible_pose):
    q = random_feasible_pose(robot, 3, seed=6)
    demo = demonstration_from_robot(robot, q)
    demo.arm_mask[1, 0, 2] = False
    demo.validate()
    assert np.isnan(demo.arm_positions[1, 0, 2]).all()
    t = targets_from_demonstration(demo, dtype=torch.float32)
    for f in dataclasses.fields(t):
        v = getattr(t, f.name)
        if isinstance(v, torch.Tensor) and v.is_floating_point():
            assert torch.isfinite(v).all(), f.name
            assert v.dtype == torch.float32
    assert not bool(t.arm_mask[1, 0, 2]) and bool(t.arm_mask[0, 0, 2])
    assert not hasattr(t, "node_features")  # the encoder's input travels separately (nlo_lab.model.EncoderInput)
    assert len(Targets.cat([t, t.index(slice(0, 2))])) == 5


def test_fast_objective_equals_the_term_functions(robot):
    """Objective (the optimiser's path) = the term-by-term path on full FK poses, values and gradients."""
    from nlo_lab.corpus import sign_corpus

    demo = sign_corpus("test")[0]
    t = targets_from_demonstration(demo, dtype=torch.float64).index(slice(0, 40))
    g = torch.Generator().manual_seed(7)
    q = robot.lower_limits + torch.rand(len(t), robot.n_joints, generator=g, dtype=torch.float64) * (robot.upper_limits - robot.lower_limits)
    q = q.requires_grad_(True)
    for form in ("hinge", "paper"):
        fast, fast_terms = objective(robot, q, t, collision_form=form)
        ref, ref_terms = objective(robot, q, t, poses=robot.forward_kinematics(q), collision_form=form)
        for name in TERMS:
            torch.testing.assert_close(fast_terms[name], ref_terms[name], atol=1e-12, rtol=1e-12)
        torch.testing.assert_close(fast, ref, atol=1e-10, rtol=1e-12)
        (g_fast,) = torch.autograd.grad(fast.sum(), q)
        (g_ref,) = torch.autograd.grad(ref.sum(), q)
        torch.testing.assert_close(g_fast, g_ref, atol=1e-9, rtol=1e-9)
    assert float(ref_terms["collision"].detach().max()) > 0, "random poses should include a close capsule pair"


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_numpy_terms_equal_the_term_functions(robot, dtype):
    """Objective's numpy path (hand-written backward) = its torch-ops path, values and gradients."""
    from nlo_lab.corpus import sign_corpus
    from nlo_lab.objective import Objective

    r = robot.to(dtype=dtype)
    t = targets_from_demonstration(sign_corpus("test")[1], dtype=dtype)  # every frame: some random pose brings capsules close
    g = torch.Generator().manual_seed(3)
    q = (r.lower_limits + torch.rand(len(t), r.n_joints, generator=g, dtype=dtype) * (r.upper_limits - r.lower_limits)).requires_grad_(True)
    tol = {"atol": 1e-9, "rtol": 1e-9} if dtype == torch.float64 else {"atol": 2e-4, "rtol": 2e-5}
    for form in ("hinge", "paper"):
        fused, fused_terms = Objective(r, t, collision_form=form, fused=True)(q)
        ref, ref_terms = Objective(r, t, collision_form=form, fused=False)(q)
        torch.testing.assert_close(fused_terms, ref_terms, **tol)
        (g_fused,) = torch.autograd.grad(fused.sum(), q)
        (g_ref,) = torch.autograd.grad(ref.sum(), q)
        torch.testing.assert_close(g_fused, g_ref, atol=tol["atol"] * float(g_ref.abs().max()), rtol=tol["rtol"])
    assert float(ref_terms[:, 4].detach().max()) > 0, "random poses should include a close capsule pair"


def test_numpy_objective_passes_gradcheck(demonstration_from_robot, random_feasible_pose):
    from nlo_lab.objective import Objective

    robot = load_robot("yumi").to(dtype=torch.float64)
    q = random_feasible_pose(robot, 2, seed=11)
    t = targets_from_demonstration(demonstration_from_robot(robot, q), dtype=torch.float64)
    start = (q + 0.3).clamp(robot.lower_limits, robot.upper_limits).requires_grad_(True)
    obj = Objective(robot, t, fused=True)
    torch.autograd.gradcheck(lambda x: obj(x)[0], (start,), eps=1e-6, atol=1e-4)


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_culling_far_capsule_pairs_changes_nothing(robot, dtype):
    """Objective(cull=True) (exact distances only where a pair may be within its margin)
    = every pair measured, values and gradients; and the bound it uses for the other
    pairs never exceeds the true surface distance."""
    from nlo_lab.corpus import sign_corpus
    from nlo_lab.objective import Objective, near_pair_distances
    from nlo_lab.robot.collision import segment_distance_ends

    r = robot.to(dtype=dtype)
    t = targets_from_demonstration(sign_corpus("test")[1], dtype=dtype)
    g = torch.Generator().manual_seed(5)
    q = (r.lower_limits + torch.rand(len(t), r.n_joints, generator=g, dtype=dtype) * (r.upper_limits - r.lower_limits)).requires_grad_(True)
    for form in ("hinge", "paper"):
        out = {}
        for cull in (True, False):
            total, terms = Objective(r, t, collision_form=form, fused=False, cull=cull)(q)
            (grad,) = torch.autograd.grad(total.sum(), q)
            out[cull] = (terms.detach(), grad)
        torch.testing.assert_close(out[True][0], out[False][0], atol=1e-12, rtol=1e-12 if dtype == torch.float64 else 1e-6)  # summation order only
        torch.testing.assert_close(out[True][1], out[False][1], atol=1e-12 if dtype == torch.float64 else 1e-5, rtol=1e-6)
    c = point_plan(r, dtype, q.device)
    pts = c.map(q.detach())
    ends = pts.index_select(1, c.pair_points).view(len(t), -1, 4, 3)
    exact = segment_distance_ends(ends) - c.pair_radii
    culled = near_pair_distances(ends, c.pair_radii, c.margins)
    far = (culled - exact).abs() > 1e-9  # measured pairs agree up to rounding (numpy vs torch path)
    assert 0 < int(far.sum()) < far.numel(), "the case should hold both culled and measured pairs"
    assert bool((culled[far] <= exact[far] + 1e-6).all()), "the bound must not exceed the distance"
    assert bool((culled[far] >= c.margins.expand_as(culled)[far]).all()), "a culled pair must clear its margin"
    assert float(out[False][0][:, 4].max()) > 0, "random poses should include a close capsule pair"

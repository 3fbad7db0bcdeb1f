"""The hand terms (issue 27): wrist -> fingertip vectors, thumb -> fingertip directions, pinch,
wrist -> fingertip and finger base -> tip directions in the wrist frame.

Each term: its gradient against finite differences (float64), exactly 0 at a perfect match and
not 0 away from it, masks; a human pinch closes the robot's thumb and finger down to what the
hand can do; the numpy fast path gives the same values and gradients with the hand terms on.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from nlo_lab.objective import (
    CHORD_EPS,
    HAND_TERMS,
    PINCH_OFF,
    PINCH_ON,
    TERMS,
    LossWeights,
    Objective,
    finger_direction_loss,
    fingertip_direction_loss,
    fingertip_loss,
    objective,
    pinch_activation,
    pinch_loss,
    point_plan,
    targets_from_demonstration,
    thumb_gap_loss,
    thumb_loss,
)
from nlo_lab.robot import load_robot

ONLY = {name: LossWeights(**{n: (1.0 if n == name else 0.0) for n in (*TERMS, "latent", "smooth")}) for name in HAND_TERMS}


@pytest.fixture(scope="module")
def yumi():
    return load_robot("yumi").to(dtype=torch.float64)


@pytest.fixture(scope="session")
def exact_targets(demonstration_from_robot):
    def build(robot, q):
        """Targets the robot meets exactly at ``q``, with the robot's own arm and hand lengths."""
        t = targets_from_demonstration(demonstration_from_robot(robot, q), dtype=torch.float64)
        c = point_plan(robot, torch.float64)
        T = len(t)
        return dataclasses.replace(t, arm_length=c.arm_length.expand(T, 2).clone(), fore_length=c.fore_length.expand(T, 2).clone(),
                                   hand_length=c.hand_length.expand(T, 2).clone())

    return build


def hand_joints(robot) -> torch.Tensor:
    """Indices of the actuated hand joints."""
    return torch.tensor([i for i, n in enumerate(robot.joint_names) if "_hand_" in n])


def tip_distance(robot, q, side: int = 0, finger: int = 1) -> torch.Tensor:
    """Thumb tip -> fingertip distance [m] of the robot at ``q (B, n)``."""
    plan = point_plan(robot, q.dtype)
    tips = plan(q).finger_tip
    k = {(int(s), int(f)): i for i, (s, f) in enumerate(zip(plan.finger_side, plan.finger_index, strict=True))}
    return (tips[:, k[side, finger]] - tips[:, k[side, 0]]).norm(dim=-1)


# ------------------------------------------------------------------ the terms on their own
def random_hand_inputs(B=3, seed=0):
    """Random robot and human quantities for one hand pair of sides with 5 fingers each (float64)."""
    g = torch.Generator().manual_seed(seed)
    r = lambda *s: torch.randn(*s, generator=g, dtype=torch.float64)  # noqa: E731
    rot = torch.linalg.qr(r(B, 2, 3, 3)).Q
    t_rot = torch.linalg.qr(r(B, 2, 3, 3)).Q
    side = torch.tensor([0] * 5 + [1] * 5)
    pairs = torch.tensor([[0, 1], [0, 2], [0, 3], [0, 4], [5, 6], [5, 7], [5, 8], [5, 9]])
    return dict(wrist=r(B, 2, 3), rot=rot, tip=0.1 * r(B, 10, 3), length=torch.tensor([0.14, 0.15], dtype=torch.float64),
                t_wrist=r(B, 2, 3), t_rot=t_rot, t_tip=0.05 * r(B, 10, 3), t_length=torch.full((B, 2), 0.09, dtype=torch.float64),
                side=side, pairs=pairs, pair_side=side[pairs[:, 1]])


def test_each_hand_term_gradient_matches_finite_differences_on_its_own():
    x = random_hand_inputs()
    mask10, mask8 = torch.ones(3, 10, dtype=torch.bool), torch.ones(3, 8, dtype=torch.bool)
    mask10[1, 4] = mask8[2, 5] = False
    # tips close to the thumb so that the pinch is active for some pairs and inactive for others
    x["t_tip"][:, 1] = x["t_tip"][:, 0] + 0.01
    floor = torch.tensor([0.03, 0.1, 0.2, 0.4] * 2, dtype=torch.float64)
    checks = {
        "tip": lambda w, R, p: fingertip_loss(w, R, p, x["length"], x["t_wrist"], x["t_rot"], x["t_tip"], x["t_length"], x["side"], mask10),
        "thumb": lambda w, R, p: thumb_loss(R, p, x["length"], x["t_rot"], x["t_tip"], x["t_length"], x["pairs"], x["pair_side"], mask8),
        "pinch": lambda w, R, p: pinch_loss(p, x["length"], x["t_tip"], x["t_length"], x["pairs"], x["pair_side"], floor, mask8),
        "tip_dir": lambda w, R, p: fingertip_direction_loss(w, R, p, x["length"], x["t_wrist"], x["t_rot"], x["t_tip"], x["t_length"],
                                                            x["side"], mask10),
        # the wrist stands in for the finger bases (one base per side, broadcast to its five fingers)
        "finger_dir": lambda w, R, p: finger_direction_loss(R, w[:, x["side"]], p, x["length"], x["t_rot"], x["t_wrist"][:, x["side"]], x["t_tip"],
                                                            x["t_length"], x["side"], mask10),
    }
    checks["thumb_gap"] = lambda w, R, p: thumb_gap_loss(p, x["length"], x["t_tip"], x["t_length"], x["pairs"], x["pair_side"], floor, mask8)
    assert set(checks) == set(HAND_TERMS)
    inputs = (x["wrist"].requires_grad_(), x["rot"].requires_grad_(), x["tip"].requires_grad_())
    for name, fn in checks.items():
        assert float(fn(*inputs).detach().abs().max()) > 0, name
        assert torch.autograd.gradcheck(fn, inputs, eps=1e-6, atol=1e-6), name


@pytest.mark.parametrize("name", HAND_TERMS)
def test_hand_term_gradient_through_yumi_matches_finite_differences(yumi, name, exact_targets, random_feasible_pose):
    q = random_feasible_pose(yumi, 2, seed=11)
    t = exact_targets(yumi, q)
    # the human pinches: thumb tips 1 cm from the index tips (active pinch on the index)
    tip = t.finger_tip.clone()
    tip[:, :, 0] = tip[:, :, 1] + 0.01
    t = dataclasses.replace(t, finger_tip=tip)
    start = q.clone()
    start[:, hand_joints(yumi)] = 0.3
    start.requires_grad_(True)
    loss = Objective(yumi, t, ONLY[name], fused=False)
    assert float(loss(start)[0].detach().min()) > 1e-6
    assert torch.autograd.gradcheck(lambda x: loss(x)[0], (start,), eps=1e-6, atol=1e-5)


def test_hand_terms_are_zero_at_a_perfect_match_and_not_away_from_it(yumi, exact_targets, random_feasible_pose):
    q = random_feasible_pose(yumi, 5, seed=12)
    q[0, hand_joints(yumi)] = yumi.upper_limits[hand_joints(yumi)]  # a closed fist: a pinch the robot makes exactly
    t = exact_targets(yumi, q)
    _, terms = objective(yumi, q, t)
    for name in HAND_TERMS:
        assert float(terms[name].abs().max()) < 1e-12, name
    hj = hand_joints(yumi)
    lo, hi = yumi.lower_limits[hj], yumi.upper_limits[hj]
    moved = q.clone()
    moved[:, hj] = torch.where(q[:, hj] > (lo + hi) / 2, lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo))  # every hand joint elsewhere
    _, terms = objective(yumi, moved, t)
    for name in ("tip", "thumb", "tip_dir", "finger_dir", "thumb_gap"):
        assert (terms[name] > 1e-4).all(), name
    # the arm alone does not change the handshape terms (they live in the wrist frame)
    arm = q.clone()
    arm[:, :14] += 0.2
    _, terms = objective(yumi, arm.clamp(yumi.lower_limits, yumi.upper_limits), t)
    for name in ("tip", "thumb", "tip_dir", "finger_dir"):
        assert float(terms[name].abs().max()) < 1e-12, name


def test_hand_terms_ignore_masked_fingers(yumi, demonstration_from_robot, random_feasible_pose):
    q = random_feasible_pose(yumi, 2, seed=13)
    demo = demonstration_from_robot(yumi, q)
    demo.finger_mask[0, 1, 1] = False  # right index, frame 0
    t = targets_from_demonstration(demo, dtype=torch.float64)
    moved = q.clone()
    moved[:, hand_joints(yumi)] = 0.5
    _, a = objective(yumi, moved, t)
    tip = t.finger_tip.clone()
    tip[0, 1, 1] = 7.0
    _, b = objective(yumi, moved, dataclasses.replace(t, finger_tip=tip))
    for name in HAND_TERMS:
        torch.testing.assert_close(a[name], b[name])
    _, c = objective(yumi, moved, dataclasses.replace(t, finger_tip=tip, finger_mask=torch.ones_like(t.finger_mask)))
    assert float(c["tip"][0]) != pytest.approx(float(a["tip"][0]))


def test_hand_terms_are_zero_on_robots_without_fingers(demonstration_from_robot, random_feasible_pose):
    nao = load_robot("nao").to(dtype=torch.float64)
    q = random_feasible_pose(nao, 2, seed=14)
    t = targets_from_demonstration(demonstration_from_robot(nao, q), dtype=torch.float64)
    _, terms = objective(nao, (q + 0.3).clamp(nao.lower_limits, nao.upper_limits), t)
    for name in HAND_TERMS:
        assert float(terms[name].abs().max()) == 0.0


def test_pinch_activation_is_one_when_touching_and_zero_when_apart():
    d = torch.tensor([0.0, PINCH_ON, (PINCH_ON + PINCH_OFF) / 2, PINCH_OFF, 2.0])
    torch.testing.assert_close(pinch_activation(d), torch.tensor([1.0, 1.0, 0.5, 0.0, 0.0]))


@pytest.mark.parametrize("finger", [1, 4])  # index: the hand can close it; pinky: only down to its floor
def test_a_human_pinch_closes_the_robots_thumb_and_finger(yumi, finger, exact_targets):
    """From an open hand, the pinch term alone draws the tips together, down to what the hand can do."""
    q = yumi.neutral_q[None].clone()  # hands open
    t = exact_targets(yumi, q)
    tip = t.finger_tip.clone()
    tip[:, 0, 0] = tip[:, 0, finger]  # the human's left thumb tip on the fingertip: a pinch
    t = dataclasses.replace(t, finger_tip=tip)
    plan = point_plan(yumi, torch.float64)
    loss = Objective(yumi, t, ONLY["pinch"], fused=False)
    pair = int(((plan.thumb_pairs[:, 0] == 0) & (plan.finger_index[plan.thumb_pairs[:, 1]] == finger)).nonzero())
    floor = float(plan.pinch_floor()[pair] * plan.hand_length[0])  # [m]
    before = float(tip_distance(yumi, q, 0, finger))
    assert float(loss(q)[0]) > 0 and before > floor + 0.03
    x = q.clone().requires_grad_(True)
    opt = torch.optim.Adam([x], lr=0.02)
    for _ in range(300):
        opt.zero_grad()
        loss(x)[0].sum().backward()
        opt.step()
        with torch.no_grad():
            x.copy_(torch.maximum(torch.minimum(x, yumi.upper_limits), yumi.lower_limits))
    after = float(tip_distance(yumi, x.detach(), 0, finger))
    assert after < floor + 0.004, (before, after, floor)  # closed as far as the hand can
    assert after > floor - 0.01  # the floor is what the hand can do (up to its sampling)
    assert float(tip_distance(yumi, x.detach(), 1, finger)) == pytest.approx(float(tip_distance(yumi, q, 1, finger)))  # other hand untouched


ALL_HAND = dict(tip=3.0, thumb=5.0, pinch=7.0, tip_dir=11.0, finger_dir=13.0, thumb_gap=17.0)
WEIGHT_SETS = {
    "all": ALL_HAND,
    "latent stage": {**ALL_HAND, "tip_dir": 0.0, "finger_dir": 0.0, "thumb_gap": 0.0},  # LossWeights.latent_stage()
    "pinch alone": {**dict.fromkeys(ALL_HAND, 0.0), "pinch": 7.0},
    "thumb gap alone": {**dict.fromkeys(ALL_HAND, 0.0), "thumb_gap": 17.0},
    "directions alone": {**dict.fromkeys(ALL_HAND, 0.0), "tip_dir": 11.0, "finger_dir": 13.0},
    "thumb without pinch or gap": {**dict.fromkeys(ALL_HAND, 0.0), "thumb": 5.0, "tip": 3.0},
    "no hand term": dict.fromkeys(ALL_HAND, 0.0),
}


@pytest.mark.parametrize("weights", list(WEIGHT_SETS), ids=list(WEIGHT_SETS))
def test_numpy_fast_path_gives_the_same_values_and_gradients_whichever_hand_weights_are_zero(yumi, exact_targets, random_feasible_pose, weights):
    """The numpy backward leaves out the kinds whose weight is 0 (the latent optimisation's direction terms):
    the same total, terms (every one, the zero-weight ones too) and gradient as the term functions (SMALL_BATCH
    frames: fewer visit every item)."""
    from nlo_lab.objective.numpy_backend import SMALL_BATCH

    q = random_feasible_pose(yumi, SMALL_BATCH, seed=16)
    t = exact_targets(yumi, q)
    tip = t.finger_tip.clone()
    tip[:, :, 0] = tip[:, :, 1] + 0.004  # pinch on the index
    t = dataclasses.replace(t, finger_tip=tip)
    start = (q - 0.07).clamp(yumi.lower_limits, yumi.upper_limits)
    out = []
    for fused in (True, False):
        x = start.clone().requires_grad_(True)
        total, terms = Objective(yumi, t, LossWeights(**WEIGHT_SETS[weights]), fused=fused, cull=fused, analytic_fk=fused)(x)
        total.sum().backward()
        out.append((total.detach(), terms.detach(), x.grad))
    for a, b in zip(*out, strict=True):
        torch.testing.assert_close(a, b, rtol=1e-9, atol=1e-9)
    hand = out[0][0].new_tensor([float(out[0][1][:, TERMS.index(n)].min()) for n in HAND_TERMS])
    assert bool((hand > 0).all()), hand  # every hand term has a value, its weight 0 or not


def test_the_numpy_backward_visits_only_the_kinds_with_a_gradient(yumi, exact_targets, random_feasible_pose):
    q = random_feasible_pose(yumi, 2, seed=17)
    loss = Objective(yumi, exact_targets(yumi, q), LossWeights().latent_stage(), fused=True)
    hand = loss.numpy_terms.hand
    from nlo_lab.objective.numpy_backend import SMALL_BATCH

    g = loss.weights.numpy()[None, 5:].repeat(SMALL_BATCH, 0)  # the gradient of SMALL_BATCH frames' loss
    sel, kind, *_ = hand._active(g)
    K, J = len(loss.plan.finger_side), len(loss.plan.thumb_pairs)
    assert hand.items == 3 * K + J and len(sel) == K + J  # tip and the thumb vectors; not tip_dir, finger_dir
    assert hand._active(0 * g)[5].shape[1] == 0 and hand._active(g + 1)[0] is None  # nothing; everything
    assert hand._active(g[: SMALL_BATCH - 1])[0] is None  # fewer frames: every item (the gathers would cost more)


def test_the_numpy_hand_terms_refuse_items_not_grouped_by_kind(yumi, exact_targets, random_feasible_pose):
    """The planes' forward reads each kind as a slice, the tip vectors first: another order is refused, not mis-summed."""
    from nlo_lab.objective.numpy_backend import HandTerms

    q = random_feasible_pose(yumi, 2, seed=18)
    h = Objective(yumi, exact_targets(yumi, q), LossWeights(), fused=True).numpy_terms.hand
    kind = h.kind.argmax(1)
    rebuild = lambda order: HandTerms(h.plus[order], h.minus[order], h.axes, h.side[order], h.length[order, 0], kind[order],  # noqa: E731
                                      h.v_hat[:, order], h.mask[:, order, 0], h.pinch_goal, h.pinch_weight, h.gap_below)
    assert rebuild(np.arange(h.items)).items == h.items  # the built order is accepted
    swapped = np.arange(h.items)
    swapped[[0, h.vectors]] = swapped[[h.vectors, 0]]  # a tip direction first, a tip vector among the directions
    with pytest.raises(ValueError, match="grouped by kind"):
        rebuild(swapped)


def test_numpy_fast_path_gives_the_same_hand_terms_values_and_gradients(yumi, exact_targets, random_feasible_pose):
    q = random_feasible_pose(yumi, 4, seed=15)
    t = exact_targets(yumi, q)
    tip = t.finger_tip.clone()
    tip[:, :, 0] = tip[:, :, 2] + 0.005  # pinch on the middle finger
    t = dataclasses.replace(t, finger_tip=tip)
    start = (q + 0.1).clamp(yumi.lower_limits, yumi.upper_limits)
    out = []
    for fused in (True, False):
        x = start.clone().requires_grad_(True)
        total, terms = Objective(yumi, t, LossWeights(tip=3.0, thumb=5.0, pinch=7.0, tip_dir=11.0, finger_dir=13.0, thumb_gap=17.0), fused=fused)(x)
        total.sum().backward()
        out.append((total.detach(), terms.detach(), x.grad))
    for a, b in zip(*out, strict=True):
        torch.testing.assert_close(a, b, rtol=1e-9, atol=1e-9)
    for name in HAND_TERMS:
        assert float(out[0][1][:, TERMS.index(name)].min()) > 0, name


def test_direction_terms_are_the_measured_angles():
    """tip_dir is the chord 2 sin(θ/2) (rounded at 0 by CHORD_EPS) of the angle θ the hand benchmark scores, finger_dir
    2 - 2 cos θ, summed over the fingers: a finger turned by a known angle about a wrist axis costs exactly that,
    whatever the lengths."""
    B = 1
    rot = torch.eye(3, dtype=torch.float64).expand(B, 2, 3, 3)
    side = torch.tensor([0, 1])
    length = torch.tensor([0.1, 0.1], dtype=torch.float64)
    t_length = torch.full((B, 2), 0.08, dtype=torch.float64)
    wrist = torch.zeros(B, 2, 3, dtype=torch.float64)
    t_tip = torch.tensor([[[0.0, 0.0, 0.07], [0.0, 0.0, 0.05]]], dtype=torch.float64)
    angle = torch.tensor([0.3, 1.1], dtype=torch.float64)  # [rad] per finger, about the wrist's x axis
    tip = 0.13 * torch.stack([torch.zeros(2), -torch.sin(angle), torch.cos(angle)], -1)[None]  # another length
    mask = torch.ones(B, 2, dtype=torch.bool)
    got = fingertip_direction_loss(wrist, rot, tip, length, wrist, rot, t_tip, t_length, side, mask)
    torch.testing.assert_close(got, (torch.sqrt(2 - 2 * torch.cos(angle) + CHORD_EPS**2) - CHORD_EPS).sum()[None])
    torch.testing.assert_close(got, (2 * torch.sin(angle / 2)).sum()[None], rtol=0, atol=2 * CHORD_EPS)  # the chord: ≈ the angle
    base = torch.full((B, 2, 3), 0.02, dtype=torch.float64)
    got = finger_direction_loss(rot, base, base + tip, length, rot, base, base + t_tip, t_length, side, mask)
    torch.testing.assert_close(got, (2 - 2 * torch.cos(angle)).sum()[None])


def test_tip_direction_costs_each_finger_its_chord_not_its_square():
    """The chord is L1-like, as the measure (a mean angle): one finger 0.8 rad off costs what four fingers 0.2 rad
    off do (2 sin(θ/2) ≈ θ), where the squared form made the one finger cost 4x more; at a perfect match the
    gradient is 0, near it finite (CHORD_EPS)."""
    def cost(angles):
        angles = torch.as_tensor(angles, dtype=torch.float64)
        k = len(angles)
        rot = torch.eye(3, dtype=torch.float64).expand(1, 2, 3, 3)
        wrist, side = torch.zeros(1, 2, 3, dtype=torch.float64), torch.zeros(k, dtype=torch.long)
        length, t_length = torch.tensor([0.1, 0.1], dtype=torch.float64), torch.full((1, 2), 0.1, dtype=torch.float64)
        t_tip = torch.tensor([0.0, 0.0, 0.1], dtype=torch.float64).expand(1, k, 3)
        tip = (0.1 * torch.stack([torch.zeros(k, dtype=torch.float64), torch.sin(angles), torch.cos(angles)], -1))[None].requires_grad_(True)
        value = fingertip_direction_loss(wrist, rot, tip, length, wrist, rot, t_tip, t_length, side, torch.ones(1, k, dtype=torch.bool))
        value.sum().backward()
        return float(value.detach()), tip.grad

    one, _ = cost([0.8, 0.0, 0.0, 0.0])
    four, _ = cost([0.2, 0.2, 0.2, 0.2])
    assert one == pytest.approx(four, rel=0.03)
    zero, grad = cost([0.0])
    assert zero == 0.0 and float(grad.abs().max()) == 0.0
    _, grad = cost([1e-4])
    assert torch.isfinite(grad).all() and 0 < float(grad.abs().max()) < 1.0 / CHORD_EPS


def test_thumb_gap_follows_the_human_both_ways_but_not_below_what_the_hand_can_do():
    """d, d̂ in hand lengths: a robot thumb farther than the human's costs, and closer too; where the human's
    distance is below d_min only a robot distance above d_min costs (the hand cannot close further)."""
    pairs = torch.tensor([[0, 1]])
    length, t_length = torch.tensor([0.1, 0.1], dtype=torch.float64), torch.full((1, 2), 0.1, dtype=torch.float64)
    floor, mask = torch.tensor([0.2], dtype=torch.float64), torch.ones(1, 1, dtype=torch.bool)

    def cost(d, d_hat):
        tip = torch.tensor([[[0.0, 0.0, 0.0], [0.1 * d, 0.0, 0.0]]], dtype=torch.float64)
        t_tip = torch.tensor([[[0.0, 0.0, 0.0], [0.1 * d_hat, 0.0, 0.0]]], dtype=torch.float64)
        return float(thumb_gap_loss(tip, length, t_tip, t_length, pairs, torch.tensor([0]), floor, mask))

    assert cost(0.5, 0.5) < 1e-12
    assert cost(0.7, 0.5) == pytest.approx(0.04, rel=1e-5) and cost(0.3, 0.5) == pytest.approx(0.04, rel=1e-5)  # both ways (UNIT_EPS)
    assert cost(0.05, 0.05) == 0.0 and cost(0.15, 0.1) == 0.0  # below d_min: nothing pushes apart
    assert cost(0.5, 0.1) == pytest.approx(0.09, rel=1e-5)  # drawn down to d_min = 0.2, not to 0.1


def test_the_numpy_hand_terms_leave_out_a_hand_never_seen_and_give_the_same_values_and_gradients(yumi, exact_targets, random_feasible_pose):
    """A clip that never shows the left hand (HandTerms.observed): its items are left out of the numpy form,
    whose values and gradients stay those of the term functions."""
    q = random_feasible_pose(yumi, 4, seed=31)
    t = exact_targets(yumi, q)
    mask = t.finger_mask.clone()
    mask[:, 0] = False  # the left hand never seen
    mask[1, 1, 2] = False  # and one right finger unseen in one frame: it stays (seen in the others)
    t = dataclasses.replace(t, finger_mask=mask)
    start = (q + 0.1).clamp(yumi.lower_limits, yumi.upper_limits)
    weights = LossWeights(tip=3.0, thumb=5.0, pinch=7.0, tip_dir=11.0, finger_dir=13.0, thumb_gap=17.0)
    out = []
    for fused in (True, False):
        x = start.clone().requires_grad_(True)
        loss = Objective(yumi, t, weights, fused=fused)
        total, terms = loss(x)
        total.sum().backward()
        out.append((total.detach(), terms.detach(), x.grad))
        if fused:
            hand, plan = loss.numpy_terms.hand, loss.plan
            K = len(plan.finger_side)
            right = int((plan.finger_side == 1).sum()), int((plan.pair_side == 1).sum())
            assert 0 < right[0] < K and hand.items == 3 * right[0] + right[1]  # the right hand's items alone
            assert bool((hand.side == 1).all())
    for a, b in zip(*out, strict=True):
        torch.testing.assert_close(a, b, rtol=1e-9, atol=1e-9)
    assert float(out[0][1][:, TERMS.index("tip")].min()) > 0

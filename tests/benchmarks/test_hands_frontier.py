"""benchmarks/hands_frontier.py: the exhaustive search that says what YuMi's hands can do within the hand stage's
speed clamp. Its dynamic programming must find the cheapest path the reach allows, and its grid must see a hand
the way the scorer does (a human hand shaped like the robot's own costs 0 at the robot's cell)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from nlo_lab.robot import load_robot


@pytest.fixture(scope="module")
def frontier(checkout_script):
    return checkout_script("benchmarks/hands_frontier.py")


@pytest.fixture(scope="module")
def grid(frontier):
    return frontier.HandGrid(load_robot("yumi"), 1, finger_grid=9, thumb_grid=7)


def test_viterbi_finds_the_cheapest_path_within_reach(frontier):
    """Against every path of a small problem: 5 frames, 6 states, steps of at most 1 (the per-frame cheapest
    states jump from one end to the other, which the reach forbids)."""
    rng = np.random.default_rng(30)
    cost = rng.uniform(0.0, 1.0, (5, 6))
    cost[::2, 0] = cost[1::2, 5] = -5.0  # per frame the cheapest alternates between states 0 and 5
    reach = np.ones((4, 1), dtype=int)
    path = frontier.viterbi(cost, reach)[:, 0]
    assert (np.abs(np.diff(path)) <= 1).all()
    best = min((p for p in itertools.product(range(6), repeat=5) if all(abs(a - b) <= 1 for a, b in itertools.pairwise(p))),
               key=lambda p: cost[np.arange(5), p].sum())
    assert np.isclose(cost[np.arange(5), path].sum(), cost[np.arange(5), best].sum())
    free = frontier.viterbi(cost, np.full((4, 1), 5))[:, 0]  # with the whole range in reach: each frame's own best
    assert (free == cost.argmin(1)).all()


def test_viterbi_on_a_two_axis_grid_keeps_each_axis_within_its_reach(frontier):
    rng = np.random.default_rng(31)
    cost = rng.uniform(0.0, 1.0, (6, 5, 4))
    reach = np.array([[1, 0]] * 5)  # the second axis may not move
    path = frontier.viterbi(cost, reach)
    assert (np.abs(np.diff(path[:, 0])) <= 1).all() and (path[:, 1] == path[0, 1]).all()
    per_column = [cost[np.arange(6), frontier.viterbi(cost[:, :, k], reach[:, :1])[:, 0], k].sum() for k in range(4)]
    assert np.isclose(cost[np.arange(6), path[:, 0], path[:, 1]].sum(), min(per_column))


def test_a_human_hand_shaped_like_the_robot_s_costs_nothing_at_the_robot_s_cell(frontier, grid):
    """The 'human' is the robot's own hand at a grid cell free of collision, at the robot's size: every measure is 0
    there, so the per-frame search picks a cell of cost 0; a hand one cell off costs more."""
    cell, values = 3 * 7 + 2, np.array([4, 6, 2, 8])
    assert grid.thumb_ok[cell] and grid.finger_ok[cell, values, np.arange(4)].all()
    tip = np.concatenate([grid.thumb_tip[cell][None], grid.finger_tip[values, np.arange(4)]])
    base = np.concatenate([grid.thumb_base[cell][None], grid.finger_base[values, np.arange(4)]])
    cost = frontier.FrameCost(grid, tip, base, grid.length, (1.0, 1.0, 1.0, 1.0))
    found, fingers = frontier.per_frame(cost)
    total = cost.thumb[found] + cost.finger(np.array([found]))[0, fingers, np.arange(4)].sum()
    assert total < 1e-3  # degrees
    assert cost.thumb[cell] + cost.finger(np.array([cell]))[0, values, np.arange(4)].sum() < 1e-3
    assert (fingers == values).all()
    off = cost.finger(np.array([cell]))[0, values + np.array([1, 1, 1, -1]), np.arange(4)]
    assert (off > 0.1).all()


def test_the_clamped_search_steps_within_the_caps(frontier, grid):
    """Targets that jump from an open hand (frames 0-2) to a closed one (3-5); caps of about one grid step: the path
    moves at most that far per frame, where each frame's own best jumps, and it does move towards the fist."""
    a, b = (3 * 7 + 2, np.array([0, 0, 0, 0])), (3 * 7 + 2, np.array([8, 8, 8, 8]))
    costs = []
    for t in range(6):
        cell, values = a if t < 3 else b
        tip = np.concatenate([grid.thumb_tip[cell][None], grid.finger_tip[values, np.arange(4)]])
        base = np.concatenate([grid.thumb_base[cell][None], grid.finger_base[values, np.arange(4)]])
        costs.append(frontier.FrameCost(grid, tip, base, grid.length, (1.0, 0.2, 0.5, 0.2)))
    steps = np.array([v[1] - v[0] for v in grid.values])
    caps = np.tile(1.5 * steps, (5, 1))
    start = np.tile([v[0] for v in grid.values], (6, 1))
    index = frontier.within_clamp(grid, costs, start, caps, sweeps=2)
    moved = np.abs(np.diff(np.stack([grid.values[k][index[:, k]] for k in range(6)], 1), axis=0))
    assert (moved <= caps + 1e-12).all()
    assert (np.abs(np.diff(index[:, 2:], axis=0)) <= 1).all() and (index[-1, 2:] > 0).all()

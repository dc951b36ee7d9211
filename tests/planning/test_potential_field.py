"""Potential fields: hand-worked potentials, plain descent, local minima, seeded escapes, typed errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.planning import (
    GoalOccupied,
    InvalidInput,
    LocalMinimum,
    NoPathFound,
    PotentialFieldParams,
    StartOutsideMap,
    check_path,
    path_cost,
    plan_grid,
    plan_potential_field,
    potential_map,
)

SQRT2 = math.sqrt(2.0)

# A cup open towards the start: straight descent from S towards G ends inside it.
CUP_ROWS = [
    "....................",
    "....................",
    ".........#####......",
    ".............#......",
    ".............#......",
    "S............#.....G",
    ".............#......",
    ".............#......",
    ".........#####......",
    "....................",
    "....................",
]
CUP = np.array([[ch == "#" for ch in row] for row in CUP_ROWS])
CUP_START, CUP_GOAL = (5, 0), (5, 19)


def test_potential_hand_worked() -> None:
    occ = np.zeros((1, 6), dtype=bool)
    occ[0, 0] = True
    params = PotentialFieldParams(attractive_gain=2.0, repulsive_gain=3.0, influence_radius_cells=4.0)
    u = potential_map(occ, (0, 5), params)
    assert u[0, 0] == math.inf
    # Attractive 2·|col − 5|; repulsive 3·(1/ρ − 1/4) for the distance ρ = col to the obstacle, 0 beyond ρ = 4.
    expected = [2 * 4 + 3 * (1 - 0.25), 2 * 3 + 3 * (0.5 - 0.25), 2 * 2 + 3 * (1 / 3 - 0.25), 2 * 1 + 0.0, 0.0]
    np.testing.assert_allclose(u[0, 1:], expected)


def test_potential_without_obstacles_is_conic() -> None:
    u = potential_map(np.zeros((5, 5), dtype=bool), (2, 2))
    assert u[2, 2] == 0.0
    assert u[0, 0] == pytest.approx(2 * SQRT2)
    assert u[2, 4] == pytest.approx(2.0)


def test_open_grid_descends_straight_to_the_goal() -> None:
    occ = np.zeros((8, 8), dtype=bool)
    p = plan_potential_field(occ, (0, 0), (6, 6), rng=np.random.default_rng(0))
    assert p.cells.tolist() == [[i, i] for i in range(7)]
    assert p.cost == pytest.approx(6 * SQRT2)
    assert p.expanded == 6
    assert p.algorithm == "potential_field"


def test_plain_descent_gets_stuck_in_the_cup() -> None:
    with pytest.raises(LocalMinimum) as info:
        plan_potential_field(
            CUP, CUP_START, CUP_GOAL, rng=np.random.default_rng(0), params=PotentialFieldParams(max_escapes=0)
        )
    r, c = info.value.cell
    assert 3 <= r <= 7 and 9 <= c <= 12  # inside the cup, in front of its back wall
    assert isinstance(info.value, NoPathFound)


@pytest.mark.parametrize("escape", ["random_walk", "annealing"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_escapes_reach_the_goal_with_a_valid_simple_path(escape: str, seed: int) -> None:
    params = PotentialFieldParams(escape=escape)
    p = plan_potential_field(CUP, CUP_START, CUP_GOAL, rng=np.random.default_rng(seed), params=params)
    check_path(CUP, p.cells, start=CUP_START, goal=CUP_GOAL)
    assert len({tuple(c) for c in p.cells}) == len(p.cells)  # loops were cut
    assert p.cost == pytest.approx(path_cost(p.cells))
    optimum = plan_grid(CUP, CUP_START, CUP_GOAL).cost
    assert p.cost >= optimum - 1e-9


def test_same_seed_same_path() -> None:
    a = plan_potential_field(CUP, CUP_START, CUP_GOAL, rng=np.random.default_rng(42))
    b = plan_potential_field(CUP, CUP_START, CUP_GOAL, rng=np.random.default_rng(42))
    np.testing.assert_array_equal(a.cells, b.cells)
    assert a.expanded == b.expanded


def test_selected_through_plan_grid() -> None:
    p = plan_grid(CUP, CUP_START, CUP_GOAL, algorithm="potential_field", rng=np.random.default_rng(3))
    check_path(CUP, p.cells, start=CUP_START, goal=CUP_GOAL)
    params = PotentialFieldParams(escape="annealing")
    q = plan_grid(CUP, CUP_START, CUP_GOAL, algorithm="potential_field", rng=np.random.default_rng(3), potential=params)
    check_path(CUP, q.cells, start=CUP_START, goal=CUP_GOAL)
    p4 = plan_grid(CUP, CUP_START, CUP_GOAL, algorithm="potential_field", connectivity=4, rng=np.random.default_rng(3))
    check_path(CUP, p4.cells, connectivity=4)


def test_unreachable_goal_gives_up_with_local_minimum() -> None:
    occ = np.zeros((7, 7), dtype=bool)
    occ[:, 3] = True
    params = PotentialFieldParams(max_escapes=5, escape_steps=200)
    with pytest.raises(LocalMinimum):
        plan_potential_field(occ, (3, 0), (3, 6), rng=np.random.default_rng(0), params=params)


def test_step_budget_is_no_path_found() -> None:
    with pytest.raises(NoPathFound):
        plan_potential_field(
            CUP, CUP_START, CUP_GOAL, rng=np.random.default_rng(0), params=PotentialFieldParams(max_steps=5)
        )


@pytest.mark.parametrize(
    "kwargs",
    [
        {"attractive_gain": 0.0},
        {"attractive_gain": math.nan},
        {"repulsive_gain": -1.0},
        {"influence_radius_cells": 0.0},
        {"escape": "teleport"},
        {"escape_steps": 0},
        {"max_escapes": -1},
        {"initial_temperature": 0.0},
        {"cooling": 1.5},
        {"max_steps": 0},
    ],
)
def test_bad_parameters_are_invalid_input(kwargs: dict) -> None:
    with pytest.raises(InvalidInput):
        PotentialFieldParams(**kwargs)


def test_bad_endpoints_and_rng() -> None:
    occ = np.zeros((4, 4), dtype=bool)
    occ[3, 3] = True
    with pytest.raises(GoalOccupied):
        plan_potential_field(occ, (0, 0), (3, 3), rng=np.random.default_rng(0))
    with pytest.raises(StartOutsideMap):
        plan_potential_field(occ, (-1, 0), (1, 1), rng=np.random.default_rng(0))
    with pytest.raises(InvalidInput, match="rng"):
        plan_potential_field(occ, (0, 0), (1, 1), rng=0)  # type: ignore[arg-type]


def test_plan_grid_potential_field_defaults_to_a_seeded_rng_and_respects_impassable_cost() -> None:
    a = plan_grid(CUP, CUP_START, CUP_GOAL, algorithm="potential_field")
    b = plan_grid(CUP, CUP_START, CUP_GOAL, algorithm="potential_field")
    np.testing.assert_array_equal(a.cells, b.cells)  # no rng given: the same seeded run each time
    occ = np.zeros((7, 7), dtype=bool)
    cost = np.zeros((7, 7))
    cost[:6, 3] = np.inf  # a wall made of impassable cost, open at the bottom row
    p = plan_grid(occ, (0, 0), (0, 6), algorithm="potential_field", cost=cost)
    assert not np.isinf(cost[p.cells[:, 0], p.cells[:, 1]]).any()

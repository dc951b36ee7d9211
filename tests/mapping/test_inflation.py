"""Inflation costmap, clearance and C-space masks: hand-worked Nav2-style costs and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.mapping import (
    INSCRIBED_COST,
    LETHAL_COST,
    CellState,
    InvalidGridError,
    InvalidParameterError,
    clearance_m,
    inflate_mask,
    inflation_costmap,
)


def single_obstacle(n: int = 9) -> np.ndarray:
    occ = np.zeros((n, n), dtype=np.int8)
    occ[n // 2, n // 2] = 100
    return occ


def test_costmap_hand_worked_single_obstacle() -> None:
    # res 0.5 m, r = 0.5 m, R = 1.5 m, s = 1/m: cost = floor(98·exp(−(d − 0.5))) for 0.5 < d ≤ 1.5.
    # d = √0.5 → 79, 1 → 59, √1.25 → 52, √2 → 39, 1.5 → 36; d = 0.5 → 99 (inscribed); d = √2.5 > 1.5 → 0.
    cost = inflation_costmap(
        single_obstacle(), 0.5, robot_radius_m=0.5, inflation_radius_m=1.5, cost_scaling_factor=1.0
    )
    assert cost.dtype == np.int8
    expected = np.array(
        [
            [0, 0, 0, 0, 0, 0, 0, 0, 0],
            [0, 0, 0, 0, 36, 0, 0, 0, 0],
            [0, 0, 39, 52, 59, 52, 39, 0, 0],
            [0, 0, 52, 79, 99, 79, 52, 0, 0],
            [0, 36, 59, 99, 100, 99, 59, 36, 0],
            [0, 0, 52, 79, 99, 79, 52, 0, 0],
            [0, 0, 39, 52, 59, 52, 39, 0, 0],
            [0, 0, 0, 0, 36, 0, 0, 0, 0],
            [0, 0, 0, 0, 0, 0, 0, 0, 0],
        ],
        dtype=np.int8,
    )
    np.testing.assert_array_equal(cost, expected)
    assert LETHAL_COST == 100
    assert INSCRIBED_COST == CellState.INFLATED == 99


def test_costmap_decays_monotonically_and_faster_with_larger_scaling() -> None:
    occ = np.zeros((1, 40), dtype=np.int8)
    occ[0, 0] = 100
    slow = inflation_costmap(occ, 0.05, 0.2, 1.5, cost_scaling_factor=1.0)[0]
    fast = inflation_costmap(occ, 0.05, 0.2, 1.5, cost_scaling_factor=10.0)[0]
    assert slow[0] == 100
    assert np.all(slow[1:5] == 99)  # d = 0.05..0.20 ≤ r
    assert np.all(np.diff(slow[4:]) <= 0)
    assert np.all(fast[5:] <= slow[5:])
    # d = 0.25 m: 98·exp(−10·0.05) = 59.4 → 59.
    assert fast[5] == 59
    assert slow[31] == 0  # d = 1.55 m > R


def test_unknown_cell_options() -> None:
    occ = np.zeros((1, 12), dtype=np.int8)
    occ[0, 0] = 100
    occ[0, 1] = -1  # unknown, within the inscribed radius
    occ[0, 9] = -1  # unknown, far away
    keep = inflation_costmap(occ, 1.0, 1.0, 4.0, 1.0, unknown="unknown")
    assert keep[0, 1] == 99  # Nav2: unknown within the inscribed radius takes the inscribed cost
    assert keep[0, 9] == -1
    assert keep[0, 2] == math.floor(98 * math.exp(-1.0))
    free = inflation_costmap(occ, 1.0, 1.0, 4.0, 1.0, unknown="free")
    assert free[0, 1] == 99
    assert free[0, 9] == 0
    lethal = inflation_costmap(occ, 1.0, 1.0, 4.0, 1.0, unknown="lethal")
    assert lethal[0, 9] == 100
    assert lethal[0, 8] == 99
    assert lethal[0, 10] == 99
    assert lethal[0, 7] == math.floor(98 * math.exp(-1.0))


def test_occupied_threshold_and_no_obstacles() -> None:
    occ = np.array([[0, 64, 65, 0, 0, 0]], dtype=np.int8)
    cost = inflation_costmap(occ, 1.0, 0.0, 0.0)
    np.testing.assert_array_equal(cost, [[0, 0, 100, 0, 0, 0]])
    cost = inflation_costmap(occ, 1.0, 0.0, 0.0, occupied_threshold=60)
    np.testing.assert_array_equal(cost, [[0, 100, 100, 0, 0, 0]])
    np.testing.assert_array_equal(inflation_costmap(occ >= 65, 1.0, 0.0, 0.0), [[0, 0, 100, 0, 0, 0]])
    empty = np.zeros((3, 4), dtype=np.int8)
    np.testing.assert_array_equal(inflation_costmap(empty, 0.1, 0.3, 1.0), np.zeros((3, 4)))


def test_clearance_euclidean_and_chebyshev() -> None:
    obs = np.zeros((5, 6), dtype=bool)
    obs[1, 1] = True
    d = clearance_m(obs, 0.5)
    assert d[1, 1] == 0.0
    assert d[1, 4] == pytest.approx(1.5)
    assert d[4, 5] == pytest.approx(0.5 * math.hypot(3, 4))
    c = clearance_m(obs, 0.5, norm="chebyshev")
    assert c[4, 5] == pytest.approx(0.5 * 4)
    assert c[3, 3] == pytest.approx(1.0)
    assert np.all(np.isinf(clearance_m(np.zeros((2, 3), dtype=bool), 0.1)))
    assert np.all(np.isinf(clearance_m(np.zeros((2, 3), dtype=bool), 0.1, norm="chebyshev")))


def test_inflate_mask_is_a_disc() -> None:
    obs = np.zeros((7, 7), dtype=bool)
    obs[3, 3] = True
    m = inflate_mask(obs, 0.1, 0.2)
    assert m.sum() == 13  # |Δ|² ≤ 4: the 13 lattice points of a radius-2 disc
    assert m[3, 1] and m[2, 2] and not m[1, 1]


@pytest.mark.parametrize(
    ("occupancy", "kwargs"),
    [
        (np.zeros((3, 3)), {}),  # float dtype
        (np.zeros((0, 3), dtype=np.int8), {}),
        (np.zeros(9, dtype=np.int8), {}),
        (np.full((3, 3), 101, dtype=np.int16), {}),
        (np.full((3, 3), -2, dtype=np.int8), {}),
    ],
)
def test_costmap_rejects_bad_grids(occupancy: np.ndarray, kwargs: dict) -> None:
    with pytest.raises(InvalidGridError):
        inflation_costmap(occupancy, 0.1, 0.2, 0.5, **kwargs)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"resolution_m": 0.0},
        {"resolution_m": float("nan")},
        {"robot_radius_m": -0.1},
        {"inflation_radius_m": 0.1},  # smaller than the robot radius
        {"cost_scaling_factor": float("inf")},
        {"unknown": "maybe"},
        {"occupied_threshold": 0},
        {"occupied_threshold": 50.0},
    ],
)
def test_costmap_rejects_bad_parameters(kwargs: dict) -> None:
    args = {"resolution_m": 0.1, "robot_radius_m": 0.2, "inflation_radius_m": 0.5} | kwargs
    with pytest.raises(InvalidParameterError):
        inflation_costmap(single_obstacle(), **args)


def test_clearance_rejects_bad_input() -> None:
    with pytest.raises(InvalidGridError):
        clearance_m(np.zeros((3, 3), dtype=np.int8), 0.1)
    with pytest.raises(InvalidGridError):
        clearance_m(np.zeros((0, 0), dtype=bool), 0.1)
    with pytest.raises(InvalidParameterError):
        clearance_m(np.zeros((3, 3), dtype=bool), -1.0)
    with pytest.raises(InvalidParameterError):
        clearance_m(np.zeros((3, 3), dtype=bool), 0.1, norm="manhattan")  # type: ignore[arg-type]
    with pytest.raises(InvalidParameterError):
        inflate_mask(np.zeros((3, 3), dtype=bool), 0.1, float("nan"))


@pytest.mark.parametrize("seed", range(6))
def test_costmap_equals_the_whole_grid_brute_force(seed: int) -> None:
    """The costmap transforms only the obstacles' bounding box grown by the inflation radius: every cell must still
    get the cost of its brute-force nearest-obstacle distance (obstacles anywhere, also near the grid's edges)."""
    rng = np.random.default_rng(seed)
    h, w, res = 60, 70, 0.05
    occ = np.full((h, w), -1, dtype=np.int8)
    r0, c0 = rng.integers(0, h - 10), rng.integers(0, w - 10)
    occ[r0 : r0 + 20, c0 : c0 + 25] = 0  # a known patch, somewhere
    blobs = rng.integers(0, [h, w], size=(4, 2))
    occ[blobs[:, 0], blobs[:, 1]] = 100
    obstacles = occ >= 65
    r_in, r_out, scale = 0.2, 0.7, 5.0
    got = inflation_costmap(occ, res, r_in, r_out, cost_scaling_factor=scale)
    rr, cc = np.indices((h, w))
    orr, occ_c = np.nonzero(obstacles)
    d = np.sqrt(((rr[..., None] - orr) ** 2 + (cc[..., None] - occ_c) ** 2).min(axis=-1)) * res
    want = np.zeros((h, w), dtype=np.int8)
    decay = (d > r_in) & (d <= r_out)
    want[decay] = np.floor(98 * np.exp(-scale * (d[decay] - r_in))).astype(np.int8)
    want[(d > 0) & (d <= r_in)] = INSCRIBED_COST
    want[obstacles] = LETHAL_COST
    want[(occ < 0) & (want < INSCRIBED_COST)] = -1
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("norm", ["euclidean", "chebyshev"])
def test_clearance_within_is_exact_up_to_the_bound(norm: str) -> None:
    rng = np.random.default_rng(3)
    obs = np.zeros((80, 90), dtype=bool)
    obs[rng.integers(20, 40, 5), rng.integers(30, 60, 5)] = True
    full = clearance_m(obs, 0.05, norm=norm)  # type: ignore[arg-type]
    near = clearance_m(obs, 0.05, norm=norm, within_m=0.4)  # type: ignore[arg-type]
    close = full <= 0.4
    np.testing.assert_array_equal(near[close], full[close])
    assert np.all(near[~close] > 0.4)
    assert np.isinf(near[79, 0]) and np.isfinite(full[79, 0])  # far cells were not transformed
    with pytest.raises(InvalidParameterError):
        clearance_m(obs, 0.05, within_m=-1.0)


def test_inflate_mask_matches_the_definition_cell_by_cell_ties_included() -> None:
    """The disc dilation against brute force: every cell within the radius of an obstacle cell's centre, for radii
    that put cells exactly on the circle (5 cells, a 3-4-5 triangle; √2 and √5 cells) and for none."""
    rng = np.random.default_rng(3)
    for _ in range(60):
        h, w = (int(v) for v in rng.integers(1, 25, size=2))
        obstacles = rng.random((h, w)) < float(rng.choice([0.0, 0.02, 0.2]))
        res = float(rng.choice([0.05, 0.1, 0.03]))
        radius = float(rng.choice([0.0, 0.19, 5 * res, math.sqrt(2) * res, math.sqrt(5) * res, 0.5]))
        rows, cols = np.nonzero(obstacles)
        r, c = np.mgrid[0:h, 0:w]
        expected = np.zeros((h, w), dtype=bool)
        for i, j in zip(rows, cols, strict=True):
            expected |= np.hypot((r - i) * res, (c - j) * res) <= radius
        np.testing.assert_array_equal(inflate_mask(obstacles, res, radius), expected)

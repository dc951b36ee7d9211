"""plan_grid: optimality against an independent Dijkstra, the seed properties, the cost grid, typed errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.planning import (
    GoalOccupied,
    GoalOutsideMap,
    GridPlan,
    InvalidInput,
    InvalidPath,
    NoPathFound,
    OutsideMap,
    StartOccupied,
    StartOutsideMap,
    check_path,
    path_cost,
    plan_grid,
)
from mjnav.planning._workspace import get_workspace, release_workspace
from tests.planning import oracle

SQRT2 = math.sqrt(2.0)

# Start S at the left, goal G at the right, a wall with its only opening at the top row.
TRAP_ROWS = [
    ".........",
    ".....#...",
    ".....#...",
    "S....#..G",
    ".....#...",
    ".....#...",
    ".....#...",
]
TRAP = np.array([[ch == "#" for ch in row] for row in TRAP_ROWS])
TRAP_START, TRAP_GOAL = (3, 0), (3, 8)
# By hand: three diagonals up to (0, 3), east to (0, 6) (the diagonal (0, 5) -> (1, 6) would cut the wall's
# corner), two diagonals down to (2, 8), one step to G: 5·√2 + 4.
TRAP_OPTIMUM = 5 * SQRT2 + 4


def random_map(rng: np.random.Generator, shape: tuple[int, int], density: float) -> np.ndarray:
    return rng.random(shape) < density


def free_pair(rng: np.random.Generator, occ: np.ndarray) -> tuple[tuple[int, int], tuple[int, int]]:
    free = np.argwhere(~occ)
    a, b = free[rng.choice(len(free), 2, replace=False)]
    return (int(a[0]), int(a[1])), (int(b[0]), int(b[1]))


def assert_valid(plan: GridPlan, occ: np.ndarray, start, goal, connectivity: int = 8, cut: bool = False) -> None:
    check_path(occ, plan.cells, start=start, goal=goal, connectivity=connectivity, corner_cutting=cut)
    assert plan.cells.dtype == np.int64 and plan.cells.shape[1] == 2
    assert path_cost(plan.cells) == pytest.approx(plan.cost, rel=1e-12, abs=1e-12)


def test_open_grid_hand_worked() -> None:
    occ = np.zeros((5, 5), dtype=bool)
    for alg in ("astar", "dijkstra", "jps"):
        p = plan_grid(occ, (0, 0), (4, 2), algorithm=alg)
        assert p.cost == pytest.approx(2 + 2 * SQRT2)  # two diagonals, two straight
        assert p.cells.shape == (5, 2)
        assert p.algorithm == alg
    p4 = plan_grid(occ, (0, 0), (4, 2), connectivity=4)
    assert p4.cost == 6.0
    check_path(occ, p4.cells, connectivity=4)


def test_trap_map_hand_worked_optimum() -> None:
    for alg in ("astar", "dijkstra", "jps", "bfs"):
        p = plan_grid(TRAP, TRAP_START, TRAP_GOAL, algorithm=alg)
        assert p.cost == pytest.approx(TRAP_OPTIMUM, abs=1e-12), alg
        assert_valid(p, TRAP, TRAP_START, TRAP_GOAL)


def test_dfs_and_greedy_are_complete_but_not_optimal() -> None:
    greedy = plan_grid(TRAP, TRAP_START, TRAP_GOAL, algorithm="greedy")
    dfs = plan_grid(TRAP, TRAP_START, TRAP_GOAL, algorithm="dfs")
    for p in (greedy, dfs):
        assert_valid(p, TRAP, TRAP_START, TRAP_GOAL)
        assert p.cost > TRAP_OPTIMUM + 1.0
    # Greedy runs straight at the wall, then along it: 3 diagonals and 8 straight steps.
    assert greedy.cost == pytest.approx(3 * SQRT2 + 8)


def test_large_beta_behaves_like_greedy() -> None:
    greedy = plan_grid(TRAP, TRAP_START, TRAP_GOAL, algorithm="greedy")
    astar = plan_grid(TRAP, TRAP_START, TRAP_GOAL, algorithm="astar")
    weighted = plan_grid(TRAP, TRAP_START, TRAP_GOAL, algorithm="astar", weights=(1.0, 1000.0))
    np.testing.assert_array_equal(weighted.cells, greedy.cells)
    assert weighted.expanded == greedy.expanded < astar.expanded
    assert weighted.cost > astar.cost
    # β = 0 is Dijkstra.
    dij = plan_grid(TRAP, TRAP_START, TRAP_GOAL, algorithm="dijkstra")
    zero_beta = plan_grid(TRAP, TRAP_START, TRAP_GOAL, algorithm="astar", weights=(1.0, 0.0))
    assert zero_beta.cost == dij.cost and zero_beta.expanded == dij.expanded


def test_astar_expands_fewer_than_dijkstra_and_jps_fewer_still() -> None:
    dij = plan_grid(TRAP, TRAP_START, TRAP_GOAL, algorithm="dijkstra")
    ast = plan_grid(TRAP, TRAP_START, TRAP_GOAL, algorithm="astar")
    jps = plan_grid(TRAP, TRAP_START, TRAP_GOAL, algorithm="jps")
    assert jps.expanded < ast.expanded < dij.expanded


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize(("connectivity", "cut"), [(8, False), (8, True), (4, False)])
def test_optimal_algorithms_match_independent_dijkstra(seed: int, connectivity: int, cut: bool) -> None:
    rng = np.random.default_rng(seed)
    occ = random_map(rng, (int(rng.integers(8, 40)), int(rng.integers(8, 40))), rng.uniform(0.1, 0.45))
    algorithms = ["dijkstra", "astar"] + (["jps"] if connectivity == 8 and not cut else [])
    heuristics = ["octile", "euclidean", "chebyshev"] + (["manhattan"] if connectivity == 4 else [])
    for _ in range(8):
        start, goal = free_pair(rng, occ)
        ref = oracle.distances(occ, start, connectivity=connectivity, corner_cutting=cut)[goal]
        for alg in algorithms:
            for heur in heuristics if alg != "dijkstra" else ["octile"]:
                kwargs = {"algorithm": alg, "heuristic": heur, "connectivity": connectivity, "corner_cutting": cut}
                if not math.isfinite(ref):
                    with pytest.raises(NoPathFound):
                        plan_grid(occ, start, goal, **kwargs)
                    continue
                p = plan_grid(occ, start, goal, **kwargs)
                assert p.cost == pytest.approx(ref, abs=1e-9), (alg, heur)
                assert_valid(p, occ, start, goal, connectivity, cut)


@pytest.mark.parametrize("seed", range(4))
def test_jps_equals_astar_on_larger_maps(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    occ = random_map(rng, (120, 90), [0.05, 0.2, 0.35, 0.45][seed])
    for _ in range(10):
        start, goal = free_pair(rng, occ)
        try:
            a = plan_grid(occ, start, goal, algorithm="astar")
        except NoPathFound:
            with pytest.raises(NoPathFound):
                plan_grid(occ, start, goal, algorithm="jps")
            continue
        j = plan_grid(occ, start, goal, algorithm="jps")
        assert j.cost == pytest.approx(a.cost, abs=1e-9)
        assert j.expanded <= a.expanded
        assert_valid(j, occ, start, goal)


@pytest.mark.parametrize("shape", [(150, 5), (7, 150), (97, 83)])
def test_jps_on_thin_tall_and_strided_maps(shape: tuple[int, int]) -> None:
    """Lines spanning several 64-cell words either way, widths that are not a multiple of 8, and occupancy given
    as strided views: jps matches the independent Dijkstra."""
    rng = np.random.default_rng(shape[0])
    occ = random_map(rng, shape, 0.25)
    for grid in (occ, occ.T, occ[::-1, ::2]):
        for _ in range(6):
            start, goal = free_pair(rng, grid)
            ref = oracle.distances(grid, start)[goal]
            if not math.isfinite(ref):
                with pytest.raises(NoPathFound):
                    plan_grid(grid, start, goal, algorithm="jps")
                continue
            p = plan_grid(grid, start, goal, algorithm="jps")
            assert p.cost == pytest.approx(ref, abs=1e-9)
            assert_valid(p, grid, start, goal)


@pytest.mark.parametrize("seed", range(4))
def test_bfs_optimal_on_4_connected_and_fewest_steps_on_8_connected(seed: int) -> None:
    rng = np.random.default_rng(200 + seed)
    occ = random_map(rng, (30, 30), 0.3)
    for _ in range(10):
        start, goal = free_pair(rng, occ)
        ref4 = oracle.distances(occ, start, connectivity=4)[goal]
        steps8 = oracle.distances(occ, start, unit_steps=True)[goal]
        if not math.isfinite(steps8):
            continue
        p8 = plan_grid(occ, start, goal, algorithm="bfs")
        assert len(p8.cells) - 1 == steps8
        assert_valid(p8, occ, start, goal)
        if math.isfinite(ref4):
            p4 = plan_grid(occ, start, goal, algorithm="bfs", connectivity=4)
            assert p4.cost == ref4
            assert_valid(p4, occ, start, goal, connectivity=4)


@pytest.mark.parametrize("seed", range(4))
def test_dfs_and_greedy_complete_on_random_maps(seed: int) -> None:
    rng = np.random.default_rng(300 + seed)
    occ = random_map(rng, (25, 35), 0.35)
    for _ in range(10):
        start, goal = free_pair(rng, occ)
        reachable = math.isfinite(oracle.distances(occ, start)[goal])
        for alg in ("dfs", "greedy"):
            if reachable:
                assert_valid(plan_grid(occ, start, goal, algorithm=alg), occ, start, goal)
            else:
                with pytest.raises(NoPathFound):
                    plan_grid(occ, start, goal, algorithm=alg)


def test_corner_cutting_rule() -> None:
    gap = np.array([[False, True], [True, False]])
    with pytest.raises(NoPathFound):
        plan_grid(gap, (0, 0), (1, 1))
    assert plan_grid(gap, (0, 0), (1, 1), corner_cutting=True).cost == pytest.approx(SQRT2)
    ell = np.array([[False, True], [False, False]])
    assert plan_grid(ell, (0, 0), (1, 1)).cost == 2.0  # around the corner
    assert plan_grid(ell, (0, 0), (1, 1), corner_cutting=True).cost == pytest.approx(SQRT2)


def test_cost_grid_hand_worked() -> None:
    occ = np.zeros((1, 3), dtype=bool)
    cost = np.array([[0.0, 1.0, 0.0]])
    p = plan_grid(occ, (0, 0), (0, 2), cost=cost)
    assert p.cost == pytest.approx(1.5 + 1.5)  # each step: 1·(1 + (0 + 1)/2)
    assert p.cost == pytest.approx(path_cost(p.cells, cost))
    # A costly middle row makes the planner go around it.
    occ = np.zeros((3, 3), dtype=bool)
    cost = np.zeros((3, 3))
    cost[1, :2] = 10.0
    straight = plan_grid(occ, (0, 0), (2, 0))
    detour = plan_grid(occ, (0, 0), (2, 0), cost=cost)
    assert straight.cost == 2.0
    assert detour.cost == pytest.approx(2 + 2 * SQRT2)  # (0,0) (0,1) (1,2) (2,1) (2,0), all of cost 0
    assert all(tuple(c) not in {(1, 0), (1, 1)} for c in detour.cells)
    # +inf blocks, NaN and negative costs are rejected.
    cost_inf = np.zeros((3, 3))
    cost_inf[1, :] = np.inf
    with pytest.raises(NoPathFound):
        plan_grid(occ, (0, 0), (2, 0), cost=cost_inf)
    with pytest.raises(GoalOccupied):
        plan_grid(occ, (0, 0), (1, 1), cost=cost_inf)


@pytest.mark.parametrize("seed", range(3))
def test_cost_grid_matches_independent_dijkstra(seed: int) -> None:
    rng = np.random.default_rng(400 + seed)
    occ = random_map(rng, (25, 25), 0.2)
    cost = rng.uniform(0.0, 3.0, occ.shape)
    for _ in range(6):
        start, goal = free_pair(rng, occ)
        ref = oracle.distances(occ, start, cost=cost)[goal]
        if not math.isfinite(ref):
            continue
        for alg in ("dijkstra", "astar"):
            p = plan_grid(occ, start, goal, algorithm=alg, cost=cost)
            assert p.cost == pytest.approx(ref, abs=1e-9)
            assert path_cost(p.cells, cost) == pytest.approx(p.cost, abs=1e-9)
            assert_valid_cells_only(p, occ, start, goal)


def assert_valid_cells_only(plan: GridPlan, occ: np.ndarray, start, goal) -> None:
    check_path(occ, plan.cells, start=start, goal=goal)


def test_start_equals_goal_and_integer_maps() -> None:
    occ = np.zeros((3, 3), dtype=np.uint8)
    occ[1, 1] = 1
    for alg in ("astar", "jps", "bfs", "dfs", "greedy", "dijkstra"):
        p = plan_grid(occ, (0, 0), (0, 0), algorithm=alg)
        assert p.cost == 0.0 and p.cells.tolist() == [[0, 0]]
    assert plan_grid(occ, (0, 0), (2, 2)).cost == 4.0  # the centre is occupied: around the side
    assert plan_grid(occ, np.array([0, 0]), (2.0, 2.0)).cost == 4.0


def test_typed_errors() -> None:
    occ = np.zeros((4, 5), dtype=bool)
    occ[0, 0] = occ[3, 4] = True
    with pytest.raises(StartOccupied):
        plan_grid(occ, (0, 0), (1, 1))
    with pytest.raises(GoalOccupied):
        plan_grid(occ, (1, 1), (3, 4))
    with pytest.raises(StartOutsideMap):
        plan_grid(occ, (4, 0), (1, 1))
    with pytest.raises(GoalOutsideMap):
        plan_grid(occ, (1, 1), (0, -1))
    with pytest.raises(OutsideMap):
        plan_grid(occ, (1, 1), (10, 10))
    walled = np.zeros((3, 3), dtype=bool)
    walled[:, 1] = True
    for alg in ("astar", "jps", "dijkstra", "bfs", "dfs", "greedy"):
        with pytest.raises(NoPathFound):
            plan_grid(walled, (0, 0), (0, 2), algorithm=alg)


@pytest.mark.parametrize(
    ("occupied", "start", "goal", "kwargs", "fragment"),
    [
        (np.zeros((0, 5), bool), (0, 0), (0, 1), {}, "empty"),
        (np.zeros(5, bool), (0, 0), (0, 1), {}, "2-D"),
        (np.zeros((3, 3)), (0, 0), (1, 1), {}, "dtype"),
        (np.array([["a", "b"]]), (0, 0), (0, 1), {}, "dtype"),
        (np.zeros((3, 3), bool), (math.nan, 0), (1, 1), {}, "finite integer"),
        (np.zeros((3, 3), bool), (0.5, 0), (1, 1), {}, "finite integer"),
        (np.zeros((3, 3), bool), (0, 0, 0), (1, 1), {}, "pair"),
        (np.zeros((3, 3), bool), "ab", (1, 1), {}, "integers"),
        (np.zeros((3, 3), bool), 7, (1, 1), {}, "pair"),
        (np.zeros((3, 3), bool), (True, 0), (1, 1), {}, "integers"),
        (np.zeros((3, 3), bool), (0, 0), (1, 1), {"algorithm": "rrt"}, "unknown algorithm"),
        (np.zeros((3, 3), bool), (0, 0), (1, 1), {"heuristic": "l3"}, "unknown heuristic"),
        (np.zeros((3, 3), bool), (0, 0), (1, 1), {"connectivity": 6}, "connectivity"),
        (np.zeros((3, 3), bool), (0, 0), (1, 1), {"weights": (1.0, math.nan)}, "weights"),
        (np.zeros((3, 3), bool), (0, 0), (1, 1), {"weights": (0.0, 0.0)}, "weights"),
        (np.zeros((3, 3), bool), (0, 0), (1, 1), {"weights": (1.0,)}, "weights"),
        (np.zeros((3, 3), bool), (0, 0), (1, 1), {"cost": np.full((3, 3), math.nan)}, "NaN"),
        (np.zeros((3, 3), bool), (0, 0), (1, 1), {"cost": -np.ones((3, 3))}, ">= 0"),
        (np.zeros((3, 3), bool), (0, 0), (1, 1), {"cost": np.ones((2, 3))}, "shape"),
        (np.zeros((3, 3), bool), (0, 0), (1, 1), {"algorithm": "jps", "connectivity": 4}, "jps"),
        (np.zeros((3, 3), bool), (0, 0), (1, 1), {"algorithm": "jps", "corner_cutting": True}, "jps"),
        (np.zeros((3, 3), bool), (0, 0), (1, 1), {"algorithm": "jps", "cost": np.ones((3, 3))}, "jps"),
    ],
)
def test_bad_input_is_invalid_input(occupied, start, goal, kwargs, fragment) -> None:
    with pytest.raises(InvalidInput, match=fragment):
        plan_grid(occupied, start, goal, **kwargs)


def test_check_path_and_path_cost() -> None:
    occ = np.zeros((3, 3), dtype=bool)
    occ[0, 1] = True
    good = np.array([[0, 0], [1, 0], [2, 1], [2, 2]])
    check_path(occ, good, start=(0, 0), goal=(2, 2))
    assert path_cost(good) == pytest.approx(2 + SQRT2)
    assert path_cost(good[:1]) == 0.0
    cases = [
        (np.array([[0, 0], [2, 0]]), "legal unit move"),
        (np.array([[0, 0], [0, 0]]), "legal unit move"),
        (np.array([[0, 0], [0, 1]]), "occupied"),
        (np.array([[0, 0], [1, 1]]), "cuts a corner"),
        (np.array([[0, 0], [-1, 0]]), "outside"),
        (np.zeros((0, 2), dtype=int), "non-empty"),
        (np.array([[0.0, 0.0]]), "integers"),
    ]
    for cells, fragment in cases:
        with pytest.raises(InvalidPath, match=fragment):
            check_path(occ, cells)
    check_path(occ, np.array([[0, 0], [1, 1]]), corner_cutting=True)
    with pytest.raises(InvalidPath, match="legal unit move"):
        check_path(occ, np.array([[1, 0], [2, 1]]), connectivity=4)
    with pytest.raises(InvalidPath, match="ends at"):
        check_path(occ, good, goal=(2, 1))


def test_workspace_reuse_and_heap_growth() -> None:
    """Searches of different sizes reuse one workspace; a full heap is grown and the search rerun."""
    rng = np.random.default_rng(5)
    big = random_map(rng, (60, 70), 0.25)
    small = random_map(rng, (9, 11), 0.2)
    release_workspace()
    results = []
    for occ in (big, small, big, small):
        start, goal = free_pair(np.random.default_rng(occ.shape[0]), occ)
        ref = oracle.distances(occ, start)[goal]
        ws = get_workspace((occ.shape[0] + 2) * (occ.shape[1] + 2))
        ws.keys = ws.keys[:2]  # force overflows: the kernels must report them and the caller regrow
        ws.subs = ws.subs[:2]
        ws.items = ws.items[:2]
        for alg in ("astar", "jps", "dfs", "astar with cost"):
            cost = np.zeros(occ.shape) if alg == "astar with cost" else None
            try:
                p = plan_grid(occ, start, goal, algorithm=alg.split()[0], cost=cost)
            except NoPathFound:
                assert not math.isfinite(ref)
                continue
            if alg != "dfs":
                assert p.cost == pytest.approx(ref, abs=1e-9)
            assert_valid(p, occ, start, goal)
            results.append(p.cost)
    assert results

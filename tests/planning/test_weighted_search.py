"""plan_grid with a cost grid (the compiled search of mjnav.planning._weighted): exact optimal costs against
scikit-image's MCP_Geometric on Moving AI maps and against an independent Dijkstra on random maps, valid paths,
the scaled heuristic, ties on zero-cost plateaus, non-optimal modes and typed errors."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import distance_transform_edt

from mjnav.mapping.movingai import read_movingai_map, read_movingai_scen
from mjnav.planning import GoalOccupied, InvalidInput, NoPathFound, StartOccupied, check_path, path_cost, plan_grid
from tests.planning import oracle

SQRT2 = math.sqrt(2.0)


def clearance_cost(blocked: np.ndarray) -> np.ndarray:
    """The benchmark's cost field minus one: 8·exp(−d/4), d = distance to the nearest blocked cell (cells)."""
    d = distance_transform_edt(~blocked)
    return np.where(blocked, 0.0, 8.0 * np.exp(-d / 4.0))


@pytest.mark.parametrize(("name", "queries"), [("den312d", 6), ("Boston_0_256", 3), ("random512-40-5", 4)])
def test_costs_equal_mcp_geometric_on_movingai_maps(refdata: Path, name: str, queries: int) -> None:
    graph = pytest.importorskip("skimage.graph")
    blocked = np.asarray(read_movingai_map(refdata / "movingai" / f"{name}.map").blocked)
    scen = read_movingai_scen(refdata / "movingai" / f"{name}.map.scen")
    extra = clearance_cost(blocked)
    mcp = graph.MCP_Geometric(np.where(blocked, np.inf, 1.0 + extra))
    rng = np.random.default_rng(17)
    longest = sorted(scen, key=lambda s: -s.optimal_length)[:2]
    picked = longest + [scen[int(i)] for i in rng.choice(len(scen), queries - 2, replace=False)]
    for q in picked:
        plan = plan_grid(blocked, q.start, q.goal, cost=extra, corner_cutting=True)
        costs, _ = mcp.find_costs([q.start], [q.goal])
        ref = float(costs[q.goal])
        assert plan.cost == pytest.approx(ref, rel=1e-12), (name, q.start, q.goal)
        assert plan.cost > path_cost(plan.cells)  # every cell costs more than 1 per unit length
        check_path(blocked, plan.cells, start=q.start, goal=q.goal, corner_cutting=True)
        assert path_cost(plan.cells, extra) == pytest.approx(plan.cost, rel=1e-12)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize(("connectivity", "cut"), [(8, False), (8, True), (4, False)])
def test_matches_independent_dijkstra_with_a_high_floor_and_impassable_cells(
    seed: int, connectivity: int, cut: bool
) -> None:
    """The heuristic is scaled by 1 + min(cost) (here ≥ 3): still optimal for every admissible metric."""
    rng = np.random.default_rng(900 + seed)
    occ = rng.random((30, 26)) < 0.2
    cost = rng.uniform(2.0, 5.0, occ.shape)
    cost[rng.random(occ.shape) < 0.05] = np.inf
    heuristics = ["octile", "euclidean", "chebyshev"] if connectivity == 8 else ["manhattan", "octile"]
    for _ in range(5):
        free = np.argwhere(~occ & np.isfinite(cost))
        a, b = free[rng.choice(len(free), 2, replace=False)]
        start, goal = (int(a[0]), int(a[1])), (int(b[0]), int(b[1]))
        ref = oracle.distances(occ, start, connectivity=connectivity, corner_cutting=cut, cost=cost)[goal]
        for alg, heur in [("dijkstra", "octile")] + [("astar", h) for h in heuristics]:
            kwargs = {"algorithm": alg, "heuristic": heur, "connectivity": connectivity, "corner_cutting": cut}
            if not math.isfinite(ref):
                with pytest.raises(NoPathFound):
                    plan_grid(occ, start, goal, cost=cost, **kwargs)
                continue
            p = plan_grid(occ, start, goal, cost=cost, **kwargs)
            assert p.cost == pytest.approx(ref, rel=1e-12), (alg, heur)
            blocked = occ | np.isinf(cost)
            check_path(blocked, p.cells, start=start, goal=goal, connectivity=connectivity, corner_cutting=cut)
            assert path_cost(p.cells, cost) == pytest.approx(p.cost, rel=1e-12)


def test_scaled_heuristic_expands_like_unweighted_astar_on_a_uniform_cost() -> None:
    occ = np.zeros((60, 60), dtype=bool)
    occ[10:50, 30] = True
    cost = np.full(occ.shape, 3.0)
    astar = plan_grid(occ, (30, 5), (30, 55), cost=cost)
    dijkstra = plan_grid(occ, (30, 5), (30, 55), algorithm="dijkstra", cost=cost)
    plain = plan_grid(occ, (30, 5), (30, 55))
    assert astar.cost == pytest.approx(dijkstra.cost, rel=1e-12)
    assert astar.cost == pytest.approx(4.0 * plain.cost, rel=1e-12)
    # Scaled by 1 + min(cost) = 4 the octile heuristic is as informed as on the unweighted map.
    assert astar.expanded <= 1.05 * plain.expanded
    assert astar.expanded < dijkstra.expanded / 3


def test_zero_cost_plateau_is_crossed_without_expanding_it() -> None:
    """Equal f everywhere on an empty zero-cost grid: the tie-break follows one optimal path."""
    occ = np.zeros((100, 100), dtype=bool)
    for goal in [(99, 99), (99, 40), (0, 99)]:
        p = plan_grid(occ, (0, 0), goal, cost=np.zeros(occ.shape))
        assert len(p.cells) == 100
        assert 99 <= p.expanded <= 100  # the path's cells (the goal need not be expanded)
        dr, dc = goal
        assert p.cost == pytest.approx(max(dr, dc) + (SQRT2 - 1) * min(dr, dc), rel=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_non_optimal_modes_report_the_cost_of_their_path(seed: int) -> None:
    rng = np.random.default_rng(40 + seed)
    occ = rng.random((40, 40)) < 0.25
    cost = rng.uniform(0.0, 4.0, occ.shape)
    free = np.argwhere(~occ)
    a, b = free[rng.choice(len(free), 2, replace=False)]
    start, goal = (int(a[0]), int(a[1])), (int(b[0]), int(b[1]))
    ref = oracle.distances(occ, start, cost=cost)[goal]
    if not math.isfinite(ref):
        pytest.skip("unreachable pair")
    modes = [{"algorithm": "greedy"}, {"algorithm": "astar", "weights": (1.0, 5.0)}, {"heuristic": "manhattan"}]
    for kwargs in modes:
        p = plan_grid(occ, start, goal, cost=cost, **kwargs)  # type: ignore[arg-type]
        check_path(occ, p.cells, start=start, goal=goal)
        assert path_cost(p.cells, cost) == pytest.approx(p.cost, rel=1e-12)
        assert p.cost >= ref - 1e-9


def test_cost_grid_errors_are_typed() -> None:
    occ = np.zeros((4, 4), dtype=bool)
    cost = np.zeros((4, 4))
    cost[0, 0] = np.inf
    with pytest.raises(StartOccupied):
        plan_grid(occ, (0, 0), (3, 3), cost=cost)
    with pytest.raises(GoalOccupied):
        plan_grid(occ, (3, 3), (0, 0), cost=cost)
    nan = np.zeros((4, 4))
    nan[2, 2] = math.nan
    with pytest.raises(InvalidInput, match="NaN"):
        plan_grid(occ, (0, 1), (3, 3), cost=nan)
    with pytest.raises(InvalidInput, match="NaN"):  # NaN is reported even where the map is occupied
        plan_grid(np.eye(4, dtype=bool)[::-1], (0, 1), (3, 3), cost=nan)
    with pytest.raises(InvalidInput, match=">= 0"):
        plan_grid(occ, (0, 1), (3, 3), cost=-np.ones((4, 4)))
    # An integer cost grid and a non-contiguous occupancy view are accepted.
    wide = np.zeros((4, 8), dtype=bool)
    p = plan_grid(wide[:, ::2], (0, 0), (3, 3), cost=np.ones((4, 4), dtype=np.int32))
    assert p.cost == pytest.approx(3 * SQRT2 * 2.0)


def test_bucket_and_heap_searches_agree_and_wide_cost_ranges_use_the_heap(monkeypatch: pytest.MonkeyPatch) -> None:
    """A cost range too wide for the bucket window runs the heap search; a key beyond the window (forced here by
    claiming a longer bucket array than the workspace has) makes the bucket search hand over to it too."""
    from mjnav.planning import _weighted

    rng = np.random.default_rng(77)
    occ = rng.random((40, 40)) < 0.2
    occ[0, 0] = occ[39, 39] = False
    cost = rng.uniform(0.0, 3.0, occ.shape)
    ref = oracle.distances(occ, (0, 0), cost=cost)[39, 39]
    assert math.isfinite(ref)
    bucketed = plan_grid(occ, (0, 0), (39, 39), cost=cost)
    assert bucketed.cost == pytest.approx(ref, rel=1e-12)
    wide = cost.copy()
    wide[5, 5] = 1e6  # the step factor range now exceeds the window: heap search
    ref_wide = oracle.distances(occ, (0, 0), cost=wide)[39, 39]
    assert plan_grid(occ, (0, 0), (39, 39), cost=wide).cost == pytest.approx(ref_wide, rel=1e-12)
    monkeypatch.setattr(_weighted, "N_BUCKETS", 1 << 30)
    monkeypatch.setattr(_weighted, "BUCKET_WIDTH", 1e-4)
    forced = plan_grid(occ, (0, 0), (39, 39), cost=cost)
    assert forced.cost == pytest.approx(ref, rel=1e-12)
    check_path(occ, forced.cells, start=(0, 0), goal=(39, 39))


@pytest.mark.parametrize("seed", range(6))
def test_plateaus_with_islands_of_cost_match_independent_dijkstra(seed: int) -> None:
    """Zero-cost plateaus (ties everywhere) broken by costly cells: the bucket search's re-expansions, skipped
    pushes and goal cut-off must still give the optimum."""
    rng = np.random.default_rng(1200 + seed)
    occ = rng.random((35, 35)) < 0.15
    cost = np.where(rng.random(occ.shape) < 0.3, rng.choice([0.5, 2.0, 6.0], occ.shape), 0.0)
    free = np.argwhere(~occ)
    for cut in (False, True):
        for _ in range(4):
            a, b = free[rng.choice(len(free), 2, replace=False)]
            start, goal = (int(a[0]), int(a[1])), (int(b[0]), int(b[1]))
            ref = oracle.distances(occ, start, corner_cutting=cut, cost=cost)[goal]
            if not math.isfinite(ref):
                continue
            for alg in ("astar", "dijkstra"):
                p = plan_grid(occ, start, goal, algorithm=alg, cost=cost, corner_cutting=cut)
                assert p.cost == pytest.approx(ref, rel=1e-12), (alg, cut)
                check_path(occ, p.cells, start=start, goal=goal, corner_cutting=cut)
                assert path_cost(p.cells, cost) == pytest.approx(p.cost, rel=1e-12)


def test_bucket_search_does_not_cascade_re_expansions_on_a_costmap() -> None:
    """A planner-like costmap: obstacles, a cost ramp around them, zero cost elsewhere. Sums of the same steps in
    another order differ in the last bits; without REOPEN_TOLERANCE those "improvements" re-expand nodes in
    cascades: 2.0× the heap search's expansions on this map (1.4× with it; 3.5× against 1.9× on a 400×400 one).
    Same optimum as the heap search."""
    from mjnav.planning import _weighted
    from mjnav.planning._workspace import get_workspace

    rng = np.random.default_rng(3)
    occ = np.zeros((300, 300), dtype=bool)
    for _ in range(100):
        r, c = rng.integers(0, 290, 2)
        h, w = rng.integers(3, 15, 2)
        occ[r : r + h, c : c + w] = True
    d = distance_transform_edt(~occ)
    cost = np.where(occ, 0.0, 2.0 * np.clip(1.0 - d / 10.0, 0.0, 1.0))
    width = occ.shape[1] + 2
    n = (occ.shape[0] + 2) * width
    ws = get_workspace(n)
    rec, pos = ws.cost_grids(n)
    far = np.argwhere(d > 3)
    totals = np.zeros(2)
    for _ in range(8):
        a, b = far[rng.choice(len(far), 2, replace=False)]
        sn, tn = (a[0] + 1) * width + a[1] + 1, (b[0] + 1) * width + b[1] + 1
        _, lo, _ = _weighted.prepare_costs(occ, cost, rec)
        g_heap, n_heap, _ = _weighted.weighted_search(
            rec, width, sn, tn, 8, False, 1.0, 1.0, 3, 1.0 + lo, pos, ws.keys, ws.items
        )
        _weighted.prepare_costs(occ, cost, rec)
        delta = _weighted.BUCKET_WIDTH * (1.0 + lo)
        g_bucket, n_bucket, _ = _weighted.bucket_search(
            rec, width, sn, tn, 8, False, 1.0 + lo, 3, delta, ws.items, ws.links, ws.heads
        )
        assert g_bucket == pytest.approx(g_heap, rel=1e-12)
        totals += (n_heap, n_bucket)
    assert totals[1] <= 1.7 * totals[0]

"""Grid path-planning benchmark: mjnav's jps / astar against named peers on the longest Moving AI queries.

Data: Moving AI maps and scenarios from ../shared/refdata/movingai (N. Sturtevant, "Benchmarks for Grid-Based
Pathfinding", IEEE TCIAIG 4(2), 2012; ODC-BY). The optimal lengths are 8-connected, diagonal √2, no corner
cutting.

Two cases (``--cases``): ``uniform`` (the maps as they are, below) and ``weighted`` (a cost grid, further below).

Uniform-cost solvers (all timed per call, best of ``--repeat`` calls per query, the same queries in the same process):

* ``mjnav jps`` / ``mjnav astar``: :func:`mjnav.planning.plan_grid` with the default semantics (√2 diagonals, no
  corner cutting). The time is the whole call: argument checks, copying the map into the padded search grid
  (for jps also packing it into bit rows and bit columns), the search and the path extraction. Numba compilation
  is excluded by a warm-up query per map (the kernels are also cached on disk).
* ``pyastar2d`` (C++ A*, https://github.com/hjweide/pyastar2d), called as a user would:
  ``pyastar2d.astar_path(weights, start, goal, allow_diagonal=...)`` with ``weights`` a float32 grid of 1.0
  (free) and +inf (blocked) built once per map outside the timing. Its semantics differ from ours: every move,
  diagonal included, costs the weight of the entered cell (so a diagonal costs 1, not √2), its heuristic is
  Chebyshev (diagonal mode) or Manhattan (4-connected mode), and a diagonal move only needs its target cell to be
  free, i.e. it cuts corners. Its paths are therefore not optimal under our metric; we recompute their length
  with √2 diagonals and count the paths that cut corners. Two modes are run: ``allow_diagonal=True`` (its
  8-connected mode; on maps with diagonal gaps it solves an easier problem than ours) and
  ``allow_diagonal=False`` (4-connected; like no-corner-cutting it cannot squeeze through diagonal gaps, so it
  searches the same free space, but its paths are longer). The wrapper's per-call work (input checks,
  ``weights.min()``, ``weights.flatten()``) is part of its time, as it is for any user.
* ``skimage MCP``: ``skimage.graph.MCP_Geometric(costs)`` (Dijkstra; diagonal cost √2·mean of the two cell
  costs), built once per map outside the timing; timed: ``find_costs([start], [goal])`` + ``traceback(goal)``.
  It also cuts corners, so its lengths can be shorter than the published optimum.
* ``python A*``: a textbook pure-Python heapq A* with our exact semantics (octile heuristic, √2 diagonals, no
  corner cutting), run on the ``--python-queries`` longest queries only because it is slow.

Weighted case: costmap A* (what the planner service runs on inflated costmaps). Each map gets the cost field
C = 1 + 8·exp(−d/4), d = Euclidean distance (cells) from a free cell to the nearest blocked cell
(``scipy.ndimage.distance_transform_edt``), built once per map outside the timing. Same queries (the ``--longest``
longest of each map), 8-connected with corner cutting (the peers' move set). Solvers, timed interleaved (for each
query, ``--repeat`` rounds of one call per solver; the best call per solver is kept), so load on the shared machine
hits all of them alike (``--clock cpu`` times this thread's CPU time instead of wall time):

* ``mjnav astar``: ``plan_grid(blocked, start, goal, cost=C - 1, corner_cutting=True)``: step a → b of length
  d (1 or √2) costs d·(C[a] + C[b]) / 2 (trapezoid rule). Whole call timed: argument checks, the pass that writes
  and validates the search grid, the search, the path.
* ``skimage MCP``: ``MCP_Geometric(C with +inf on blocked cells)``, the same cost model and move set, so its
  optimal costs are the reference: mjnav's must equal them to 1e-9 (relative) on every query. Timed:
  ``find_costs([start], [goal])`` (it stops once the goal is settled) + ``traceback(goal)``.
* ``pyastar2d``: ``astar_path(weights, start, goal, allow_diagonal=True)`` with ``weights`` = C as float32
  (+inf on blocked cells; it requires weights ≥ 1, which C satisfies). Its cost model is not ours: every move,
  diagonal included, costs the weight of the cell it enters (a diagonal into a cell of weight w costs w, not
  √2·w; checked on a 3×3 grid where the two models choose different paths), with a Chebyshev heuristic. So it
  solves a different shortest-path problem on the same graph (same cells, same moves, same weights), which is
  why it is a speed peer only; its paths, re-costed under our model, are reported as the mean excess over the
  optimum. The wrapper's per-call work (``weights.min()``, ``weights.flatten()``) is part of its time, as it is
  for any user, as our argument checks and grid pass are part of ours.

Goal (issue 17): mjnav astar total time ≤ 0.5 × pyastar2d over all weighted queries, with costs exactly equal to
MCP_Geometric's.

Run: ``.venv/bin/python benchmarks/planning.py`` (``--help`` for options). Timings on a shared machine are noisy;
the best-of-``--repeat`` per query reduces but does not remove that.
"""

from __future__ import annotations

import argparse
import heapq
import json
import math
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjnav.mapping.movingai import MovingAIScenario, read_movingai_map, read_movingai_scen
from mjnav.planning import InvalidPath, check_path, path_cost, plan_grid

SQRT2 = math.sqrt(2.0)
DEFAULT_MAPS = ("maze512-32-9", "random512-40-5", "Boston_0_256")
WEIGHTED_MAPS = ("maze512-32-9", "random512-40-5", "Boston_0_256", "Paris_1_256")
#: Goal of the weighted case: mjnav astar time over pyastar2d time.
WEIGHTED_GOAL = 0.5


def default_refdata() -> Path:
    """$MJNAV_REFDATA or ../shared/refdata beside the repository."""
    env = os.environ.get("MJNAV_REFDATA")
    return Path(env) if env else Path(__file__).resolve().parent.parent.parent / "shared" / "refdata"


def textbook_astar(blocked: NDArray[np.bool_], start: tuple[int, int], goal: tuple[int, int]) -> float:
    """Pure-Python heapq A*: 8-connected, √2 diagonals, no corner cutting, octile heuristic; returns the cost."""
    h, w = blocked.shape
    grid = blocked.tolist()
    gr, gc = goal
    moves = [(-1, 0, 1.0), (1, 0, 1.0), (0, -1, 1.0), (0, 1, 1.0)]
    moves += [(-1, -1, SQRT2), (-1, 1, SQRT2), (1, -1, SQRT2), (1, 1, SQRT2)]

    def heuristic(r: int, c: int) -> float:
        dr, dc = abs(r - gr), abs(c - gc)
        return max(dr, dc) + (SQRT2 - 1.0) * min(dr, dc)

    g: dict[tuple[int, int], float] = {start: 0.0}
    closed: set[tuple[int, int]] = set()
    heap = [(heuristic(*start), start)]
    while heap:
        _, cur = heapq.heappop(heap)
        if cur in closed:
            continue
        if cur == goal:
            return g[cur]
        closed.add(cur)
        r, c = cur
        for dr, dc, step in moves:
            nr, nc = r + dr, c + dc
            if not (0 <= nr < h and 0 <= nc < w) or grid[nr][nc]:
                continue
            if dr and dc and (grid[r + dr][c] or grid[r][c + dc]):
                continue
            ng = g[cur] + step
            if ng < g.get((nr, nc), math.inf):
                g[(nr, nc)] = ng
                heapq.heappush(heap, (ng + heuristic(nr, nc), (nr, nc)))
    return math.inf


def best_time(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    """Best wall time of ``repeat`` calls (seconds) and the last result."""
    best = math.inf
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def corner_cuts(blocked: NDArray[np.bool_], cells: NDArray[np.int64]) -> int:
    """Number of diagonal steps of a path that pass an occupied orthogonal cell."""
    c = np.asarray(cells, dtype=np.int64)
    d = np.diff(c, axis=0)
    diag = np.abs(d).sum(axis=1) == 2
    a = c[:-1][diag]
    dd = d[diag]
    return int(np.count_nonzero(blocked[a[:, 0] + dd[:, 0], a[:, 1]] | blocked[a[:, 0], a[:, 1] + dd[:, 1]]))


def run_map(refdata: Path, name: str, longest: int, repeat: int, python_queries: int, peers: bool) -> dict[str, Any]:
    """Benchmark one map; returns per-solver results."""
    mai = read_movingai_map(refdata / "movingai" / f"{name}.map")
    scen = read_movingai_scen(refdata / "movingai" / f"{name}.map.scen")
    queries: list[MovingAIScenario] = sorted(scen, key=lambda s: -s.optimal_length)[:longest]
    blocked = np.asarray(mai.blocked)
    for alg in ("jps", "astar"):  # warm-up: load/compile the numba kernels
        plan_grid(blocked, queries[-1].start, queries[-1].goal, algorithm=alg)

    solvers: dict[str, Callable[[MovingAIScenario], tuple[float, Any]]] = {}
    for alg in ("jps", "astar"):
        solvers[f"mjnav {alg}"] = lambda q, alg=alg: best_time(
            lambda: plan_grid(blocked, q.start, q.goal, algorithm=alg), repeat
        )
    if peers:
        import pyastar2d
        from skimage.graph import MCP_Geometric

        weights = np.where(blocked, np.inf, 1.0).astype(np.float32)
        for diag in (True, False):
            label = "pyastar2d diag" if diag else "pyastar2d 4-conn"
            solvers[label] = lambda q, diag=diag: best_time(
                lambda: pyastar2d.astar_path(weights, q.start, q.goal, allow_diagonal=diag), repeat
            )
        mcp = MCP_Geometric(np.where(blocked, np.inf, 1.0))

        def run_mcp(q: MovingAIScenario) -> tuple[float, Any]:
            def call() -> Any:
                mcp.find_costs([q.start], [q.goal])
                return np.asarray(mcp.traceback(q.goal))

            return best_time(call, repeat)

        solvers["skimage MCP"] = run_mcp

    out: dict[str, Any] = {"map": name, "shape": list(blocked.shape), "queries": len(queries), "solvers": {}}
    for label, solve in solvers.items():
        times: list[float] = []
        errors: list[float] = []
        cuts = 0
        invalid = 0
        expanded: list[int] = []
        for q in queries:
            t, res = solve(q)
            times.append(t)
            if label.startswith("mjnav"):
                cells = res.cells
                expanded.append(res.expanded)
                if abs(path_cost(cells) - res.cost) > 1e-9 * max(1.0, res.cost):
                    invalid += 1
                cost = res.cost
            else:
                cells = np.asarray(res, dtype=np.int64)
                cost = path_cost(cells)
            try:
                check_path(blocked, cells, start=q.start, goal=q.goal, connectivity=8, corner_cutting=True)
            except InvalidPath:
                invalid += 1
            cuts += corner_cuts(blocked, cells) > 0
            errors.append(cost - q.optimal_length)
        out["solvers"][label] = {
            "times_s": times,
            "total_s": float(np.sum(times)),
            "median_s": float(np.median(times)),
            "max_abs_error": float(np.max(np.abs(errors))),
            "matched_1e-4": int(np.sum(np.abs(errors) <= 1e-4)),
            "paths_cutting_corners": int(cuts),
            "invalid_paths": invalid,
            "median_expanded": float(np.median(expanded)) if expanded else None,
        }
    if python_queries > 0:
        times = []
        errors = []
        for q in queries[:python_queries]:
            t0 = time.perf_counter()
            cost = textbook_astar(blocked, q.start, q.goal)
            times.append(time.perf_counter() - t0)
            errors.append(cost - q.optimal_length)
        jps_times = out["solvers"]["mjnav jps"]["times_s"][:python_queries]
        out["solvers"]["python A*"] = {
            "times_s": times,
            "total_s": float(np.sum(times)),
            "median_s": float(np.median(times)),
            "max_abs_error": float(np.max(np.abs(errors))),
            "matched_1e-4": int(np.sum(np.abs(errors) <= 1e-4)),
            "paths_cutting_corners": 0,
            "invalid_paths": 0,
            "median_expanded": None,
            "jps_total_same_queries_s": float(np.sum(jps_times)),
        }
    return out


def clearance_cost(blocked: NDArray[np.bool_]) -> NDArray[np.float64]:
    """C = 1 + 8·exp(−d/4) on free cells (d: distance to the nearest blocked cell, cells), +inf on blocked ones."""
    from scipy.ndimage import distance_transform_edt

    d = distance_transform_edt(~blocked)
    return np.where(blocked, np.inf, 1.0 + 8.0 * np.exp(-d / 4.0))


def run_weighted_map(
    refdata: Path, name: str, longest: int, repeat: int, clock: Callable[[], float] = time.perf_counter
) -> dict[str, Any]:
    """The weighted case on one map (see the module docstring); returns per-solver results.

    ``clock`` is the timer (seconds): wall time by default, ``time.thread_time`` for the CPU time of this thread
    (all three solvers run in the calling thread), which time slices lost to other processes do not inflate.
    """
    import pyastar2d
    from skimage.graph import MCP_Geometric

    mai = read_movingai_map(refdata / "movingai" / f"{name}.map")
    scen = read_movingai_scen(refdata / "movingai" / f"{name}.map.scen")
    queries: list[MovingAIScenario] = sorted(scen, key=lambda s: -s.optimal_length)[:longest]
    blocked = np.asarray(mai.blocked)
    c = clearance_cost(blocked)
    extra = np.where(blocked, 0.0, c - 1.0)
    weights = c.astype(np.float32)
    mcp = MCP_Geometric(c)
    plan_grid(blocked, queries[-1].start, queries[-1].goal, cost=extra, corner_cutting=True)  # load the kernels

    def mcp_call(q: MovingAIScenario) -> tuple[float, NDArray[np.int64]]:
        costs, _ = mcp.find_costs([q.start], [q.goal])
        return float(costs[q.goal]), np.asarray(mcp.traceback(q.goal), dtype=np.int64)

    solvers: dict[str, Callable[[MovingAIScenario], Any]] = {
        "mjnav astar": lambda q: plan_grid(blocked, q.start, q.goal, cost=extra, corner_cutting=True),
        "pyastar2d": lambda q: pyastar2d.astar_path(weights, q.start, q.goal, allow_diagonal=True),
        "skimage MCP": mcp_call,
    }
    times: dict[str, list[float]] = {label: [] for label in solvers}
    exact = 0
    invalid = 0
    max_rel_err = 0.0
    py_excess: list[float] = []
    expanded: list[int] = []
    for q in queries:
        best = dict.fromkeys(solvers, math.inf)
        out: dict[str, Any] = {}
        for _ in range(repeat):
            for label, solve in solvers.items():
                t0 = clock()
                out[label] = solve(q)
                best[label] = min(best[label], clock() - t0)
        for label, t in best.items():
            times[label].append(t)
        plan = out["mjnav astar"]
        ref_cost, _ = out["skimage MCP"]
        expanded.append(plan.expanded)
        rel = abs(plan.cost - ref_cost) / ref_cost
        max_rel_err = max(max_rel_err, rel)
        exact += rel <= 1e-9
        try:
            check_path(blocked, plan.cells, start=q.start, goal=q.goal, corner_cutting=True)
            if abs(path_cost(plan.cells, extra) - plan.cost) > 1e-9 * plan.cost:
                raise InvalidPath("reported cost differs from the path's cost")
        except InvalidPath:
            invalid += 1
        py_cells = np.asarray(out["pyastar2d"], dtype=np.int64)
        check_path(blocked, py_cells, start=q.start, goal=q.goal, corner_cutting=True)
        py_excess.append(path_cost(py_cells, extra) / ref_cost - 1.0)
    totals = {label: float(np.sum(t)) for label, t in times.items()}
    return {
        "map": name,
        "shape": list(blocked.shape),
        "queries": len(queries),
        "totals_s": totals,
        "times_s": times,
        "exact_vs_mcp": int(exact),
        "max_rel_error_vs_mcp": max_rel_err,
        "invalid_paths": invalid,
        "median_expanded": float(np.median(expanded)),
        "pyastar2d_mean_excess": float(np.mean(py_excess)),
    }


def report_weighted(results: list[dict[str, Any]], repeat: int, clock: str, quick: bool = False) -> None:
    """Print the weighted case: per map and over all maps, with the verdict line for the goal (``quick``: marked
    as a smoke test, not a measurement)."""
    print(f"\nweighted grids (C = 1 + 8·exp(−d/4), corner cutting), interleaved {clock} time, best of {repeat}")
    print(f"  {'map':16s} {'mjnav ms':>9s} {'pyastar2d ms':>12s} {'MCP ms':>8s} {'vs pyastar2d':>12s} {'vs MCP':>7s} "
          f"{'exact':>6s} {'expanded':>9s} {'pyastar2d excess':>16s}")  # fmt: skip
    for r in results:
        t = r["totals_s"]
        print(
            f"  {r['map']:16s} {t['mjnav astar'] * 1e3:9.1f} {t['pyastar2d'] * 1e3:12.1f} "
            f"{t['skimage MCP'] * 1e3:8.1f} "
            f"{t['mjnav astar'] / t['pyastar2d']:11.3g}× {t['mjnav astar'] / t['skimage MCP']:6.3g}× "
            f"{r['exact_vs_mcp']:>2d}/{r['queries']:<3d} {r['median_expanded']:9.0f} "
            f"{100 * r['pyastar2d_mean_excess']:15.2f}%"
        )
    ours = sum(r["totals_s"]["mjnav astar"] for r in results)
    py = sum(r["totals_s"]["pyastar2d"] for r in results)
    mcp = sum(r["totals_s"]["skimage MCP"] for r in results)
    n = sum(r["queries"] for r in results)
    exact = sum(r["exact_vs_mcp"] for r in results)
    invalid = sum(r["invalid_paths"] for r in results)
    ratio = ours / py
    print(f"  {'all maps':16s} {ours * 1e3:9.1f} {py * 1e3:12.1f} {mcp * 1e3:8.1f} {ratio:11.3g}× {ours / mcp:6.3g}× "
          f"{exact:>2d}/{n:<3d}")  # fmt: skip
    met = ratio <= WEIGHTED_GOAL and exact == n and invalid == 0
    print(
        f"goal: mjnav astar <= {WEIGHTED_GOAL} × pyastar2d on weighted grids, costs exact vs MCP_Geometric: "
        f"{'met' if met else 'NOT met'} ({ratio:.3g}×, {exact}/{n} exact, {invalid} invalid paths)"
        + (" [--quick: 3 short queries on one map, not a measurement of the goal]" if quick else "")
    )


def ratios(res: dict[str, Any], ours: str) -> dict[str, float]:
    """Total time of ``ours`` over each peer's total time (same queries)."""
    s = res["solvers"]
    out = {}
    for label, r in s.items():
        if label == ours:
            continue
        if label == "python A*":
            out[label] = r["jps_total_same_queries_s"] / r["total_s"] if ours == "mjnav jps" else math.nan
        else:
            out[label] = s[ours]["total_s"] / r["total_s"]
    return out


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--refdata", type=Path, default=default_refdata(), help="reference data folder")
    parser.add_argument("--maps", nargs="+", default=list(DEFAULT_MAPS), help="map names (without .map)")
    parser.add_argument("--longest", type=int, default=10, help="the N longest queries per map (default 10)")
    parser.add_argument("--repeat", type=int, default=5, help="calls per query; the best is kept (default 5)")
    parser.add_argument(
        "--python-queries", type=int, default=2, help="longest queries for the pure-Python A* (default 2)"
    )
    parser.add_argument("--no-peers", action="store_true", help="skip pyastar2d and scikit-image (uniform case)")
    parser.add_argument(
        "--cases", nargs="+", choices=("uniform", "weighted"), default=["uniform", "weighted"], help="cases to run"
    )
    parser.add_argument(
        "--weighted-maps", nargs="+", default=list(WEIGHTED_MAPS), help="maps of the weighted case (without .map)"
    )
    parser.add_argument(
        "--clock",
        choices=("wall", "cpu"),
        default="wall",
        help="weighted case timer: wall time, or this thread's CPU time (steadier on a loaded machine)",
    )
    parser.add_argument("--json", type=Path, default=None, help="also write the full results here")
    parser.add_argument(
        "--quick", action="store_true", help="short run (make bench): one map, 3 queries, best of 2, no pure Python"
    )
    args = parser.parse_args(argv)
    if args.quick:
        args.maps, args.longest, args.repeat, args.python_queries = ["random512-40-5"], 3, 2, 0
        args.weighted_maps = ["random512-40-5"]
    if not (args.refdata / "movingai").is_dir():
        print(f"reference data not found: {args.refdata / 'movingai'}", file=sys.stderr)
        return 2

    results = []
    for name in args.maps if "uniform" in args.cases else []:
        res = run_map(args.refdata, name, args.longest, args.repeat, args.python_queries, not args.no_peers)
        results.append(res)
        print(f"\n{name} {res['shape'][1]}×{res['shape'][0]}, {res['queries']} longest queries, best of "
              f"{args.repeat}")  # fmt: skip
        print(f"  {'solver':18s} {'total ms':>10s} {'median ms':>10s} {'matched':>8s} {'max |err|':>10s} "
              f"{'cut corners':>11s} {'expanded':>9s}")  # fmt: skip
        for label, r in res["solvers"].items():
            n = len(r["times_s"])
            exp = "" if r["median_expanded"] is None else f"{r['median_expanded']:.0f}"
            print(
                f"  {label:18s} {r['total_s'] * 1e3:10.3f} {r['median_s'] * 1e3:10.3f} "
                f"{r['matched_1e-4']:>3d}/{n:<4d} {r['max_abs_error']:10.3g} {r['paths_cutting_corners']:>11d} "
                f"{exp:>9s}"
            )
        for ours in ("mjnav jps", "mjnav astar"):
            rs = ratios(res, ours)
            print(f"  {ours} time / peer: " + ", ".join(f"{k} {v:.3g}×" for k, v in rs.items()))
    if results and not args.no_peers:
        print("\ngoal: mjnav jps total time <= 0.5 × pyastar2d on the same queries (exact optimal costs required)")
        totals: dict[str, float] = {}
        for res in results:
            s = res["solvers"]
            exact = s["mjnav jps"]["matched_1e-4"] == res["queries"]
            parts = []
            for peer in ("pyastar2d diag", "pyastar2d 4-conn"):
                ratio = s["mjnav jps"]["total_s"] / s[peer]["total_s"]
                parts.append(f"vs {peer} {ratio:.3g}× {'met' if ratio <= 0.5 and exact else 'NOT met'}")
                totals[peer] = totals.get(peer, 0.0) + s[peer]["total_s"]
            totals["jps"] = totals.get("jps", 0.0) + s["mjnav jps"]["total_s"]
            print(f"  {res['map']:16s} costs {'exact' if exact else 'NOT exact'}; " + "; ".join(parts))
        print(
            f"  {'all maps':16s} "
            + "; ".join(f"vs {p} {totals['jps'] / totals[p]:.3g}×" for p in ("pyastar2d diag", "pyastar2d 4-conn"))
        )
    weighted = []
    if "weighted" in args.cases:
        clock = time.perf_counter if args.clock == "wall" else time.thread_time
        weighted = [
            run_weighted_map(args.refdata, name, args.longest, args.repeat, clock) for name in args.weighted_maps
        ]
        report_weighted(weighted, args.repeat, args.clock, args.quick)
    if args.json:
        args.json.write_text(json.dumps({"uniform": results, "weighted": weighted}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Grid path-planning benchmark: mjnav's jps / astar against named peers on the longest Moving AI queries.

Data: Moving AI maps and scenarios from ../shared/refdata/movingai (N. Sturtevant, "Benchmarks for Grid-Based
Pathfinding", IEEE TCIAIG 4(2), 2012; ODC-BY). The optimal lengths are 8-connected, diagonal √2, no corner
cutting.

Solvers (all timed per call, best of ``--repeat`` calls per query, the same queries in the same process):

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
    parser.add_argument("--no-peers", action="store_true", help="skip pyastar2d and scikit-image")
    parser.add_argument("--json", type=Path, default=None, help="also write the full results here")
    parser.add_argument(
        "--quick", action="store_true", help="short run (make bench): one map, 3 queries, best of 2, no pure Python"
    )
    args = parser.parse_args(argv)
    if args.quick:
        args.maps, args.longest, args.repeat, args.python_queries = ["random512-40-5"], 3, 2, 0
    if not (args.refdata / "movingai").is_dir():
        print(f"reference data not found: {args.refdata / 'movingai'}", file=sys.stderr)
        return 2

    results = []
    for name in args.maps:
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
    if not args.no_peers:
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
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

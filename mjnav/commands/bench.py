"""``mjnav bench``: correctness-and-speed checks of the algorithms on public benchmark data.

``mjnav bench movingai MAP.map MAP.map.scen`` plans every scenario (or the first ``--limit``) and compares the
cost with the published optimal length (√2 diagonals, no corner cutting). It also validates every path (unit
moves, free cells, no corner cutting) and recomputes its cost. Exit code 0 when every query matched within the
tolerance with a valid path, 1 otherwise, 2 for unreadable files or bad arguments.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from pathlib import Path
from typing import Any

from mjnav import jsonsafe
from mjnav.commands._args import non_negative_float, positive_int

ALGORITHMS = ("astar", "jps", "dijkstra", "greedy", "bfs", "dfs")


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``bench`` sub-command and its ``movingai`` action."""
    p = subparsers.add_parser(
        "bench",
        help="check algorithms against public benchmark data",
        description="Correctness and speed of the algorithms on public benchmark data.",
    )
    sub = p.add_subparsers(dest="bench_command", metavar="BENCHMARK")

    def usage(_args: argparse.Namespace) -> int:
        p.print_help()
        return 2

    p.set_defaults(func=usage)

    m = sub.add_parser(
        "movingai",
        help="grid path finding on a Moving AI map and scenario file",
        description=(
            "Plan the scenarios of a Moving AI .scen file on its .map (N. Sturtevant, 'Benchmarks for "
            "Grid-Based Pathfinding', 2012) and compare with the published optimal lengths (8-connected, "
            "diagonal √2, no corner cutting). Prints the number of queries, how many matched within the "
            "tolerance, the maximum absolute error, invalid paths and the median time per query (one warm-up "
            "query first, so numba compilation is not timed; times include all per-query set-up)."
        ),
    )
    m.add_argument("map", type=Path, help="the .map file")
    m.add_argument("scen", type=Path, help="the .scen file")
    m.add_argument(
        "--algorithm",
        choices=ALGORITHMS,
        default="astar",
        help="algorithm (default astar; only astar, jps and dijkstra are optimal)",
    )
    m.add_argument("--limit", type=positive_int, default=None, help="only the first N scenarios")
    m.add_argument(
        "--tolerance", type=non_negative_float, default=1e-4, help="absolute match tolerance, cells (default 1e-4)"
    )
    m.add_argument("--json", action="store_true", help="print one JSON object")
    m.set_defaults(func=run_movingai)


def run_movingai(args: argparse.Namespace) -> int:
    """Run the Moving AI benchmark; returns the exit code."""
    import numpy as np

    from mjnav.mapping.movingai import read_movingai_map, read_movingai_scen
    from mjnav.planning import InvalidPath, PlanningError, check_path, path_cost, plan_grid

    try:
        mai = read_movingai_map(args.map)
        scenarios = read_movingai_scen(args.scen)
    except (OSError, ValueError) as exc:
        print(f"mjnav bench movingai: error: {exc}", file=sys.stderr)
        return 2
    if args.limit is not None:
        scenarios = scenarios[: args.limit]
    if not scenarios:
        print("mjnav bench movingai: error: no scenarios", file=sys.stderr)
        return 2
    blocked = np.asarray(mai.blocked)
    for sc in scenarios:
        if (sc.height, sc.width) != blocked.shape:
            print(
                f"mjnav bench movingai: error: scenario for a {sc.width}×{sc.height} map, but {mai.name} is "
                f"{blocked.shape[1]}×{blocked.shape[0]}",
                file=sys.stderr,
            )
            return 2

    warm = scenarios[0]
    with contextlib.suppress(PlanningError):
        plan_grid(blocked, warm.start, warm.goal, algorithm=args.algorithm)

    times: list[float] = []
    errors: list[float] = []
    matched = 0
    invalid = 0
    failed = 0
    worst: dict[str, Any] | None = None
    for i, sc in enumerate(scenarios):
        t0 = time.perf_counter()
        try:
            plan = plan_grid(blocked, sc.start, sc.goal, algorithm=args.algorithm)
        except PlanningError as exc:
            times.append(time.perf_counter() - t0)
            failed += 1
            errors.append(float("inf"))
            if worst is None or worst["error"] != float("inf"):
                worst = {"index": i, "error": float("inf"), "reason": f"{type(exc).__name__}: {exc}"}
            continue
        times.append(time.perf_counter() - t0)
        err = abs(plan.cost - sc.optimal_length)
        errors.append(err)
        try:
            check_path(blocked, plan.cells, start=sc.start, goal=sc.goal)
            if abs(path_cost(plan.cells) - plan.cost) > 1e-9 * max(1.0, plan.cost):
                raise InvalidPath(f"recomputed cost {path_cost(plan.cells)} != reported {plan.cost}")
        except InvalidPath as exc:
            invalid += 1
            worst = {"index": i, "error": err, "reason": f"invalid path: {exc}"}
            continue
        if err <= args.tolerance:
            matched += 1
        elif worst is None or err > worst["error"]:
            worst = {"index": i, "error": err, "reason": f"cost {plan.cost} vs optimal {sc.optimal_length}"}

    t = np.asarray(times)
    result = {
        "map": mai.name,
        "scen": args.scen.name,
        "algorithm": args.algorithm,
        "queries": len(scenarios),
        "matched": matched,
        "tolerance": args.tolerance,
        "max_error": float(max(errors)),
        "invalid_paths": invalid,
        "failed": failed,
        "median_time_s": float(np.median(t)),
        "max_time_s": float(t.max()),
        "total_time_s": float(t.sum()),
        "worst": worst,
    }
    ok = matched == len(scenarios)
    if args.json:
        print(jsonsafe.dumps(result))
    else:
        print(f"map:            {mai.name} ({blocked.shape[1]}×{blocked.shape[0]}), {args.scen.name}")
        print(f"algorithm:      {args.algorithm}")
        print(f"queries:        {len(scenarios)}")
        print(f"matched:        {matched} within {args.tolerance:g}")
        print(f"max error:      {result['max_error']:.3g}")
        print(f"invalid paths:  {invalid}   failed: {failed}")
        print(
            f"time per query: median {result['median_time_s'] * 1e3:.3f} ms, "
            f"max {result['max_time_s'] * 1e3:.3f} ms, total {result['total_time_s']:.3f} s"
        )
        if not ok and worst is not None:
            print(f"worst:          scenario {worst['index']}: {worst['reason']}")
    return 0 if ok else 1

"""``mjnav plan``: plan a grid path on a map file with :func:`mjnav.planning.plan_grid`.

Exit codes: 0 path found; 1 planning failure (no path, start/goal occupied or outside the map, stuck potential
field); 2 bad arguments or an unreadable map file.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mjnav import jsonsafe

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from mjnav.mapping.frame import GridFrame

ALGORITHMS = ("astar", "jps", "dijkstra", "greedy", "bfs", "dfs", "potential_field")
HEURISTICS = ("octile", "euclidean", "chebyshev", "manhattan")


def parse_point(text: str) -> tuple[float, float]:
    """``X,Y`` → (x, y) floats (finite)."""
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        x, y = float(parts[0]), float(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y (two numbers), got {text!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise argparse.ArgumentTypeError(f"X,Y must be finite, got {text!r}")
    return x, y


def parse_weights(text: str) -> tuple[float, float]:
    """``A,B`` → (α, β), finite and >= 0."""
    a, b = parse_point(text)
    if a < 0 or b < 0 or (a == 0 and b == 0):
        raise argparse.ArgumentTypeError(f"weights must be >= 0 and not both 0, got {text!r}")
    return a, b


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``plan`` sub-command."""
    p = subparsers.add_parser(
        "plan",
        help="plan a grid path on a Moving AI .map or ROS .yaml map",
        description=(
            "Plan a path on an occupancy grid read from a file and print its cost and cells. "
            "Coordinates: for a Moving AI .map, X,Y are the integer column and row of a cell (0-based, row 0 "
            "is the first map line; the convention of the .scen files). For a ROS map (.yaml + image), X,Y "
            "are metres in the map frame; the planner uses the cell containing the point and reports the path "
            "as cell centres in metres. Costs are in cells (orthogonal step 1, diagonal √2); ROS maps also "
            "give metres."
        ),
        epilog=(
            "Examples: mjnav plan --map arena.map --start 1,3 --goal 40,20 --algorithm jps; "
            "mjnav plan --map office.yaml --start 0.5,1.2 --goal 7.0,3.5 --json"
        ),
    )
    p.add_argument("--map", required=True, type=Path, help="map file: Moving AI .map or ROS .yaml")
    p.add_argument("--start", required=True, type=parse_point, metavar="X,Y", help="start (see above)")
    p.add_argument("--goal", required=True, type=parse_point, metavar="X,Y", help="goal (see above)")
    p.add_argument(
        "--algorithm",
        choices=ALGORITHMS,
        default="astar",
        help="search algorithm (default astar; jps is the fast exact one for 8-connected maps)",
    )
    p.add_argument("--heuristic", choices=HEURISTICS, default="octile", help="A*/greedy/jps heuristic")
    p.add_argument("--connectivity", type=int, choices=(4, 8), default=8, help="neighbourhood (default 8)")
    p.add_argument(
        "--weights",
        type=parse_weights,
        default=(1.0, 1.0),
        metavar="A,B",
        help="A* priority f = A·g + B·h (default 1,1 = optimal)",
    )
    p.add_argument(
        "--corner-cutting",
        action="store_true",
        help="allow diagonal steps past occupied orthogonal cells (default: not allowed)",
    )
    p.add_argument(
        "--unknown-occupied",
        action="store_true",
        help="ROS maps: treat unknown cells as occupied (default: only occupied cells block)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the potential-field escapes (default 0)")
    p.add_argument("--json", action="store_true", help="print one JSON object (with the full path)")
    p.set_defaults(func=run)


def _fail(code: int, message: str) -> int:
    print(f"mjnav plan: error: {message}", file=sys.stderr)
    return code


def run(args: argparse.Namespace) -> int:
    """Load the map, plan, print the result; returns the exit code."""
    import numpy as np

    from mjnav.planning import PlanningError, plan_grid
    from mjnav.planning.errors import InvalidInput

    path: Path = args.map
    suffix = path.suffix.lower()
    frame: _Frame
    try:
        if suffix == ".map":
            from mjnav.mapping.movingai import read_movingai_map

            mai = read_movingai_map(path)
            occupied = np.asarray(mai.blocked)
            frame = _Frame("moving-ai", occupied.shape)
        elif suffix in (".yaml", ".yml"):
            from mjnav.mapping import GridFrame, read_ros_map

            ros = read_ros_map(path)
            occupied = np.asarray(ros.occupied_mask(unknown_is_occupied=args.unknown_occupied), dtype=bool)
            ox, oy, yaw = (float(v) for v in ros.origin_m)
            frame = _Frame("ros", occupied.shape, GridFrame(float(ros.resolution_m), (ox, oy), occupied.shape, yaw))
        else:
            return _fail(2, f"{path}: unknown map type {suffix!r}; use a Moving AI .map or a ROS .yaml")
    except (OSError, ValueError) as exc:
        return _fail(2, f"cannot read map {path}: {exc}")

    try:
        start = frame.to_cell(args.start, "start")
        goal = frame.to_cell(args.goal, "goal")
    except ValueError as exc:
        return _fail(2, str(exc))

    # Load the compiled kernels (numba cache) on a tiny map so the reported time is the planning only.
    with contextlib.suppress(PlanningError):
        plan_grid(
            np.zeros((2, 2), bool),
            (0, 0),
            (1, 1),
            algorithm=args.algorithm,
            connectivity=args.connectivity,
            rng=np.random.default_rng(0),
        )
    t0 = time.perf_counter()
    try:
        plan = plan_grid(
            occupied,
            start,
            goal,
            algorithm=args.algorithm,
            heuristic=args.heuristic,
            connectivity=args.connectivity,
            weights=args.weights,
            corner_cutting=args.corner_cutting,
            rng=np.random.default_rng(args.seed),
        )
    except InvalidInput as exc:
        return _fail(2, str(exc))
    except PlanningError as exc:
        return _fail(1, f"{type(exc).__name__}: {exc}")
    elapsed = time.perf_counter() - t0

    points = frame.to_points(plan.cells)
    result: dict[str, Any] = {
        "map": str(path),
        "map_type": frame.kind,
        "size_cells": [int(occupied.shape[1]), int(occupied.shape[0])],
        "coordinates": frame.coordinates,
        "algorithm": plan.algorithm,
        "heuristic": args.heuristic,
        "connectivity": args.connectivity,
        "weights": list(args.weights),
        "corner_cutting": bool(args.corner_cutting),
        "start": list(args.start) if frame.kind == "ros" else [start[1], start[0]],
        "goal": list(args.goal) if frame.kind == "ros" else [goal[1], goal[0]],
        "cost_cells": plan.cost,
        "cost_m": plan.cost * frame.resolution_m if frame.kind == "ros" else None,
        "expanded": plan.expanded,
        "num_cells": int(plan.cells.shape[0]),
        "time_s": elapsed,
        "path": points,
    }
    if args.json:
        print(jsonsafe.dumps(result))
        return 0
    print(f"map:        {path} ({frame.kind}, {occupied.shape[1]}×{occupied.shape[0]} cells)")
    print(
        f"algorithm:  {plan.algorithm} (heuristic {args.heuristic}, {args.connectivity}-connected, "
        f"weights {args.weights[0]:g},{args.weights[1]:g}, "
        f"{'corner cutting' if args.corner_cutting else 'no corner cutting'})"
    )
    cost = f"{plan.cost:.6f} cells"
    if result["cost_m"] is not None:
        cost += f" = {result['cost_m']:.4f} m"
    print(f"cost:       {cost}")
    print(f"path:       {plan.cells.shape[0]} cells, {plan.expanded} expanded, {elapsed * 1e3:.2f} ms")
    print(f"points ({frame.coordinates}):")
    print(" ".join(_fmt(pt) for pt in points))
    return 0


def _fmt(pt: list[float] | list[int]) -> str:
    return f"{pt[0]},{pt[1]}" if isinstance(pt[0], int) else f"{pt[0]:.4f},{pt[1]:.4f}"


class _Frame:
    """Conversion between user coordinates X,Y and grid cells (row, col) for one map: integer column,row on a
    Moving AI map, metres in the map frame (through the map's :class:`~mjnav.mapping.GridFrame`) on a ROS map."""

    def __init__(self, kind: str, shape: tuple[int, ...], grid: GridFrame | None = None) -> None:
        self.kind = kind
        self.shape = (int(shape[0]), int(shape[1]))
        self.grid = grid
        self.resolution_m = grid.resolution_m if grid is not None else 1.0

    @property
    def coordinates(self) -> str:
        return "x=col,y=row (cells)" if self.kind == "moving-ai" else "x,y metres, map frame (cell centres)"

    def to_cell(self, point: tuple[float, float], what: str) -> tuple[int, int]:
        """(row, col) of a user point; raises ValueError for a non-integer Moving AI coordinate."""
        x, y = point
        if self.kind == "moving-ai":
            if x != int(x) or y != int(y):
                raise ValueError(f"{what} must be integer column,row on a Moving AI map; got {x:g},{y:g}")
            return int(y), int(x)
        assert self.grid is not None
        return self.grid.world_to_cell(x, y)

    def to_points(self, cells: NDArray[np.int64]) -> list[list[Any]]:
        """User coordinates of (N, 2) (row, col) cells: [x, y] ints (Moving AI) or metres (ROS centres)."""
        if self.kind == "moving-ai":
            return [[int(col), int(row)] for row, col in cells]
        assert self.grid is not None
        return [[float(x), float(y)] for x, y in self.grid.cells_to_world(cells)]

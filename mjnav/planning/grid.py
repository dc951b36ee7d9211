"""Graph search on occupancy grids: DFS, BFS, greedy best-first, Dijkstra, A*, jump point search.

Grid model (shared by every algorithm here and by :func:`path_cost` / :func:`check_path`):

* ``occupied``: (H, W) bool array (integer arrays are accepted, non-zero = occupied); cells are (row, col).
* Moves: 4-connected (N, S, W, E; length 1) or 8-connected (plus diagonals; length √2). Without corner cutting
  (the default, and the Moving AI benchmark rule) a diagonal step is illegal when either orthogonal cell it
  passes is occupied; with ``corner_cutting=True`` only its target cell must be free.
* Step cost: its length d (cells), or with a ``cost`` grid d·(1 + (cost[a] + cost[b]) / 2) — the extra cost
  is a per-cell traversal penalty per unit length, integrated along the step by the trapezoid rule. ``cost``
  is (H, W) float, ≥ 0; +inf marks a cell impassable. With a cost grid, ``greedy``, ``dijkstra`` and ``astar``
  run :mod:`mjnav.planning._weighted` and the heuristic is scaled by 1 + min(cost) over the free cells (every
  step costs at least that per unit length, so it stays admissible and consistent); for ``astar`` with α = β
  and ``dijkstra`` ``expanded`` counts a node again when a better path reaches it after its expansion.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mjnav.planning import _kernels as kern
from mjnav.planning import _weighted as weighted
from mjnav.planning._workspace import get_workspace
from mjnav.planning.errors import (
    GoalOccupied,
    GoalOutsideMap,
    InvalidInput,
    InvalidPath,
    NoPathFound,
    StartOccupied,
    StartOutsideMap,
)
from mjnav.planning.heuristics import HEURISTIC_CODES, heuristic_code
from mjnav.planning.jps import grid_layout, jump_point_search, prepare_grid, trace_jump_path

if TYPE_CHECKING:
    from mjnav.planning.potential_field import PotentialFieldParams

SQRT2 = math.sqrt(2.0)

Algorithm = Literal["dfs", "bfs", "greedy", "dijkstra", "astar", "jps", "potential_field"]

#: Every algorithm name :func:`plan_grid` accepts.
ALGORITHMS: tuple[str, ...] = ("dfs", "bfs", "greedy", "dijkstra", "astar", "jps", "potential_field")


@dataclass(frozen=True, slots=True)
class GridPlan:
    """A planned grid path.

    Attributes:
        cells: (N, 2) int64 array of (row, col) cells from start to goal inclusive; N ≥ 1.
        cost: path cost, cells (orthogonal step 1, diagonal √2; scaled by the cost grid if one was given).
        expanded: nodes the search expanded (closed); for ``jps`` the jump points expanded, for
            ``potential_field`` the descent and escape steps taken.
        algorithm: the algorithm that produced the path.
    """

    cells: NDArray[np.int64]
    cost: float
    expanded: int
    algorithm: str


# ---------------------------------------------------------------------------------------------------------------
# Input validation


def as_occupancy(occupied: ArrayLike) -> NDArray[np.bool_]:
    """Validate an occupancy grid and return it as a (H, W) bool array.

    Args:
        occupied: (H, W) bool, or integer (non-zero = occupied).

    Returns:
        The grid as bool (the input itself when it already is a bool array).

    Raises:
        InvalidInput: not 2-D, empty, or of a dtype other than bool/integer (for example float: threshold
            occupancy probabilities first).
    """
    arr = np.asarray(occupied)
    if arr.ndim != 2:
        raise InvalidInput(f"occupied must be a 2-D (H, W) array; got shape {arr.shape}")
    if arr.size == 0:
        raise InvalidInput(f"occupied is empty (shape {arr.shape})")
    if arr.dtype == np.bool_:
        return arr
    if np.issubdtype(arr.dtype, np.integer):
        return arr != 0
    raise InvalidInput(f"occupied must be a bool (or integer) array; got dtype {arr.dtype}")


def as_cell(value: object, what: str) -> tuple[int, int]:
    """Validate a (row, col) cell: two integers (integral floats are accepted); raises InvalidInput."""
    try:
        seq = list(value)  # type: ignore[call-overload]
    except TypeError:
        raise InvalidInput(f"{what} must be a (row, col) pair; got {value!r}") from None
    if len(seq) != 2:
        raise InvalidInput(f"{what} must be a (row, col) pair; got {value!r}")
    out: list[int] = []
    for v in seq:
        if isinstance(v, bool | np.bool_):
            raise InvalidInput(f"{what} must hold integers; got {value!r}")
        if isinstance(v, int | np.integer):
            out.append(int(v))
            continue
        if isinstance(v, float | np.floating):
            if not math.isfinite(v) or v != int(v):
                raise InvalidInput(f"{what} must hold finite integer cell indices; got {value!r}")
            out.append(int(v))
            continue
        raise InvalidInput(f"{what} must hold integers; got {value!r}")
    return out[0], out[1]


def as_cost(cost: ArrayLike | None, shape: tuple[int, int]) -> NDArray[np.float64] | None:
    """Validate an optional (H, W) traversal-cost grid (finite ≥ 0 or +inf); raises InvalidInput."""
    if cost is None:
        return None
    arr = _cost_array(cost, shape)
    if np.isnan(arr).any():
        raise InvalidInput(_COST_NAN)
    if (arr < 0).any():
        raise InvalidInput(_COST_NEGATIVE)
    return arr


_COST_NAN = "cost contains NaN"
_COST_NEGATIVE = "cost must be >= 0 (use +inf for impassable cells)"


def _cost_array(cost: ArrayLike, shape: tuple[int, int]) -> NDArray[np.float64]:
    """``cost`` as float64 after the shape and dtype checks of :func:`as_cost` (values not checked)."""
    arr = np.asarray(cost)
    if arr.shape != shape:
        raise InvalidInput(f"cost must have the map shape {shape}; got {arr.shape}")
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise InvalidInput(f"cost must be a real array; got dtype {arr.dtype}")
    return arr.astype(np.float64, copy=False)


def check_endpoints(blocked: NDArray[np.bool_], start: tuple[int, int], goal: tuple[int, int]) -> None:
    """Raise the typed error when ``start``/``goal`` (row, col) lie outside ``blocked`` (H, W) or on a blocked cell."""
    shape = (int(blocked.shape[0]), int(blocked.shape[1]))
    if not (0 <= start[0] < shape[0] and 0 <= start[1] < shape[1]):
        raise StartOutsideMap(start, shape)
    if not (0 <= goal[0] < shape[0] and 0 <= goal[1] < shape[1]):
        raise GoalOutsideMap(goal, shape)
    if blocked[start]:
        raise StartOccupied(start)
    if blocked[goal]:
        raise GoalOccupied(goal)


def _as_weights(weights: Sequence[float]) -> tuple[float, float]:
    try:
        a, b = (float(w) for w in weights)
    except (TypeError, ValueError):
        raise InvalidInput(f"weights must be two numbers (alpha, beta); got {weights!r}") from None
    if not (math.isfinite(a) and math.isfinite(b)) or a < 0 or b < 0 or (a == 0 and b == 0):
        raise InvalidInput(f"weights must be finite, >= 0 and not both zero; got {weights!r}")
    return a, b


def pad_blocked(mask: NDArray[np.bool_]) -> NDArray[np.uint8]:
    """(H + 2, W + 2) uint8 copy of ``mask`` with a blocked one-cell border."""
    out = np.empty((mask.shape[0] + 2, mask.shape[1] + 2), np.uint8)
    pad_into(mask, out)
    return out


def pad_into(mask: NDArray[np.bool_], out: NDArray[np.uint8]) -> None:
    """Write ``mask`` (H, W) into the (H + 2, W + 2) ``out`` with a blocked one-cell border."""
    out[0, :] = 1
    out[-1, :] = 1
    out[:, 0] = 1
    out[:, -1] = 1
    out[1:-1, 1:-1] = mask


# ---------------------------------------------------------------------------------------------------------------
# Planning


def plan_grid(
    occupied: ArrayLike,
    start: Sequence[int] | ArrayLike,
    goal: Sequence[int] | ArrayLike,
    *,
    algorithm: Algorithm | str = "astar",
    heuristic: str = "octile",
    connectivity: int = 8,
    weights: Sequence[float] = (1.0, 1.0),
    corner_cutting: bool = False,
    cost: ArrayLike | None = None,
    rng: np.random.Generator | None = None,
    potential: PotentialFieldParams | None = None,
) -> GridPlan:
    """Plan a path on an occupancy grid.

    Algorithms:

    * ``dfs``: depth-first search; complete, not optimal.
    * ``bfs``: breadth-first search; fewest steps (optimal on 4-connected grids without a cost grid).
    * ``greedy``: greedy best-first on h; complete, not optimal.
    * ``dijkstra``: uniform-cost search; optimal.
    * ``astar``: priority f = α·g + β·h with (α, β) = ``weights``; optimal for α = β with an admissible h,
      tends to greedy for β ≫ α.
    * ``jps``: jump point search — A* with the same f over jump points; exactly optimal and much faster on
      uniform grids. Needs ``connectivity=8``, ``corner_cutting=False`` and no ``cost`` grid.
    * ``potential_field``: steepest descent on an attractive + repulsive potential with seeded escapes from
      local minima (:func:`mjnav.planning.potential_field.plan_potential_field`); needs ``rng``; ignores
      ``heuristic``, ``weights`` and ``cost``.

    Args:
        occupied: (H, W) bool occupancy (integer accepted, non-zero = occupied).
        start: (row, col) start cell.
        goal: (row, col) goal cell.
        algorithm: one of :data:`ALGORITHMS`.
        heuristic: ``manhattan``, ``euclidean``, ``chebyshev`` or ``octile`` (see
            :mod:`mjnav.planning.heuristics`); used by ``greedy``, ``astar`` and ``jps``.
        connectivity: 4 or 8.
        weights: (α, β) ≥ 0, not both 0, for ``astar``/``jps``: f = α·g + β·h.
        corner_cutting: allow diagonal steps past occupied orthogonal cells.
        cost: optional (H, W) extra traversal cost ≥ 0 per unit length (+inf = impassable), see module doc.
        rng: random generator for ``potential_field`` escapes (default: ``numpy.random.default_rng(0)``, so
            runs repeat exactly).
        potential: parameters for ``potential_field`` (defaults when ``None``).

    Returns:
        The :class:`GridPlan`; for start == goal a single-cell path of cost 0.

    Raises:
        InvalidInput: malformed map, cell, weights, cost grid or option.
        StartOutsideMap, GoalOutsideMap: a cell is outside the map (both are :class:`OutsideMap`).
        StartOccupied, GoalOccupied: a cell is occupied or has infinite cost.
        NoPathFound: the goal is unreachable (or the potential field got stuck: ``LocalMinimum``).
    """
    grid = as_occupancy(occupied)
    shape = (int(grid.shape[0]), int(grid.shape[1]))
    s = as_cell(start, "start")
    t = as_cell(goal, "goal")
    if algorithm not in ALGORITHMS:
        raise InvalidInput(f"unknown algorithm {algorithm!r}; choose one of {list(ALGORITHMS)}")
    if connectivity not in (4, 8):
        raise InvalidInput(f"connectivity must be 4 or 8; got {connectivity!r}")
    hcode = heuristic_code(heuristic)
    alpha, beta = _as_weights(weights)
    if cost is not None and algorithm in ("astar", "dijkstra", "greedy"):
        if algorithm == "dijkstra":
            alpha, beta = 1.0, 0.0
        elif algorithm == "greedy":
            alpha, beta = 0.0, 1.0
        cost_grid = _cost_array(cost, shape)
        return _plan_weighted(grid, cost_grid, s, t, str(algorithm), connectivity, corner_cutting, alpha, beta, hcode)
    cost_arr = as_cost(cost, shape)
    blocked_mask = grid if cost_arr is None else (grid | np.isinf(cost_arr))
    check_endpoints(blocked_mask, s, t)

    if algorithm == "potential_field":
        from mjnav.planning.potential_field import plan_potential_field

        return plan_potential_field(
            blocked_mask,
            s,
            t,
            rng=np.random.default_rng(0) if rng is None else rng,
            params=potential,
            connectivity=connectivity,
            corner_cutting=corner_cutting,
        )
    if algorithm == "jps" and (connectivity != 8 or corner_cutting or cost_arr is not None):
        raise InvalidInput("algorithm 'jps' needs connectivity=8, corner_cutting=False and no cost grid")

    if s == t:
        return GridPlan(np.array([s], dtype=np.int64), 0.0, 0, str(algorithm))

    if algorithm == "jps":
        return _plan_jps(blocked_mask, s, t, alpha, beta, hcode)

    h, w = shape
    width = w + 2
    n_nodes = (h + 2) * width
    if n_nodes >= 2**31:
        raise InvalidInput(f"map of {h}×{w} cells is too large (node ids are int32)")
    ws = get_workspace(n_nodes)
    flat = ws.blocked[:n_nodes]
    pad_into(blocked_mask, flat.reshape(h + 2, width))
    sn = (s[0] + 1) * width + s[1] + 1
    tn = (t[0] + 1) * width + t[1] + 1
    n_moves = connectivity

    if algorithm in ("bfs", "dfs"):
        while True:
            if algorithm == "bfs":
                expanded, status = kern.breadth_first(
                    flat, width, sn, tn, n_moves, corner_cutting, ws.nodes, ws.begin(), ws.queue
                )
            else:
                expanded, status = kern.depth_first(
                    flat, width, sn, tn, n_moves, corner_cutting, ws.nodes, ws.begin(), ws.items
                )
            if status != kern.OVERFLOW:
                break
            ws.grow_heap()
        if status != kern.FOUND:
            raise NoPathFound(f"no path from {s} to {t} ({algorithm} expanded {expanded} nodes)")
        cells = kern.trace_path(ws.nodes, width, sn, tn)
        return GridPlan(cells, path_cost(cells, cost_arr), int(expanded), str(algorithm))

    if algorithm == "dijkstra":
        alpha, beta = 1.0, 0.0
    elif algorithm == "greedy":
        alpha, beta = 0.0, 1.0
    while True:
        g_goal, expanded, status = kern.best_first(
            flat, width, sn, tn, n_moves, corner_cutting, alpha, beta, hcode,
            ws.nodes, ws.begin(), ws.keys, ws.subs, ws.items,
        )  # fmt: skip
        if status != kern.OVERFLOW:
            break
        ws.grow_heap()
    if status != kern.FOUND:
        raise NoPathFound(f"no path from {s} to {t} ({algorithm} expanded {expanded} nodes)")
    cells = kern.trace_path(ws.nodes, width, sn, tn)
    return GridPlan(cells, float(g_goal), int(expanded), str(algorithm))


def _plan_jps(
    mask: NDArray[np.bool_], s: tuple[int, int], t: tuple[int, int], alpha: float, beta: float, hcode: int
) -> GridPlan:
    """Jump point search (:mod:`mjnav.planning.jps`) from ``s`` to ``t`` (distinct free cells of ``mask``)."""
    h, w = mask.shape
    stride, words, twords = grid_layout(h, w)
    n_nodes = (h + 2) * stride
    if n_nodes >= 2**31:
        raise InvalidInput(f"map of {h}×{w} cells is too large (node ids are int32)")
    ws = get_workspace(n_nodes)
    flat = ws.blocked[:n_nodes]
    bits, tbits = ws.bit_grids((h + 2) * words, stride * twords)
    prepare_grid(np.ascontiguousarray(mask), flat.reshape(h + 2, stride), bits, tbits)
    sn = (s[0] + 1) * stride + s[1] + 1
    tn = (t[0] + 1) * stride + t[1] + 1
    while True:
        g_goal, expanded, status = jump_point_search(
            flat, bits, words, tbits, twords, stride, sn, tn, alpha, beta, hcode,
            ws.nodes, ws.begin(), ws.keys, ws.items,
        )  # fmt: skip
        if status != kern.OVERFLOW:
            break
        ws.grow_heap()
    if status != kern.FOUND:
        raise NoPathFound(f"no path from {s} to {t} (jps expanded {expanded} jump points)")
    return GridPlan(trace_jump_path(ws.nodes, stride, sn, tn), float(g_goal), int(expanded), "jps")


def _plan_weighted(
    grid: NDArray[np.bool_],
    cost: NDArray[np.float64],
    s: tuple[int, int],
    t: tuple[int, int],
    algorithm: str,
    connectivity: int,
    corner_cutting: bool,
    alpha: float,
    beta: float,
    hcode: int,
) -> GridPlan:
    """A*, Dijkstra or greedy with a cost grid (:mod:`mjnav.planning._weighted`); checks the cost values and cells.

    Args:
        grid: (H, W) bool occupancy.
        cost: (H, W) float64 extra cost per unit length (shape and dtype already checked).
        s: start (row, col).
        t: goal (row, col).
        algorithm: the name reported in the plan.
        connectivity: 4 or 8.
        corner_cutting: allow diagonal steps past occupied orthogonal cells.
        alpha: weight of g.
        beta: weight of h.
        hcode: heuristic code.
    """
    h, w = int(grid.shape[0]), int(grid.shape[1])
    width = w + 2
    n_nodes = (h + 2) * width
    if n_nodes >= 2**31:
        raise InvalidInput(f"map of {h}×{w} cells is too large (node ids are int32)")
    ws = get_workspace(n_nodes)
    rec, pos = ws.cost_grids(n_nodes)
    grid = np.ascontiguousarray(grid)
    cost = np.ascontiguousarray(cost)
    verdict, lowest, highest = weighted.prepare_costs(grid, cost, rec)
    if verdict == weighted.COSTS_NAN:
        raise InvalidInput(_COST_NAN)
    if verdict == weighted.COSTS_NEGATIVE:
        raise InvalidInput(_COST_NEGATIVE)
    if not (0 <= s[0] < h and 0 <= s[1] < w):
        raise StartOutsideMap(s, (h, w))
    if not (0 <= t[0] < h and 0 <= t[1] < w):
        raise GoalOutsideMap(t, (h, w))
    sn = (s[0] + 1) * width + s[1] + 1
    tn = (t[0] + 1) * width + t[1] + 1
    if rec[2 * sn] == -np.inf:  # occupied or of infinite cost
        raise StartOccupied(s)
    if rec[2 * tn] == -np.inf:
        raise GoalOccupied(t)
    if s == t:
        return GridPlan(np.array([s], dtype=np.int64), 0.0, 0, algorithm)
    hscale = 1.0 + lowest
    # Optimal modes with a consistent heuristic run the bucket search; the others (weighted A*, greedy, Manhattan
    # on 8-connected moves) the heap search, whose expansion order defines them. Keys run at most a step's cost
    # plus the heuristic's change ahead of the current bucket: the bucket array must cover that.
    hweight = 0.0 if beta == 0.0 else (hscale if alpha == beta else -1.0)
    consistent = beta == 0.0 or hcode != HEURISTIC_CODES["manhattan"] or connectivity == 4
    delta = weighted.BUCKET_WIDTH * hscale
    reach = SQRT2 * (1.0 + highest + max(hweight, 0.0))
    use_buckets = hweight >= 0.0 and consistent and reach < 0.9 * weighted.N_BUCKETS * delta
    while True:
        if use_buckets:
            g_goal, expanded, status = weighted.bucket_search(
                rec, width, sn, tn, connectivity, corner_cutting, hweight, hcode, delta,
                ws.items, ws.links, ws.heads,
            )  # fmt: skip
        else:
            g_goal, expanded, status = weighted.weighted_search(
                rec, width, sn, tn, connectivity, corner_cutting, alpha, beta, hcode, hscale,
                pos, ws.keys, ws.items,
            )  # fmt: skip
        if status == weighted.OUT_OF_WINDOW:
            use_buckets = False
        elif status == kern.OVERFLOW:
            ws.grow_heap()
        else:
            break
        weighted.prepare_costs(grid, cost, rec)
    if status != kern.FOUND:
        raise NoPathFound(f"no path from {s} to {t} ({algorithm} expanded {expanded} nodes)")
    cells = weighted.trace_back(rec, width, sn, tn, connectivity, corner_cutting)
    return GridPlan(cells, float(g_goal), int(expanded), algorithm)


# ---------------------------------------------------------------------------------------------------------------
# Path checks


def path_cost(cells: ArrayLike, cost: ArrayLike | None = None) -> float:
    """Cost of a grid path under the step-cost model of this module.

    Args:
        cells: (N, 2) (row, col) cells; consecutive cells must be 8-neighbours (not checked here, see
            :func:`check_path`).
        cost: optional (H, W) extra traversal cost grid.

    Returns:
        Σ d·(1 + (cost[a] + cost[b]) / 2) over the steps (d = 1 or √2), cells; 0 for a single cell.
    """
    c = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    if c.shape[0] < 2:
        return 0.0
    d = np.abs(np.diff(c, axis=0)).sum(axis=1)
    if cost is None:
        n_diag = int(np.count_nonzero(d == 2))
        return float(c.shape[0] - 1 - n_diag) + n_diag * SQRT2
    cg = np.asarray(cost, dtype=np.float64)
    lengths = np.where(d == 2, SQRT2, 1.0)
    cv = cg[c[:, 0], c[:, 1]]
    return float(np.sum(lengths * (1.0 + 0.5 * (cv[:-1] + cv[1:]))))


def check_path(
    occupied: ArrayLike,
    cells: ArrayLike,
    *,
    start: Sequence[int] | None = None,
    goal: Sequence[int] | None = None,
    connectivity: int = 8,
    corner_cutting: bool = False,
) -> None:
    """Validate a grid path: inside the map, free cells, unit moves, no corner cuts (unless allowed).

    Args:
        occupied: (H, W) bool occupancy.
        cells: (N, 2) (row, col) cells.
        start: when given, the required first cell.
        goal: when given, the required last cell.
        connectivity: 4 or 8 — which moves are legal.
        corner_cutting: whether diagonal steps may pass occupied orthogonal cells.

    Raises:
        InvalidPath: the first violation found, with its index.
    """
    grid = as_occupancy(occupied)
    c = np.asarray(cells)
    if c.ndim != 2 or c.shape[1] != 2 or c.shape[0] == 0:
        raise InvalidPath(f"cells must be a non-empty (N, 2) array; got shape {c.shape}")
    if not np.issubdtype(c.dtype, np.integer):
        raise InvalidPath(f"cells must be integers; got dtype {c.dtype}")
    h, w = grid.shape
    inside = (c[:, 0] >= 0) & (c[:, 0] < h) & (c[:, 1] >= 0) & (c[:, 1] < w)
    if not inside.all():
        i = int(np.argmin(inside))
        raise InvalidPath(f"cell {i} {tuple(c[i])} is outside the {h}×{w} map")
    occ = grid[c[:, 0], c[:, 1]]
    if occ.any():
        i = int(np.argmax(occ))
        raise InvalidPath(f"cell {i} {tuple(c[i])} is occupied")
    if start is not None and tuple(int(v) for v in c[0]) != tuple(int(v) for v in start):
        raise InvalidPath(f"path starts at {tuple(c[0])}, not {tuple(start)}")
    if goal is not None and tuple(int(v) for v in c[-1]) != tuple(int(v) for v in goal):
        raise InvalidPath(f"path ends at {tuple(c[-1])}, not {tuple(goal)}")
    if c.shape[0] < 2:
        return
    d = np.diff(c, axis=0)
    ad = np.abs(d)
    cheb = ad.max(axis=1)
    bad = cheb != 1
    if connectivity == 4:
        bad |= ad.sum(axis=1) != 1
    if bad.any():
        i = int(np.argmax(bad))
        raise InvalidPath(f"step {i} {tuple(c[i])} -> {tuple(c[i + 1])} is not a legal unit move")
    if not corner_cutting:
        diag = ad.sum(axis=1) == 2
        a = c[:-1][diag]
        dd = d[diag]
        cut = grid[a[:, 0] + dd[:, 0], a[:, 1]] | grid[a[:, 0], a[:, 1] + dd[:, 1]]
        if cut.any():
            k = int(np.flatnonzero(diag)[int(np.argmax(cut))])
            raise InvalidPath(f"step {k} {tuple(c[k])} -> {tuple(c[k + 1])} cuts a corner")

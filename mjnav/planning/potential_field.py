"""Artificial potential fields on occupancy grids, with seeded escapes from local minima.

The potential of a free cell q (potential units; distances in cells):

    U(q) = ξ·‖q − q_goal‖ + η·(1/ρ(q) − 1/ρ₀)   if ρ(q) ≤ ρ₀,   else ξ·‖q − q_goal‖

with ξ = ``attractive_gain``, η = ``repulsive_gain``, ρ₀ = ``influence_radius_cells`` and ρ(q) the Euclidean
distance from q to the nearest occupied cell (a distance transform; ρ ≥ 1 on free cells). The attractive term
is conic (its gradient has constant magnitude ξ), the repulsive term grows like 1/ρ near obstacles and vanishes
at ρ₀. Occupied cells have U = +inf. Cells outside the map are not obstacles.

The planner follows −∇U by discrete steepest descent: from the current cell it moves to the legal neighbour
with the most negative slope (U(n) − U(q)) / |n − q|, and steps onto the goal whenever the goal is a legal
neighbour. A cell with no downhill neighbour (other than the goal) is a local minimum; the planner then runs an
escape — a random walk or simulated annealing driven by the caller's ``rng`` — that ends as soon as it reaches
a cell whose potential is below that minimum's (or the goal), or after ``escape_steps`` steps, and then resumes
the descent. A successful escape never leads back to the same minimum (descent only goes down); a failed one
usually does, and the next escape starts from there with fresh random numbers. After ``max_escapes`` escapes
the planner gives up with :class:`~mjnav.planning.errors.LocalMinimum`. Loops are cut from the final path (a
revisited cell truncates the path back to its first visit), so the path is simple; it is not optimal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from mjnav.planning._kernels import MOVE_DC, MOVE_DR, step_allowed
from mjnav.planning.errors import InvalidInput, LocalMinimum, NoPathFound
from mjnav.planning.grid import GridPlan, as_cell, as_occupancy, check_endpoints, pad_blocked, path_cost

SQRT2 = math.sqrt(2.0)


@dataclass(frozen=True, slots=True)
class PotentialFieldParams:
    """Parameters of :func:`plan_potential_field`.

    Attributes:
        attractive_gain: ξ, potential per cell of distance to the goal (> 0).
        repulsive_gain: η, potential·cells of the repulsive term (≥ 0).
        influence_radius_cells: ρ₀, distance (cells) beyond which obstacles do not repel (> 0).
        escape: ``"random_walk"`` (uniform random legal moves) or ``"annealing"`` (simulated annealing on U).
        escape_steps: step budget of one escape (random-walk moves or annealing proposals).
        max_escapes: escapes allowed before giving up.
        initial_temperature: annealing start temperature of every escape, potential units (> 0).
        cooling: annealing geometric cooling factor per proposal, in (0, 1].
        max_steps: total step budget (descent + escapes); exceeding it raises ``NoPathFound``.
    """

    attractive_gain: float = 1.0
    repulsive_gain: float = 4.0
    influence_radius_cells: float = 4.0
    escape: Literal["random_walk", "annealing"] = "random_walk"
    escape_steps: int = 2000
    max_escapes: int = 100
    initial_temperature: float = 3.0
    cooling: float = 0.998
    max_steps: int = 2_000_000

    def __post_init__(self) -> None:
        checks = (
            (math.isfinite(self.attractive_gain) and self.attractive_gain > 0, "attractive_gain must be > 0"),
            (math.isfinite(self.repulsive_gain) and self.repulsive_gain >= 0, "repulsive_gain must be >= 0"),
            (
                math.isfinite(self.influence_radius_cells) and self.influence_radius_cells > 0,
                "influence_radius_cells must be > 0",
            ),
            (self.escape in ("random_walk", "annealing"), "escape must be 'random_walk' or 'annealing'"),
            (self.escape_steps >= 1, "escape_steps must be >= 1"),
            (self.max_escapes >= 0, "max_escapes must be >= 0"),
            (
                math.isfinite(self.initial_temperature) and self.initial_temperature > 0,
                "initial_temperature must be > 0",
            ),
            (0 < self.cooling <= 1, "cooling must be in (0, 1]"),
            (self.max_steps >= 1, "max_steps must be >= 1"),
        )
        for ok, message in checks:
            if not ok:
                raise InvalidInput(f"PotentialFieldParams: {message}")


def potential_map(
    occupied: ArrayLike, goal: tuple[int, int] | ArrayLike, params: PotentialFieldParams | None = None
) -> NDArray[np.float64]:
    """The total potential U of every cell (see the module docstring).

    Args:
        occupied: (H, W) bool occupancy.
        goal: (row, col) goal cell.
        params: gains and radius (defaults when ``None``).

    Returns:
        (H, W) float64 potential, potential units; +inf on occupied cells.
    """
    p = params or PotentialFieldParams()
    grid = as_occupancy(occupied)
    goal = as_cell(goal, "goal")
    h, w = grid.shape
    rows, cols = np.indices((h, w), dtype=np.float64)
    u = p.attractive_gain * np.hypot(rows - goal[0], cols - goal[1])
    if grid.any() and p.repulsive_gain > 0:
        rho = ndimage.distance_transform_edt(~grid)
        near = (rho > 0) & (rho <= p.influence_radius_cells)
        u[near] += p.repulsive_gain * (1.0 / rho[near] - 1.0 / p.influence_radius_cells)
    u[grid] = np.inf
    return u


@njit(cache=True)
def _append(buf: NDArray[np.int64], n: int, node: int) -> tuple[NDArray[np.int64], int]:  # pragma: no cover
    if n == buf.shape[0]:
        bigger = np.empty(2 * n, np.int64)
        bigger[:n] = buf
        buf = bigger
    buf[n] = node
    return buf, n + 1


@njit(cache=True)
def _descend(
    u: NDArray[np.float64],
    blocked: NDArray[np.uint8],
    width: int,
    start: int,
    goal: int,
    n_moves: int,
    corner_cutting: bool,
    max_steps: int,
) -> NDArray[np.int64]:  # pragma: no cover - compiled
    """Steepest descent from ``start``; returns the nodes visited after ``start`` (ends at goal or a minimum)."""
    buf = np.empty(256, np.int64)
    n = 0
    cur = start
    while cur != goal and n < max_steps:
        best = -1
        best_slope = 0.0
        for k in range(n_moves):
            dr = MOVE_DR[k]
            dc = MOVE_DC[k]
            if not step_allowed(blocked, width, cur, dr, dc, corner_cutting):
                continue
            nb = cur + dr * width + dc
            if nb == goal:
                best = nb
                break
            slope = (u[nb] - u[cur]) / (SQRT2 if k >= 4 else 1.0)
            if slope < best_slope:
                best_slope = slope
                best = nb
        if best < 0:
            break
        cur = best
        buf, n = _append(buf, n, cur)
    return buf[:n]


@njit(cache=True)
def _escape(
    u: NDArray[np.float64],
    blocked: NDArray[np.uint8],
    width: int,
    start: int,
    goal: int,
    n_moves: int,
    corner_cutting: bool,
    uniforms: NDArray[np.float64],
    annealing: bool,
    temperature: float,
    cooling: float,
) -> tuple[NDArray[np.int64], bool]:  # pragma: no cover - compiled
    """Random walk / simulated annealing from a local minimum until U drops below it (or the goal is hit).

    ``uniforms`` holds 2 values in [0, 1) per step (move choice, acceptance). Returns (nodes visited after
    ``start``, escaped).
    """
    u_min = u[start]
    buf = np.empty(256, np.int64)
    n = 0
    cur = start
    cand = np.empty(8, np.int64)
    lens = np.empty(8, np.float64)
    for i in range(uniforms.shape[0] // 2):
        m = 0
        for k in range(n_moves):
            dr = MOVE_DR[k]
            dc = MOVE_DC[k]
            if step_allowed(blocked, width, cur, dr, dc, corner_cutting):
                cand[m] = cur + dr * width + dc
                lens[m] = SQRT2 if k >= 4 else 1.0
                m += 1
        if m == 0:
            return buf[:n], False
        j = min(int(uniforms[2 * i] * m), m - 1)
        nb = cand[j]
        if annealing:
            du = u[nb] - u[cur]
            accept = du <= 0.0 or uniforms[2 * i + 1] < math.exp(-du / temperature)
            temperature *= cooling
            if not accept:
                continue
        cur = nb
        buf, n = _append(buf, n, cur)
        if cur == goal or u[cur] < u_min:
            return buf[:n], True
    return buf[:n], False


@njit(cache=True)
def _remove_loops(nodes: NDArray[np.int64], n_total: int) -> NDArray[np.int64]:  # pragma: no cover
    """Cut loops: a revisited node truncates the path back to its first visit."""
    pos = np.full(n_total, -1, np.int64)
    out = np.empty(nodes.shape[0], np.int64)
    n = 0
    for node in nodes:
        p = pos[node]
        if p >= 0:
            for i in range(p + 1, n):
                pos[out[i]] = -1
            n = p + 1
            continue
        pos[node] = n
        out[n] = node
        n += 1
    return out[:n]


def plan_potential_field(
    occupied: ArrayLike,
    start: tuple[int, int] | ArrayLike,
    goal: tuple[int, int] | ArrayLike,
    *,
    rng: np.random.Generator,
    params: PotentialFieldParams | None = None,
    connectivity: int = 8,
    corner_cutting: bool = False,
) -> GridPlan:
    """Plan with an attractive + repulsive potential field (see the module docstring).

    Args:
        occupied: (H, W) bool occupancy.
        start: (row, col) free start cell.
        goal: (row, col) free goal cell.
        rng: generator driving the escapes (seed it for reproducible paths).
        params: potential and escape parameters (defaults when ``None``).
        connectivity: 4 or 8.
        corner_cutting: allow diagonal steps past occupied orthogonal cells.

    Returns:
        A :class:`~mjnav.planning.grid.GridPlan` whose ``expanded`` counts descent and escape steps.

    Raises:
        InvalidInput: malformed map, cell or parameters (also a missing ``rng``).
        StartOutsideMap, GoalOutsideMap, StartOccupied, GoalOccupied: bad start or goal.
        LocalMinimum: still in a local minimum after ``max_escapes`` escapes.
        NoPathFound: the total step budget ran out.
    """
    p = params or PotentialFieldParams()
    grid = as_occupancy(occupied)
    start = as_cell(start, "start")
    goal = as_cell(goal, "goal")
    check_endpoints(grid, start, goal)
    if connectivity not in (4, 8):
        raise InvalidInput(f"connectivity must be 4 or 8; got {connectivity!r}")
    if not isinstance(rng, np.random.Generator):
        raise InvalidInput(f"rng must be a numpy.random.Generator; got {type(rng).__name__}")
    h, w = grid.shape
    width = w + 2
    u = np.full((h + 2, w + 2), np.inf)
    u[1:-1, 1:-1] = potential_map(grid, goal, p)
    uf = u.ravel()
    blocked = pad_blocked(grid).ravel()
    sn = (start[0] + 1) * width + start[1] + 1
    tn = (goal[0] + 1) * width + goal[1] + 1
    pieces = [np.array([sn], np.int64)]
    cur = sn
    steps = 0
    escapes = 0
    while True:
        seg = _descend(uf, blocked, width, cur, tn, connectivity, corner_cutting, p.max_steps - steps)
        steps += seg.shape[0]
        if seg.shape[0]:
            pieces.append(seg)
            cur = int(seg[-1])
        if cur == tn:
            break
        if steps >= p.max_steps:
            raise NoPathFound(f"potential field: step budget {p.max_steps} exhausted")
        cell = (cur // width - 1, cur % width - 1)
        if escapes >= p.max_escapes:
            raise LocalMinimum(
                cell, f"potential field: stuck in the local minimum at {cell} after {escapes} {p.escape} escapes"
            )
        escapes += 1
        uniforms = rng.random(2 * p.escape_steps)
        seg, _escaped = _escape(
            uf,
            blocked,
            width,
            cur,
            tn,
            connectivity,
            corner_cutting,
            uniforms,
            p.escape == "annealing",
            p.initial_temperature,
            p.cooling,
        )
        steps += seg.shape[0]
        if seg.shape[0]:
            pieces.append(seg)
            cur = int(seg[-1])
        if cur == tn:
            break
        if steps >= p.max_steps:
            raise NoPathFound(f"potential field: step budget {p.max_steps} exhausted")
    nodes = _remove_loops(np.concatenate(pieces), uf.shape[0])
    rows = nodes // width - 1
    cols = nodes % width - 1
    cells = np.stack([rows, cols], axis=1).astype(np.int64)
    return GridPlan(cells, path_cost(cells), int(steps), "potential_field")

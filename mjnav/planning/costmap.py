"""From a Nav2-style costmap (0–100, −1 unknown) to the inputs of :func:`~mjnav.planning.plan_grid`.

Cells at or above ``blocked_at`` (99 = inscribed, the robot would touch an obstacle; 100 = lethal) are blocked.
Free cells cost ``cost_weight · c / 98`` extra per unit length, so the search keeps away from obstacles where it
can. Unknown cells are traversable but cost ``unknown_cost`` (optimistic exploration that still prefers known
free space).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mjnav.planning.errors import InvalidInput

#: Costmap value of a cell the robot's footprint would overlap an obstacle from (Nav2's INSCRIBED).
INSCRIBED = 99
#: Highest decaying cost (Nav2's MAX_NON_OBSTACLE - 1 scale).
MAX_FREE_COST = 98


def planning_grid(
    costmap: ArrayLike, *, blocked_at: int = INSCRIBED, cost_weight: float = 2.0, unknown_cost: float = 0.5
) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """Blocked mask and extra traversal cost of a costmap.

    Args:
        costmap: (H, W) integer costs 0..100, −1 for unknown.
        blocked_at: cells with cost >= this are blocked.
        cost_weight: extra cost per unit length of a cell at cost 98 (scales linearly with the cost), >= 0.
        unknown_cost: extra cost per unit length of an unknown cell, >= 0.

    Returns:
        ``(occupied, cost)``: (H, W) bool and (H, W) float64, ready for ``plan_grid(occupied, ..., cost=cost)``.

    Raises:
        InvalidInput: a malformed costmap or a negative weight.
    """
    c = np.asarray(costmap)
    if c.ndim != 2 or c.size == 0 or not np.issubdtype(c.dtype, np.integer):
        raise InvalidInput(f"costmap must be a non-empty (H, W) integer array, got {c.dtype} {c.shape}")
    if not (cost_weight >= 0 and unknown_cost >= 0):
        raise InvalidInput("cost_weight and unknown_cost must be >= 0")
    occupied = c >= blocked_at
    cost = np.where(c < 0, unknown_cost, np.clip(c, 0, MAX_FREE_COST) * (cost_weight / MAX_FREE_COST))
    cost[occupied] = 0.0
    return occupied, cost


def clear_disc(occupied: ArrayLike, cell: tuple[int, int], radius_cells: float) -> NDArray[np.bool_]:
    """A copy of ``occupied`` with every cell within ``radius_cells`` of ``cell`` marked free.

    Used for the robot's own cell: after an approach close to a wall the robot's centre can lie in the inscribed
    band, and the planner must still be able to leave it.
    """
    occ = np.array(occupied, dtype=bool, copy=True)
    h, w = occ.shape
    r0, c0 = cell
    rad = int(np.ceil(radius_cells))
    rows = np.arange(max(0, r0 - rad), min(h, r0 + rad + 1))
    cols = np.arange(max(0, c0 - rad), min(w, c0 + rad + 1))
    if rows.size and cols.size:
        rr, cc = np.meshgrid(rows, cols, indexing="ij")
        disc = (rr - r0) ** 2 + (cc - c0) ** 2 <= radius_cells**2
        occ[rr[disc], cc[disc]] = False
    return occ

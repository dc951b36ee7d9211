"""Independent reference for the grid tests: scipy's Dijkstra on an explicitly built move graph."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

ORTHO = [(-1, 0), (1, 0), (0, -1), (0, 1)]
DIAG = [(-1, -1), (-1, 1), (1, -1), (1, 1)]


def distances(
    occupied: NDArray[np.bool_],
    start: tuple[int, int],
    *,
    connectivity: int = 8,
    corner_cutting: bool = False,
    cost: NDArray[np.float64] | None = None,
    unit_steps: bool = False,
) -> NDArray[np.float64]:
    """(H, W) shortest distances from ``start`` (inf where unreachable) under the planners' step-cost model.

    A step a → b of length d (1 or √2; 1 with ``unit_steps``) costs d·(1 + (cost[a] + cost[b]) / 2).
    """
    occ = np.asarray(occupied, dtype=bool)
    h, w = occ.shape
    c = np.zeros((h, w)) if cost is None else np.where(np.isinf(cost), 0.0, cost)
    blocked = occ if cost is None else occ | np.isinf(cost)
    idx = np.arange(h * w).reshape(h, w)
    src_all, dst_all, wt_all = [], [], []
    for dr, dc in ORTHO + (DIAG if connectivity == 8 else []):
        r0, r1 = max(0, -dr), min(h, h - dr)
        c0, c1 = max(0, -dc), min(w, w - dc)
        if r0 >= r1 or c0 >= c1:
            continue
        a = (slice(r0, r1), slice(c0, c1))
        b = (slice(r0 + dr, r1 + dr), slice(c0 + dc, c1 + dc))
        ok = ~blocked[a] & ~blocked[b]
        if dr and dc and not corner_cutting:
            ok &= ~blocked[r0 + dr : r1 + dr, c0:c1] & ~blocked[r0:r1, c0 + dc : c1 + dc]
        length = 1.0 if unit_steps or not (dr and dc) else math.sqrt(2.0)
        src_all.append(idx[a][ok])
        dst_all.append(idx[b][ok])
        wt_all.append((length * (1.0 + 0.5 * (c[a] + c[b])))[ok])
    graph = csr_matrix(
        (np.concatenate(wt_all), (np.concatenate(src_all), np.concatenate(dst_all))), shape=(h * w, h * w)
    )
    d = dijkstra(graph, indices=start[0] * w + start[1])
    return np.asarray(d).reshape(h, w)

"""Numba kernels on pose graphs (private; see :mod:`mjnav.estimation.slam`)."""

from __future__ import annotations

import heapq

import numpy as np
from numba import njit
from numpy.typing import NDArray


@njit(cache=True)
def shortest_paths(
    ei: NDArray[np.int64], ej: NDArray[np.int64], weights: NDArray[np.float64], n: int, source: int
) -> NDArray[np.float64]:
    """Dijkstra from ``source`` over an undirected graph of n vertices.

    Args:
        ei: (E,) first vertex of each edge.
        ej: (E,) second vertex of each edge.
        weights: (W, E) non-negative edge weights, one row per weighting.
        n: number of vertices.
        source: start vertex.

    Returns:
        (W, n) least summed weight from ``source`` to every vertex under each weighting (∞ when unreachable).
    """
    m = ei.shape[0]
    deg = np.zeros(n + 1, dtype=np.int64)
    for e in range(m):
        deg[ei[e] + 1] += 1
        deg[ej[e] + 1] += 1
    for v in range(n):
        deg[v + 1] += deg[v]
    nbr = np.empty(2 * m, dtype=np.int64)
    via = np.empty(2 * m, dtype=np.int64)
    fill = deg[:-1].copy()
    for e in range(m):
        a, b = ei[e], ej[e]
        nbr[fill[a]] = b
        via[fill[a]] = e
        fill[a] += 1
        nbr[fill[b]] = a
        via[fill[b]] = e
        fill[b] += 1
    out = np.full((weights.shape[0], n), np.inf)
    for w in range(weights.shape[0]):
        dist = out[w]
        dist[source] = 0.0
        heap = [(0.0, source)]
        while len(heap) > 0:
            d, v = heapq.heappop(heap)
            if d > dist[v]:
                continue
            for q in range(deg[v], deg[v + 1]):
                u = nbr[q]
                nd = d + weights[w, via[q]]
                if nd < dist[u]:
                    dist[u] = nd
                    heapq.heappush(heap, (nd, u))
    return out

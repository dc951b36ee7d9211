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


@njit(cache=True)
def g2o_blocks(
    p: NDArray[np.float64],
    ei: NDArray[np.int64],
    ej: NDArray[np.int64],
    z: NDArray[np.float64],
    information: NDArray[np.float64],
    w: NDArray[np.float64],
    r: NDArray[np.float64],
    blocks: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gauss–Newton blocks of g2o's χ² on SE(2) edges (see ``posegraph._Problem._g2o_blocks``).

    Args:
        p: (N, 3) poses.
        ei: (M,) first vertex of each edge.
        ej: (M,) second vertex of each edge.
        z: (M, 3) edge measurements.
        information: (M, 3, 3) edge information matrices.
        w: (M,) robust weights.
        r: (M, 3) edge errors at ``p``.
        blocks: (M, 4, 3, 3) output; blocks ii, ij and jj (indices 0, 1, 3) are written, 2 is left to the caller.

    Returns:
        (gi (M, 3), gj (M, 3)): Jᵢᵀ Ω r and Jⱼᵀ Ω r of each edge (Ω = w·information).
    """
    m = ei.shape[0]
    gi = np.empty((m, 3))
    gj = np.empty((m, 3))
    ji = np.zeros((3, 3))
    jj = np.zeros((3, 3))
    om = np.empty((3, 3))
    oji = np.empty((3, 3))
    ojj = np.empty((3, 3))
    wr = np.empty(3)
    for e in range(m):
        i = ei[e]
        j = ej[e]
        dx = p[j, 0] - p[i, 0]
        dy = p[j, 1] - p[i, 1]
        # A = R_zᵀ R_iᵀ = R(−θ_i − θ_z); e_t = A (t_j − t_i) − R_zᵀ t_z.
        ca = np.cos(p[i, 2] + z[e, 2])
        sa = np.sin(p[i, 2] + z[e, 2])
        jj[0, 0] = ca
        jj[0, 1] = sa
        jj[1, 0] = -sa
        jj[1, 1] = ca
        jj[2, 2] = 1.0
        ji[0, 0] = -ca
        ji[0, 1] = -sa
        ji[1, 0] = sa
        ji[1, 1] = -ca
        ji[0, 2] = -sa * dx + ca * dy  # dA/dθ_i (t_j − t_i)
        ji[1, 2] = -ca * dx - sa * dy
        ji[2, 2] = -1.0
        for a in range(3):
            for b in range(3):
                om[a, b] = w[e] * information[e, a, b]
        for a in range(3):
            wr[a] = om[a, 0] * r[e, 0] + om[a, 1] * r[e, 1] + om[a, 2] * r[e, 2]
            for b in range(3):
                oji[a, b] = om[a, 0] * ji[0, b] + om[a, 1] * ji[1, b] + om[a, 2] * ji[2, b]
                ojj[a, b] = om[a, 0] * jj[0, b] + om[a, 1] * jj[1, b] + om[a, 2] * jj[2, b]
        for a in range(3):
            gi[e, a] = ji[0, a] * wr[0] + ji[1, a] * wr[1] + ji[2, a] * wr[2]
            gj[e, a] = jj[0, a] * wr[0] + jj[1, a] * wr[1] + jj[2, a] * wr[2]
            for b in range(3):
                blocks[e, 0, a, b] = ji[0, a] * oji[0, b] + ji[1, a] * oji[1, b] + ji[2, a] * oji[2, b]
                blocks[e, 1, a, b] = ji[0, a] * ojj[0, b] + ji[1, a] * ojj[1, b] + ji[2, a] * ojj[2, b]
                blocks[e, 3, a, b] = jj[0, a] * ojj[0, b] + jj[1, a] * ojj[1, b] + jj[2, a] * ojj[2, b]
    return gi, gj

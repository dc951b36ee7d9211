"""Numba kernels of the scan matchers (private; see :mod:`mjnav.estimation.scan_matching`).

Nearest neighbours use a sorted spatial hash: every reference point gets the key of its square cell, keys are
sorted once per match, and a query walks square rings of cells outward from its own cell (binary search per
cell) until no unvisited cell can hold a closer point. Exact within ``max_d``.

The correlative kernels work on (L, H, W) stacks of score tables (level h holds, at cell (r, c), the maximum of
level 0 over the 2^h × 2^h block starting there) and on scan points already rotated and discretised per
candidate angle: (A, N) integer rows and columns into the tables.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

_OFF = 1 << 20
_MUL = 1 << 21


# ---------------------------------------------------------------------------------------------------------
# Spatial hash and k nearest neighbours
# ---------------------------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _slot(ix: int, iy: int, mask: int) -> int:
    return ((ix * 73856093) ^ (iy * 19349663)) & mask


@njit(cache=True)
def build_hash(
    pts: NDArray[np.float64], cell: float
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Open-addressing hash of the points' cells: (slot keys (T,) (−1 = empty), slot → cell number (T,),
    starts (U + 1,) into ``order``, order (N,): point indices grouped by cell)."""
    n = pts.shape[0]
    keys = np.empty(n, dtype=np.int64)
    for i in range(n):
        ix = math.floor(pts[i, 0] / cell) + _OFF
        iy = math.floor(pts[i, 1] / cell) + _OFF
        keys[i] = ix * _MUL + iy
    order = np.argsort(keys, kind="mergesort")
    ukeys = np.empty(n, dtype=np.int64)
    starts = np.empty(n + 1, dtype=np.int64)
    u = 0
    for j in range(n):
        k = keys[order[j]]
        if u == 0 or ukeys[u - 1] != k:
            ukeys[u] = k
            starts[u] = j
            u += 1
    starts[u] = n
    size = 16
    while size < 2 * u:
        size <<= 1
    mask = size - 1
    slot_key = np.full(size, -1, dtype=np.int64)
    slot_val = np.zeros(size, dtype=np.int64)
    for q in range(u):
        k = ukeys[q]
        h = _slot(k // _MUL, k % _MUL, mask)
        while slot_key[h] != -1:
            h = (h + 1) & mask
        slot_key[h] = k
        slot_val[h] = q
    return slot_key, slot_val, starts[: u + 1].copy(), order


@njit(cache=True, inline="always")
def _find(slot_key: NDArray[np.int64], slot_val: NDArray[np.int64], ix: int, iy: int) -> int:
    mask = slot_key.shape[0] - 1
    key = ix * _MUL + iy
    h = _slot(ix, iy, mask)
    while True:
        k = slot_key[h]
        if k == key:
            return slot_val[h]
        if k == -1:
            return -1
        h = (h + 1) & mask


@njit(cache=True, inline="always")
def knn(
    px: float,
    py: float,
    pts: NDArray[np.float64],
    slot_key: NDArray[np.int64],
    slot_val: NDArray[np.int64],
    starts: NDArray[np.int64],
    order: NDArray[np.int64],
    cell: float,
    k: int,
    max_d: float,
    out_idx: NDArray[np.int64],
    out_d2: NDArray[np.float64],
    hint: int = -1,
) -> int:
    """The up to ``k`` nearest points within ``max_d`` of (px, py), sorted by distance; returns their count.

    ``hint`` (k = 1 only): index of a point likely to be the nearest (e.g. last iteration's); its distance
    bounds the search from the start, so most queries stop at their own cell.
    """
    for j in range(k):
        out_d2[j] = np.inf
        out_idx[j] = -1
    fx = px / cell
    fy = py / cell
    cx = math.floor(fx)
    cy = math.floor(fy)
    # Distance from the query to its own cell's nearest side: every cell of ring r + 1 is farther than
    # (r + margin)·cell.
    ux = fx - cx
    uy = fy - cy
    margin = min(min(ux, 1.0 - ux), min(uy, 1.0 - uy))
    max_d2 = max_d * max_d
    found = 0
    if hint >= 0 and k == 1:
        ex = pts[hint, 0] - px
        ey = pts[hint, 1] - py
        d2 = ex * ex + ey * ey
        if d2 <= max_d2:
            out_d2[0] = d2
            out_idx[0] = hint
            found = 1
    ring = 0
    max_ring = int(max_d / cell) + 1
    while ring <= max_ring:
        for dx in range(-ring, ring + 1):
            edge = dx == -ring or dx == ring
            step = 1 if edge else 2 * ring
            dy = -ring
            while dy <= ring:
                u = _find(slot_key, slot_val, cx + dx + _OFF, cy + dy + _OFF)
                if u >= 0:
                    for j in range(starts[u], starts[u + 1]):
                        i = order[j]
                        ex = pts[i, 0] - px
                        ey = pts[i, 1] - py
                        d2 = ex * ex + ey * ey
                        if d2 <= max_d2 and d2 < out_d2[k - 1]:
                            m = k - 1
                            while m > 0 and out_d2[m - 1] > d2:
                                out_d2[m] = out_d2[m - 1]
                                out_idx[m] = out_idx[m - 1]
                                m -= 1
                            out_d2[m] = d2
                            out_idx[m] = i
                            if found < k:
                                found += 1
                if ring == 0:
                    break
                dy += step
        bound = (ring + margin) * cell
        if found == k and out_d2[k - 1] <= bound * bound:
            break
        ring += 1
    return found


@njit(cache=True)
def fit_normals(
    pts: NDArray[np.float64],
    slot_key: NDArray[np.int64],
    slot_val: NDArray[np.int64],
    starts: NDArray[np.int64],
    order: NDArray[np.int64],
    cell: float,
    radius: float,
    max_radius: float,
    min_k: int,
    max_ratio: float,
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Unit normals (N, 2) of the local line at each point and whether it is a line (planarity test).

    Neighbourhood: the index-contiguous run of points within ``radius`` around the point (scan order: the
    same surface) when it has at least ``min_k`` points and is bounded on both sides by farther points;
    otherwise every point within ``radius`` (spatial hash) or, where fewer than ``min_k`` lie there, the
    ``min_k`` nearest within ``max_radius``. A line is accepted when the neighbourhood's smaller covariance eigenvalue
    is at most ``max_ratio`` times the larger one.
    """
    n = pts.shape[0]
    normals = np.zeros((n, 2))
    valid = np.zeros(n, dtype=np.bool_)
    idx = np.empty(min_k, dtype=np.int64)
    d2k = np.empty(min_k)
    r2 = radius * radius
    rings = math.ceil(radius / cell)
    for i in range(n):
        px = pts[i, 0]
        py = pts[i, 1]
        m = 0
        sx = 0.0
        sy = 0.0
        sxx = 0.0
        sxy = 0.0
        syy = 0.0
        # Points in scan order: the neighbours along the same surface are the index-contiguous run within the
        # radius on either side. Runs that are cut short (unordered input, or a point where the surface is
        # interrupted) fall back to the spatial search below.
        lo = i
        while lo > 0:
            ex = pts[lo - 1, 0] - px
            ey = pts[lo - 1, 1] - py
            if ex * ex + ey * ey > r2:
                break
            lo -= 1
        hi = i
        while hi < n - 1:
            ex = pts[hi + 1, 0] - px
            ey = pts[hi + 1, 1] - py
            if ex * ex + ey * ey > r2:
                break
            hi += 1
        if hi - lo + 1 >= min_k and lo > 0 and hi < n - 1:
            for q in range(lo, hi + 1):
                ex = pts[q, 0] - px
                ey = pts[q, 1] - py
                m += 1
                sx += ex
                sy += ey
                sxx += ex * ex
                sxy += ex * ey
                syy += ey * ey
        if m == 0:
            cx = math.floor(px / cell)
            cy = math.floor(py / cell)
            for dx in range(-rings, rings + 1):
                for dy in range(-rings, rings + 1):
                    u = _find(slot_key, slot_val, cx + dx + _OFF, cy + dy + _OFF)
                    if u < 0:
                        continue
                    for j in range(starts[u], starts[u + 1]):
                        q = order[j]
                        ex = pts[q, 0] - px
                        ey = pts[q, 1] - py
                        if ex * ex + ey * ey <= r2:
                            m += 1
                            sx += ex
                            sy += ey
                            sxx += ex * ex
                            sxy += ex * ey
                            syy += ey * ey
        if m < min_k:
            cnt = knn(px, py, pts, slot_key, slot_val, starts, order, cell, min_k, max_radius, idx, d2k)
            m = cnt
            sx = 0.0
            sy = 0.0
            sxx = 0.0
            sxy = 0.0
            syy = 0.0
            for j in range(cnt):
                ex = pts[idx[j], 0] - px
                ey = pts[idx[j], 1] - py
                sx += ex
                sy += ey
                sxx += ex * ex
                sxy += ex * ey
                syy += ey * ey
        if m < 3:
            continue
        mx = sx / m
        my = sy / m
        cxx = sxx / m - mx * mx
        cxy = sxy / m - mx * my
        cyy = syy / m - my * my
        tr = 0.5 * (cxx + cyy)
        det = math.sqrt(max(0.25 * (cxx - cyy) ** 2 + cxy * cxy, 0.0))
        lmax = tr + det
        lmin = tr - det
        if lmax <= 0.0 or lmin > max_ratio * lmax:
            continue
        # Normal: eigenvector of the smaller eigenvalue; the line's direction angle is ½·atan2(2cxy, cxx − cyy).
        phi = 0.5 * math.atan2(2.0 * cxy, cxx - cyy)
        normals[i, 0] = -math.sin(phi)
        normals[i, 1] = math.cos(phi)
        valid[i] = True
    return normals, valid


# ---------------------------------------------------------------------------------------------------------
# ICP and PL-ICP
# ---------------------------------------------------------------------------------------------------------


@njit(cache=True)
def _solve3(H: NDArray[np.float64], g: NDArray[np.float64], scale: float, rel_tol: float) -> NDArray[np.float64]:
    """Minimum-norm solution of H·x = g (H symmetric PSD) on the scaled problem (θ scaled by ``scale``),
    discarding eigen-directions below ``rel_tol`` × the largest eigenvalue."""
    D = np.array([1.0, 1.0, scale])
    Hs = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            Hs[a, b] = H[a, b] * D[a] * D[b]
    w, V = np.linalg.eigh(Hs)
    gs = g * D
    x = np.zeros(3)
    top = w[2]
    for e in range(3):
        if w[e] > rel_tol * top and w[e] > 0.0:
            c = 0.0
            for a in range(3):
                c += V[a, e] * gs[a]
            for a in range(3):
                x[a] += V[a, e] * c / w[e]
    return x * D


@njit(cache=True)
def icp_kernel(
    ref: NDArray[np.float64],
    normals: NDArray[np.float64],
    line_ok: NDArray[np.bool_],
    slot_key: NDArray[np.int64],
    slot_val: NDArray[np.int64],
    starts: NDArray[np.int64],
    order: NDArray[np.int64],
    cell: float,
    scan: NDArray[np.float64],
    x0: float,
    y0: float,
    th0: float,
    point_to_line: bool,
    max_iter: int,
    max_corr: float,
    outlier_mult: float,
    eps_t: float,
    eps_r: float,
    rot_scale: float,
    anneal: float,
) -> tuple[float, float, float, int, bool, NDArray[np.int64], NDArray[np.bool_]]:
    """Iterate correspondences and the closed-form (point-to-point) or Gauss–Newton (point-to-line) update.

    Returns (x, y, θ, iterations, converged, nearest reference index per scan point (−1: none),
    inlier mask of the last iteration).
    """
    n = scan.shape[0]
    x = x0
    y = y0
    th = th0
    nn = np.full(n, -1, dtype=np.int64)
    d = np.full(n, np.inf)
    res = np.zeros(n)
    inl = np.zeros(n, dtype=np.bool_)
    idx1 = np.empty(1, dtype=np.int64)
    d21 = np.empty(1)
    it = 0
    converged = False
    tx = np.empty(n)
    ty = np.empty(n)
    search = max_corr
    # The trimming threshold never drops below a floor that starts at max_corr and shrinks geometrically, so
    # a direction constrained by few points (a far wall) is not trimmed away before the others have converged.
    floor = max_corr
    # Pose two iterations back: a correspondence set flipping between two states makes a 2-cycle, which
    # ends the iteration like a fixed point does.
    px2 = np.inf
    py2 = np.inf
    pth2 = np.inf
    px1 = x
    py1 = y
    pth1 = th
    while it < max_iter:
        it += 1
        c = math.cos(th)
        s = math.sin(th)
        m = 0
        for i in range(n):
            tx[i] = c * scan[i, 0] - s * scan[i, 1] + x
            ty[i] = s * scan[i, 0] + c * scan[i, 1] + y
            cnt = knn(tx[i], ty[i], ref, slot_key, slot_val, starts, order, cell, 1, search, idx1, d21, nn[i])
            if cnt == 0 or (point_to_line and not line_ok[idx1[0]]):
                nn[i] = -1
                d[i] = np.inf
                continue
            j = idx1[0]
            nn[i] = j
            d[i] = math.sqrt(d21[0])
            if point_to_line:
                res[i] = normals[j, 0] * (tx[i] - ref[j, 0]) + normals[j, 1] * (ty[i] - ref[j, 1])
            else:
                res[i] = d[i]
            m += 1
        if m < 3:
            for i in range(n):
                inl[i] = False
            return x, y, th, it, False, nn, inl
        # Adaptive trimming: keep |residual| <= outlier_mult × median |residual| (floored at 1e-9 m).
        absr = np.empty(m)
        dist = np.empty(m)
        k = 0
        for i in range(n):
            if nn[i] >= 0:
                absr[k] = abs(res[i])
                dist[k] = d[i]
                k += 1
        adaptive = outlier_mult * np.median(absr)
        # The floor still decides (until it is below 1 % of max_corr): not a fixed point yet.
        annealing = floor > adaptive and floor > 0.01 * max_corr
        thr = max(adaptive, floor, 1e-9)
        # Later searches stop at 4 × the median pair distance (>= 0.25 m): farther pairs would be trimmed.
        search = min(search, max(4.0 * np.median(dist), 0.25))
        cnt_in = 0
        for i in range(n):
            inl[i] = nn[i] >= 0 and abs(res[i]) <= thr
            if inl[i]:
                cnt_in += 1
        if cnt_in < 3:
            return x, y, th, it, False, nn, inl
        if point_to_line:
            H = np.zeros((3, 3))
            g = np.zeros(3)
            J = np.empty(3)
            for i in range(n):
                if not inl[i]:
                    continue
                j = nn[i]
                nx = normals[j, 0]
                ny = normals[j, 1]
                J[0] = nx
                J[1] = ny
                J[2] = nx * (-(ty[i] - y)) + ny * (tx[i] - x)
                for a in range(3):
                    g[a] -= J[a] * res[i]
                    for b in range(3):
                        H[a, b] += J[a] * J[b]
            dx = _solve3(H, g, rot_scale, 1e-9)
            nxp = x + dx[0]
            nyp = y + dx[1]
            nth = th + dx[2]
        else:
            # Closed-form least squares (Arun et al. 1987, in 2-D): rotation from the centred cross-covariance.
            px = 0.0
            py = 0.0
            qx = 0.0
            qy = 0.0
            for i in range(n):
                if inl[i]:
                    px += scan[i, 0]
                    py += scan[i, 1]
                    qx += ref[nn[i], 0]
                    qy += ref[nn[i], 1]
            px /= cnt_in
            py /= cnt_in
            qx /= cnt_in
            qy /= cnt_in
            sdot = 0.0
            scross = 0.0
            for i in range(n):
                if inl[i]:
                    ax = scan[i, 0] - px
                    ay = scan[i, 1] - py
                    bx = ref[nn[i], 0] - qx
                    by = ref[nn[i], 1] - qy
                    sdot += ax * bx + ay * by
                    scross += ax * by - ay * bx
            nth = math.atan2(scross, sdot)
            cn = math.cos(nth)
            sn = math.sin(nth)
            nxp = qx - (cn * px - sn * py)
            nyp = qy - (sn * px + cn * py)
        dth = math.atan2(math.sin(nth - th), math.cos(nth - th))
        step_t = math.hypot(nxp - x, nyp - y)
        # Next floor: at most ``anneal`` × itself and 3 × how far this update moved the farthest-typical point
        # (translation + rotation × typical range): correct pairs are then off by about the remaining error.
        floor = min(floor * anneal, 3.0 * (step_t + abs(dth) / rot_scale))
        x = nxp
        y = nyp
        th = th + dth
        if annealing:
            continue
        if step_t < eps_t and abs(dth) < eps_r:
            converged = True
            break
        if math.hypot(x - px2, y - py2) < eps_t and abs(th - pth2) < eps_r:
            converged = True
            break
        px2 = px1
        py2 = py1
        pth2 = pth1
        px1 = x
        py1 = y
        pth1 = th
    return x, y, th, it, converged, nn, inl


@njit(cache=True)
def point_to_line_hessian(
    ref: NDArray[np.float64],
    normals: NDArray[np.float64],
    line_ok: NDArray[np.bool_],
    scan: NDArray[np.float64],
    nn: NDArray[np.int64],
    inl: NDArray[np.bool_],
    x: float,
    y: float,
    th: float,
) -> tuple[NDArray[np.float64], float, int]:
    """(JᵀJ (3, 3), Σ r², count) of the point-to-line residuals of the inlier pairs whose reference is a line."""
    c = math.cos(th)
    s = math.sin(th)
    H = np.zeros((3, 3))
    ss = 0.0
    m = 0
    J = np.empty(3)
    for i in range(scan.shape[0]):
        j = nn[i]
        if not inl[i] or j < 0 or not line_ok[j]:
            continue
        rx = c * scan[i, 0] - s * scan[i, 1]
        ry = s * scan[i, 0] + c * scan[i, 1]
        nx = normals[j, 0]
        ny = normals[j, 1]
        r = nx * (rx + x - ref[j, 0]) + ny * (ry + y - ref[j, 1])
        J[0] = nx
        J[1] = ny
        J[2] = -nx * ry + ny * rx
        for a in range(3):
            for b in range(3):
                H[a, b] += J[a] * J[b]
        ss += r * r
        m += 1
    return H, ss, m


@njit(cache=True)
def information_to_covariance(
    H: NDArray[np.float64], sigma2: float, scale: float, ratio: float, unobservable_var: float
) -> tuple[NDArray[np.float64], bool]:
    """σ²·H⁻¹ on the problem with θ scaled to metres (× ``scale``); eigen-directions below ``ratio`` × the
    largest eigenvalue get ``unobservable_var`` instead. Returns (symmetric covariance (3, 3), degenerate)."""
    D = np.array([1.0, 1.0, scale])
    Hs = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            Hs[a, b] = 0.5 * (H[a, b] + H[b, a]) / (D[a] * D[b])
    w, V = np.linalg.eigh(Hs)
    top = max(w[2], 1e-300)
    var = np.empty(3)
    degenerate = False
    for e in range(3):
        if w[e] < ratio * top:
            var[e] = unobservable_var
            degenerate = True
        else:
            var[e] = sigma2 / w[e]
    cov = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            c = 0.0
            for e in range(3):
                c += V[a, e] * var[e] * V[b, e]
            cov[a, b] = c / (D[a] * D[b])
    for a in range(3):
        for b in range(a + 1, 3):
            m = 0.5 * (cov[a, b] + cov[b, a])
            cov[a, b] = m
            cov[b, a] = m
    return cov, degenerate


# ---------------------------------------------------------------------------------------------------------
# Correlative matching on score tables
# ---------------------------------------------------------------------------------------------------------


@njit(cache=True)
def table_range(values: NDArray[np.float64]) -> tuple[bool, float, float]:
    """(every value finite, minimum, maximum) of a non-empty 2-D table in one pass."""
    finite = True
    lo = np.inf
    hi = -np.inf
    for v in values.ravel():
        if not math.isfinite(v):
            finite = False
        elif v < lo:
            lo = v
        if v > hi:
            hi = v
    return finite, lo, hi


@njit(cache=True)
def max_pyramid(values: NDArray[np.float64], pad: int, levels: int) -> NDArray[np.float64]:
    """(levels, H, W) of ``values`` padded with ``pad`` rows and columns of zeros on the low sides (H and W the
    padded sizes): level 0 is the padded table, level h at (r, c) the max of level 0 over rows r..r+2^h−1, cols
    c..c+2^h−1 (clipped).

    Level h is the maximum of four cells of level h − 1 (offsets 0 and 2^(h−1) in each axis); the inner loops
    run branch-free over the columns whose right partner exists, so they vectorise.
    """
    H = values.shape[0] + pad
    W = values.shape[1] + pad
    out = np.empty((levels, H, W))
    base = out[0]
    base[:pad, :] = 0.0
    base[pad:, :pad] = 0.0
    base[pad:, pad:] = values
    for h in range(1, levels):
        half = 1 << (h - 1)
        prev = out[h - 1]
        cur = out[h]
        inner = max(W - half, 0)
        for r in range(H):
            a = prev[r]
            row = cur[r]
            if r + half < H:
                b = prev[r + half]
                for c in range(inner):
                    row[c] = max(max(a[c], a[c + half]), max(b[c], b[c + half]))
                for c in range(inner, W):
                    row[c] = max(a[c], b[c])
            else:
                for c in range(inner):
                    row[c] = max(a[c], a[c + half])
                for c in range(inner, W):
                    row[c] = a[c]
    return out


@njit(cache=True, inline="always")
def _score(
    table: NDArray[np.float64], rows: NDArray[np.int64], cols: NDArray[np.int64], a: int, dr: int, dc: int
) -> float:
    """Sum of the table at the scan cells of angle ``a`` shifted by (dr, dc); cells outside count 0."""
    H, W = table.shape
    total = 0.0
    for k in range(rows.shape[1]):
        r = rows[a, k] + dr
        c = cols[a, k] + dc
        if 0 <= r < H and 0 <= c < W:
            total += table[r, c]
    return total


@njit(cache=True)
def lattice_score(
    table: NDArray[np.float64], rows: NDArray[np.int64], cols: NDArray[np.int64], a: int, dr: int, dc: int
) -> float:
    """:func:`_score` for callers outside the kernels (the score of the chosen pose, without the prior)."""
    return _score(table, rows, cols, a, dr, dc)


@njit(cache=True)
def _prior(a: int, dr: int, dc: int, a0: int, pen_cell: float, pen_ang: float) -> float:
    """The prior's penalty of lattice offset (a, dr, dc) from the centre (a0, 0, 0), in summed-score units."""
    da = a - a0
    return pen_cell * (dr * dr + dc * dc) + pen_ang * da * da


@njit(cache=True)
def brute_force(
    table: NDArray[np.float64],
    rows: NDArray[np.int64],
    cols: NDArray[np.int64],
    wr: int,
    wc: int,
    a0: int,
    pen_cell: float,
    pen_ang: float,
) -> tuple[int, int, int, float]:
    """Best (angle index, dr, dc, summed score − prior) over every angle and every offset |dr| <= wr,
    |dc| <= wc; the prior is :func:`_prior` (0 with both penalties 0).

    Ties keep the first in (angle, dr, dc) lexicographic order.
    """
    best = -np.inf
    ba = 0
    br = 0
    bc = 0
    for a in range(rows.shape[0]):
        for dr in range(-wr, wr + 1):
            for dc in range(-wc, wc + 1):
                v = _score(table, rows, cols, a, dr, dc) - _prior(a, dr, dc, a0, pen_cell, pen_ang)
                if v > best:
                    best = v
                    ba = a
                    br = dr
                    bc = dc
    return ba, br, bc, best


@njit(cache=True)
def branch_and_bound(
    pyr: NDArray[np.float64],
    rows: NDArray[np.int64],
    cols: NDArray[np.int64],
    wr: int,
    wc: int,
    min_score: float,
    a0: int,
    pen_cell: float,
    pen_ang: float,
) -> tuple[int, int, int, float, int]:
    """Exact maximum of :func:`brute_force`'s objective by depth-first branch and bound (Hess et al. 2016).

    A node (a, r0, c0, h) stands for the offsets r0..r0+2^h−1 × c0..c0+2^h−1 at angle a; its score on level h
    bounds every offset it covers (the prior only lowers a leaf's score: the bounds stay bounds). Children
    are visited best first; a node whose bound does not exceed the best leaf so far (initially ``min_score``)
    is pruned. Returns (a, dr, dc, score, nodes scored); score = −inf when nothing beats ``min_score``.
    """
    L = pyr.shape[0]
    A = rows.shape[0]
    top = L - 1
    step = 1 << top
    nr = (2 * wr) // step + 1
    nc = (2 * wc) // step + 1
    cap = A * nr * nc + 4 * L * 4 + 16
    st_s = np.empty(cap)
    st_a = np.empty(cap, dtype=np.int64)
    st_r = np.empty(cap, dtype=np.int64)
    st_c = np.empty(cap, dtype=np.int64)
    st_h = np.empty(cap, dtype=np.int64)
    # Top level: score all, sort ascending, push so the best is popped first.
    n0 = A * nr * nc
    sc = np.empty(n0)
    ta = np.empty(n0, dtype=np.int64)
    tr = np.empty(n0, dtype=np.int64)
    tc = np.empty(n0, dtype=np.int64)
    k = 0
    for a in range(A):
        for i in range(nr):
            r0 = -wr + i * step
            for j in range(nc):
                c0 = -wc + j * step
                sc[k] = _score(pyr[top], rows, cols, a, r0, c0)
                if top == 0:
                    sc[k] -= _prior(a, r0, c0, a0, pen_cell, pen_ang)
                ta[k] = a
                tr[k] = r0
                tc[k] = c0
                k += 1
    scored = n0
    ordr = np.argsort(sc, kind="mergesort")
    sp = 0
    for q in range(n0):
        o = ordr[q]
        st_s[sp] = sc[o]
        st_a[sp] = ta[o]
        st_r[sp] = tr[o]
        st_c[sp] = tc[o]
        st_h[sp] = top
        sp += 1
    best = min_score
    ba = -1
    br = 0
    bc = 0
    cs = np.empty(4)
    cr = np.empty(4, dtype=np.int64)
    cc = np.empty(4, dtype=np.int64)
    while sp > 0:
        sp -= 1
        s = st_s[sp]
        if s <= best:
            continue
        h = st_h[sp]
        a = st_a[sp]
        if h == 0:
            best = s
            ba = a
            br = st_r[sp]
            bc = st_c[sp]
            continue
        half = 1 << (h - 1)
        r0 = st_r[sp]
        c0 = st_c[sp]
        nch = 0
        for di in range(2):
            rr = r0 + di * half
            if rr > wr:
                continue
            for dj in range(2):
                ccol = c0 + dj * half
                if ccol > wc:
                    continue
                cs[nch] = _score(pyr[h - 1], rows, cols, a, rr, ccol)
                if h == 1:
                    cs[nch] -= _prior(a, rr, ccol, a0, pen_cell, pen_ang)
                cr[nch] = rr
                cc[nch] = ccol
                nch += 1
        scored += nch
        # Push ascending (insertion sort of ≤ 4) so the best child is on top.
        for u in range(1, nch):
            v = u
            while v > 0 and cs[v - 1] > cs[v]:
                cs[v - 1], cs[v] = cs[v], cs[v - 1]
                cr[v - 1], cr[v] = cr[v], cr[v - 1]
                cc[v - 1], cc[v] = cc[v], cc[v - 1]
                v -= 1
        for u in range(nch):
            if cs[u] > best:
                st_s[sp] = cs[u]
                st_a[sp] = a
                st_r[sp] = cr[u]
                st_c[sp] = cc[u]
                st_h[sp] = h - 1
                sp += 1
    if ba < 0:
        return 0, 0, 0, -np.inf, scored
    return ba, br, bc, best, scored


@njit(cache=True)
def neighbourhood_moments(
    loglik: NDArray[np.float64],
    rows: NDArray[np.int64],
    cols: NDArray[np.int64],
    a0: int,
    r0: int,
    c0: int,
    half: int,
    res: float,
    ang_step: float,
    ll_scale: float,
) -> NDArray[np.float64]:
    """Covariance (3, 3) of (x, y, θ) offsets under p ∝ exp(Σ log-likelihood) over the (2·half+1)³ fine
    candidates around (a0, r0, c0) (Olson 2009); the log-likelihood of a point is ``ll_scale × loglik`` at its
    cell; units metres and radians."""
    A = rows.shape[0]
    m = 2 * half + 1
    vals = np.full(m * m * m, -np.inf)
    off = np.zeros((m * m * m, 3))
    k = 0
    vmax = -np.inf
    for da in range(-half, half + 1):
        a = a0 + da
        for dr in range(-half, half + 1):
            for dc in range(-half, half + 1):
                off[k, 0] = dc * res
                off[k, 1] = dr * res
                off[k, 2] = da * ang_step
                if 0 <= a < A:
                    v = ll_scale * _score(loglik, rows, cols, a, r0 + dr, c0 + dc)
                    vals[k] = v
                    if v > vmax:
                        vmax = v
                k += 1
    K = np.zeros((3, 3))
    u = np.zeros(3)
    tot = 0.0
    for q in range(k):
        if vals[q] == -np.inf:
            continue
        p = math.exp(vals[q] - vmax)
        tot += p
        for i in range(3):
            u[i] += p * off[q, i]
            for j in range(3):
                K[i, j] += p * off[q, i] * off[q, j]
    cov = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            cov[i, j] = K[i, j] / tot - u[i] * u[j] / (tot * tot)
    return cov


@njit(cache=True)
def likelihood_stamp(
    rows: NDArray[np.int64], cols: NDArray[np.int64], shape_h: int, shape_w: int, res: float, sigma: float, eps: float
) -> NDArray[np.float64]:
    """(H, W) table of log(exp(−d²/2σ²) + eps) − log(eps), d the distance between cell centres to the nearest
    listed cell, evaluated within 4σ of each listed cell (beyond it the table holds 0, the floor; there the exact
    value is below log(1 + exp(−8)/eps) ≈ 0.03 for eps = 0.01)."""
    out = np.zeros((shape_h, shape_w))
    reach = math.ceil(4.0 * sigma / res)
    inv = 1.0 / (2.0 * sigma * sigma)
    log_eps = math.log(eps)
    stamp = np.empty((2 * reach + 1, 2 * reach + 1))
    for dr in range(-reach, reach + 1):
        for dc in range(-reach, reach + 1):
            d2 = (dr * dr + dc * dc) * res * res
            stamp[dr + reach, dc + reach] = math.log(math.exp(-d2 * inv) + eps) - log_eps
    for k in range(rows.shape[0]):
        r0 = rows[k]
        c0 = cols[k]
        for dr in range(-reach, reach + 1):
            r = r0 + dr
            if r < 0 or r >= shape_h:
                continue
            for dc in range(-reach, reach + 1):
                c = c0 + dc
                if c < 0 or c >= shape_w:
                    continue
                v = stamp[dr + reach, dc + reach]
                if v > out[r, c]:
                    out[r, c] = v
    return out

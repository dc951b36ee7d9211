"""Compiled kernels for the QP smoother: symmetric pentadiagonal solves and the active-set polish."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray


@njit(cache=True)
def penta_solve(
    d0: NDArray[np.float64], d1: NDArray[np.float64], d2: NDArray[np.float64], rhs: NDArray[np.float64]
) -> NDArray[np.float64]:  # pragma: no cover - compiled
    """Solve A X = rhs for a symmetric positive definite pentadiagonal A by LDLᵀ factorisation.

    Args:
        d0: (n,) main diagonal of A.
        d1: (n-1,) first super-diagonal, A[i, i+1].
        d2: (n-2,) second super-diagonal, A[i, i+2] (may be shorter when n < 3).
        rhs: (n, k) right-hand sides.

    Returns:
        (n, k) solution.
    """
    n = d0.shape[0]
    diag = np.empty(n)
    l1 = np.zeros(max(n - 1, 0))
    l2 = np.zeros(max(n - 2, 0))
    for i in range(n):
        dv = d0[i]
        if i >= 1:
            dv -= l1[i - 1] * l1[i - 1] * diag[i - 1]
        if i >= 2:
            dv -= l2[i - 2] * l2[i - 2] * diag[i - 2]
        diag[i] = dv
        if i + 1 < n:
            a = d1[i]
            if i >= 1:
                a -= l2[i - 1] * l1[i - 1] * diag[i - 1]
            l1[i] = a / dv
        if i + 2 < n:
            l2[i] = d2[i] / dv
    x = rhs.copy()
    k = rhs.shape[1]
    for c in range(k):
        for i in range(n):
            v = x[i, c]
            if i >= 1:
                v -= l1[i - 1] * x[i - 1, c]
            if i >= 2:
                v -= l2[i - 2] * x[i - 2, c]
            x[i, c] = v
        for i in range(n):
            x[i, c] /= diag[i]
        for i in range(n - 1, -1, -1):
            v = x[i, c]
            if i + 1 < n:
                v -= l1[i] * x[i + 1, c]
            if i + 2 < n:
                v -= l2[i] * x[i + 2, c]
            x[i, c] = v
    return x


@njit(cache=True)
def smoothing_matrix_diagonal(n: int, w_smooth: float, w_data: float) -> NDArray[np.float64]:  # pragma: no cover
    """(n,) main diagonal of P = w_s T² + w_d I: w_s (4 + [has left] + [has right]) + w_d."""
    out = np.empty(n)
    for j in range(n):
        out[j] = w_smooth * (4.0 + (1.0 if j > 0 else 0.0) + (1.0 if j < n - 1 else 0.0)) + w_data
    return out


@njit(cache=True)
def _matvec(v: NDArray[np.float64], w_smooth: float, w_data: float) -> NDArray[np.float64]:  # pragma: no cover
    n = v.shape[0]
    diag = smoothing_matrix_diagonal(n, w_smooth, w_data)
    out = np.empty(n)
    for i in range(n):
        acc = diag[i] * v[i]
        if i >= 1:
            acc -= 4.0 * w_smooth * v[i - 1]
        if i + 1 < n:
            acc -= 4.0 * w_smooth * v[i + 1]
        if i >= 2:
            acc += w_smooth * v[i - 2]
        if i + 2 < n:
            acc += w_smooth * v[i + 2]
        out[i] = acc
    return out


@njit(cache=True)
def active_set_polish(
    d: NDArray[np.float64],
    y: NDArray[np.float64],
    q: NDArray[np.float64],
    h: NDArray[np.float64],
    w_smooth: float,
    w_data: float,
    tol: float,
) -> tuple[bool, NDArray[np.float64]]:  # pragma: no cover - compiled
    """Exact minimiser of ½dᵀPd + qᵀd on the active set suggested by an ADMM iterate (d, y), KKT-checked.

    Bounds are fixed where OSQP's polishing rule marks them active (lower: z + h < -y, upper: h - z < y,
    z = clip(d)); pinned points (h = 0) are always fixed. The free offsets solve P_FF d_F = -q_F - P_FA d_A;
    P_FF is again pentadiagonal (entries P[i, i+1] = -4 w_s and P[i, i+2] = w_s survive only between free
    indices 1 or 2 apart). Returns (True, d*) when d* passes the KKT test (free offsets inside the box,
    the gradient P d* + q pointing outward at every fixed bound, within ``tol``), else (False, d*).
    """
    n = d.shape[0]
    v = np.zeros(n)
    state = np.zeros(n, dtype=np.int8)  # 0 free, 1 upper, -1 lower, 2 pinned
    n_free = 0
    for i in range(n):
        if h[i] <= 0.0:
            state[i] = 2
            continue
        z = min(max(d[i], -h[i]), h[i])
        if h[i] - z < y[i]:
            state[i] = 1
            v[i] = h[i]
        elif z + h[i] < -y[i]:
            state[i] = -1
            v[i] = -h[i]
        else:
            n_free += 1
    if n_free > 0:
        idx = np.empty(n_free, dtype=np.int64)
        m = 0
        for i in range(n):
            if state[i] == 0:
                idx[m] = i
                m += 1
        pv = _matvec(v, w_smooth, w_data)
        full_diag = smoothing_matrix_diagonal(n, w_smooth, w_data)
        d0 = np.empty(n_free)
        d1 = np.zeros(max(n_free - 1, 0))
        d2 = np.zeros(max(n_free - 2, 0))
        rhs = np.empty((n_free, 1))
        for a in range(n_free):
            i = idx[a]
            d0[a] = full_diag[i]
            rhs[a, 0] = -q[i] - pv[i]
            if a + 1 < n_free:
                gap = idx[a + 1] - i
                if gap == 1:
                    d1[a] = -4.0 * w_smooth
                elif gap == 2:
                    d1[a] = w_smooth
            if a + 2 < n_free and idx[a + 2] - i == 2:
                d2[a] = w_smooth
        sol = penta_solve(d0, d1, d2, rhs)
        for a in range(n_free):
            v[idx[a]] = sol[a, 0]
    ok = True
    grad = _matvec(v, w_smooth, w_data)
    qmax = 0.0
    for i in range(n):
        qmax = max(qmax, abs(q[i]))
    gtol = tol * (1.0 + qmax)
    for i in range(n):
        grad_i = grad[i] + q[i]
        s = state[i]
        inside_violated = s == 0 and abs(v[i]) > h[i] + tol
        wrong_sign = (s == 1 and grad_i > gtol) or (s == -1 and grad_i < -gtol)
        if inside_violated or wrong_sign:
            ok = False
    return ok, v

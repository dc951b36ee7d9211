"""The compiled pieces of the QP smoother: pentadiagonal solve and the KKT-checked active-set polish."""

from __future__ import annotations

import numpy as np
import pytest

from mjnav.smoothing._kernels import active_set_polish, penta_solve, smoothing_matrix_diagonal


def dense_p(n: int, ws: float, wd: float) -> np.ndarray:
    t = np.diag(np.full(n, -2.0)) + np.diag(np.ones(n - 1), 1) + np.diag(np.ones(n - 1), -1)
    return ws * t @ t + wd * np.eye(n)


def test_penta_solve_matches_dense() -> None:
    rng = np.random.default_rng(0)
    for n in (1, 2, 3, 7, 40):
        p = dense_p(n, 1.3, 0.2)
        np.testing.assert_allclose(np.diag(p), smoothing_matrix_diagonal(n, 1.3, 0.2))
        rhs = rng.normal(size=(n, 2))
        d1 = np.diag(p, 1).copy() if n > 1 else np.zeros(0)
        d2 = np.diag(p, 2).copy() if n > 2 else np.zeros(0)
        np.testing.assert_allclose(penta_solve(np.diag(p).copy(), d1, d2, rhs), np.linalg.solve(p, rhs), atol=1e-12)


@pytest.mark.e2e
def test_polish_accepts_the_right_active_set_and_rejects_a_wrong_one() -> None:
    # 1-D problem: min ½ dᵀPd + qᵀd, |d| <= h; the unconstrained optimum violates the box at some points
    n, ws, wd = 30, 1.0, 0.1
    rng = np.random.default_rng(3)
    p = dense_p(n, ws, wd)
    q = rng.normal(0.0, 0.1, n)
    h = np.full(n, 0.3)
    # reference by projected gradient descent (independent of the kernel)
    d = np.zeros(n)
    for _ in range(100_000):
        d = np.clip(d - (p @ d + q) / 17.0, -h, h)
    y = -(p @ d + q)  # multipliers: positive at active upper bounds, negative at active lower bounds
    assert np.count_nonzero(np.abs(d) >= h - 1e-9) > 0
    ok, exact = active_set_polish(d, y, q, h, ws, wd, 1e-9)
    assert ok
    np.testing.assert_allclose(exact, d, atol=1e-8)
    ok_wrong, _ = active_set_polish(np.zeros(n), np.zeros(n), q, h, ws, wd, 1e-9)  # "nothing active"
    assert not ok_wrong

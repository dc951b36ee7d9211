"""Benchmark: OSQP path smoothing (qp_smooth) against the unconstrained banded-solve floor and peers.

Goal (issue): a 500-point path in <= 2 ms including set-up, constraints met to 1e-4.

Columns, per case, all on the same path in the same run:
  qp_smooth      mjnav.smoothing.qp_smooth, full call (validation, presolve, OSQP set-up + solve, polish)
  floor          scipy.linalg.solveh_banded on the same cost without the box: the unconstrained optimum,
                 a lower bound for any solver of this problem
  ratio          qp_smooth / floor
  osqp-naive     OSQP on the textbook formulation (absolute coordinates, scipy.sparse.diags, default
                 settings): time and its distance from qp_smooth's optimum
  gd             mjnav.smoothing.gradient_descent (projected), for scale
Violation is the largest box violation of qp_smooth's output; "err" compares to a tightly converged
reference (projected gradient descent to 1e-12).

Run: .venv/bin/python benchmarks/smoothing.py [--quick]
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable

import numpy as np
import osqp
import scipy.sparse as sp
from scipy.linalg import solveh_banded

from mjnav.smoothing import gradient_descent, qp_smooth, qp_smooth_detailed


def timeit(fn: Callable[[], object], repeats: int) -> tuple[float, float]:
    """(median, min) wall time in milliseconds after one warm-up call."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) * 1e3, float(np.min(times)) * 1e3


def banded_floor(path: np.ndarray, w_smooth: float = 1.0, w_data: float = 0.1) -> np.ndarray:
    """Unconstrained optimum of the same cost (end points fixed) by one banded Cholesky solve."""
    n = path.shape[0] - 2
    j = np.arange(n)
    ab = np.zeros((3, n))
    ab[2] = w_smooth * (4.0 + (j > 0) + (j < n - 1)) + w_data
    ab[1, 1:] = -4.0 * w_smooth
    ab[0, 2:] = w_smooth
    rhs = w_data * path[1:-1].copy()
    rhs[0] += 2.0 * w_smooth * path[0]
    rhs[1] -= w_smooth * path[0]
    rhs[-1] += 2.0 * w_smooth * path[-1]
    rhs[-2] -= w_smooth * path[-1]
    out = path.copy()
    out[1:-1] = solveh_banded(ab, rhs, check_finite=False)
    return out


def osqp_naive(path: np.ndarray, box: np.ndarray, w_smooth: float = 1.0, w_data: float = 0.1) -> np.ndarray:
    """Textbook OSQP use: absolute coordinates, both axes in one problem, default settings."""
    n_pts = path.shape[0]
    n = 2 * n_pts
    d2 = sp.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(n_pts - 2, n_pts))
    dd = sp.kron(sp.identity(2), d2)
    p_mat = 2.0 * (w_smooth * (dd.T @ dd) + w_data * sp.identity(n))
    x = path.T.reshape(-1)
    q = -2.0 * w_data * x
    h = np.r_[box, box].copy()
    h[[0, n_pts - 1, n_pts, n - 1]] = 0.0  # fixed end points
    solver = osqp.OSQP()
    solver.setup(sp.csc_matrix(p_mat), q, sp.identity(n, format="csc"), x - h, x + h, verbose=False)
    res = solver.solve(raise_error=False)
    return np.asarray(res.x).reshape(2, n_pts).T


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer repetitions")
    ap.add_argument("--points", type=int, default=500)
    args = ap.parse_args()
    reps = 15 if args.quick else 101
    n = args.points
    rng = np.random.default_rng(42)
    t = np.linspace(0.0, 20.0, n)
    path = np.c_[t, 2.0 * np.sin(t / 3.0)] + rng.normal(0.0, 0.05, (n, 2))
    clearance_like = rng.uniform(0.005, 0.15, n)
    cases = [
        ("box 0.10 m", 0.10),
        ("box 0.05 m", 0.05),
        ("box 0.02 m", 0.02),
        ("per-point 0.005-0.15", clearance_like),
        ("no box (inf)", math.inf),
    ]
    print(f"qp_smooth benchmark: {n}-point noisy S-curve (σ = 5 cm), w_smooth = 1, w_data = 0.1, {reps} reps")
    print(f"times in ms: median (min); goal <= 2 ms median including set-up; osqp {osqp.__version__}")
    header = (
        f"{'case':22s} {'qp_smooth':>15s} {'floor':>13s} {'ratio':>6s} {'osqp-naive':>15s} {'naive err m':>11s}"
        f" {'gd':>9s} {'iters':>5s} {'active':>6s} {'pol':>3s} {'viol m':>8s} {'err m':>8s} {'goal':>4s}"
    )
    print(header)
    print("-" * len(header))
    floor_ms = timeit(lambda: banded_floor(path), reps)
    for name, box in cases:
        res = qp_smooth_detailed(path, max_deviation_m=box)
        qp_ms = timeit(lambda box=box: qp_smooth(path, max_deviation_m=box), reps)
        hb = np.broadcast_to(np.asarray(box, dtype=float), (n,))
        violation = float(np.max(np.abs(res.path - path) - hb[:, None]))
        ref = gradient_descent(path, 1.0, 0.1, 1e-12, 400_000, max_deviation_m=box)
        err = float(np.abs(res.path - ref).max())
        gd_ms = timeit(lambda box=box: gradient_descent(path, max_deviation_m=box), max(3, reps // 10))
        if math.isfinite(float(np.max(hb))):
            naive_ms = timeit(lambda hb=hb: osqp_naive(path, hb), max(3, reps // 5))
            naive_err = f"{np.abs(osqp_naive(path, hb) - res.path).max():11.2e}"
            naive_txt = f"{naive_ms[0]:7.3f} ({naive_ms[1]:5.3f})"
        else:
            naive_err, naive_txt = f"{'-':>11s}", f"{'-':>15s}"
        ok = "yes" if qp_ms[0] <= 2.0 and violation <= 1e-4 else "NO"
        print(
            f"{name:22s} {qp_ms[0]:7.3f} ({qp_ms[1]:5.3f}) {floor_ms[0]:5.3f} ({floor_ms[1]:5.3f})"
            f" {qp_ms[0] / floor_ms[0]:6.1f} {naive_txt} {naive_err} {gd_ms[0]:9.2f} {res.iterations:5d}"
            f" {res.active_bounds:6d} {'y' if res.polished else 'n':>3s} {max(violation, 0.0):8.1e}"
            f" {err:8.1e} {ok:>4s}"
        )


if __name__ == "__main__":
    main()

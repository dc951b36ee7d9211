"""Box-constrained quadratic-programme path smoothing solved with OSQP.

The cost is the seed's J = sum_i w_s |s_{i+1} - 2 s_i + s_{i-1}|^2 + w_d |s_i - x_i|^2 (the same as
:func:`mjnav.smoothing.gradient_descent`), the end points are fixed and every interior point must stay in
an axis-aligned box of half-width h_i around its input position.

Formulation. The unknowns are the offsets d = s - x of the N - 2 interior points, separately for x and y
(the cost and the boxes do not couple the coordinates, so the two problems share one matrix). With
T the (N-2) x (N-2) tridiagonal matrix [1, -2, 1] (the second-difference operator restricted to the
interior points, symmetric) and c the second differences of the input path at the interior points:

    minimise ½ dᵀ (w_s T² + w_d I) d + (w_s T c)ᵀ d   subject to  -h <= d <= h.

P = w_s T² + w_d I is pentadiagonal; it is assembled directly in compressed-column form (upper triangle).
Working in offsets keeps OSQP's absolute/relative tolerances at the scale of the deviations rather than of
the map coordinates.

Solve. A presolve computes the unconstrained minimiser with one banded Cholesky solve; for a coordinate
where it already lies inside the box it is the exact answer (the cost is strictly convex). Otherwise at
least one bound is active and OSQP solves that coordinate: it is set up once and, when both coordinates
need it, solved twice (the second time after ``update(q=...)``), warm-started from the clipped presolve.
Polishing: the bounds OSQP's solution marks as active are fixed and the remaining offsets are solved
exactly with one banded Cholesky solve (a principal submatrix of a pentadiagonal matrix is still
banded); the result is kept if it passes the KKT test, which makes it the exact optimum. This replaces
OSQP's generic polishing (a sparse LDLᵀ of the reduced KKT system, several times slower here); if the
test fails, OSQP continues from its iterate with its own polishing switched on. The result is finally
clipped into the box, so the constraints hold to round-off whatever the tolerance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import osqp
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from mjnav.smoothing._bounds import half_widths
from mjnav.smoothing._kernels import active_set_polish, penta_solve, smoothing_matrix_diagonal
from mjnav.smoothing.errors import SolverError
from mjnav.smoothing.path import check_path

FloatArray = NDArray[np.float64]

_EPS = 1e-4  # OSQP eps_abs / eps_rel on the offset problem (metres scale)
_MAX_ITER = 10_000


@dataclass(frozen=True, slots=True)
class QPSmoothResult:
    """Outcome of :func:`qp_smooth_detailed`.

    Attributes:
        path: (N, 2) smoothed positions, metres.
        status: ``"solved"`` (any other OSQP status raises :class:`SolverError`).
        iterations: ADMM iterations summed over the x and y solves.
        polished: True when the result is the exact optimum up to round-off for both coordinates (the
            active-set polish verified the KKT conditions, or OSQP's own polishing succeeded); False
            means OSQP's ADMM solution (within its tolerance) was returned for at least one coordinate.
        objective: J of the returned path (the seed's cost, not halved).
        solver_violation_m: largest box violation of OSQP's raw solution before the final clip, metres.
        active_bounds: number of coordinates (of the 2 (N - 2) free ones) that end on their box bound.
        osqp_solves: coordinates (0, 1 or 2) that needed OSQP; the others were solved exactly by the
            unconstrained presolve because its minimiser already lay inside the box.
    """

    path: FloatArray
    status: str
    iterations: int
    polished: bool
    objective: float
    solver_violation_m: float
    active_bounds: int
    osqp_solves: int


def smoothing_cost(path: ArrayLike, reference: ArrayLike, w_smooth: float, w_data: float) -> float:
    """The seed's cost J = sum w_s |second difference of path|^2 + w_d |path - reference|^2.

    Args:
        path: (N, 2) candidate positions s, metres.
        reference: (N, 2) input positions x, metres.
        w_smooth: smoothness weight.
        w_data: data weight.
    """
    s = check_path(path)
    x = check_path(reference, name="reference")
    if s.shape != x.shape:
        raise ValueError(f"path and reference shapes differ: {s.shape} vs {x.shape}")
    dd = s[2:] - 2.0 * s[1:-1] + s[:-2]
    return float(w_smooth * np.sum(dd * dd) + w_data * np.sum((s - x) ** 2))


def _pentadiagonal_upper(n: int, w_smooth: float, w_data: float) -> sp.csc_matrix:
    """Upper triangle of P = w_s T² + w_d I (n x n) in CSC form, built without scipy's generic helpers."""
    j = np.arange(n, dtype=np.int32)
    counts = np.minimum(j, 2) + 1  # rows j-2, j-1, j present in column j
    indptr = np.zeros(n + 1, dtype=np.int32)
    np.cumsum(counts, out=indptr[1:])
    indices = np.empty(indptr[-1], dtype=np.int32)
    data = np.empty(indptr[-1])
    diag_pos = indptr[1:] - 1
    # (T²)_jj = 4 + (j has a left neighbour) + (j has a right neighbour)
    indices[diag_pos] = j
    data[diag_pos] = w_smooth * (4.0 + (j > 0) + (j < n - 1)) + w_data
    indices[diag_pos[1:] - 1] = j[1:] - 1
    data[diag_pos[1:] - 1] = -4.0 * w_smooth
    indices[diag_pos[2:] - 2] = j[2:] - 2
    data[diag_pos[2:] - 2] = w_smooth
    return sp.csc_matrix((data, indices, indptr), shape=(n, n))


def _identity(n: int) -> sp.csc_matrix:
    idx = np.arange(n, dtype=np.int32)
    return sp.csc_matrix((np.ones(n), idx, np.arange(n + 1, dtype=np.int32)), shape=(n, n))


def qp_smooth_detailed(
    path: ArrayLike,
    *,
    max_deviation_m: float | ArrayLike,
    w_smooth: float = 1.0,
    w_data: float = 0.1,
    clearance: ArrayLike | None = None,
) -> QPSmoothResult:
    """:func:`qp_smooth` returning the solver report alongside the path (same arguments and errors)."""
    x = check_path(path)
    if not (math.isfinite(w_smooth) and w_smooth >= 0.0):
        raise ValueError(f"w_smooth must be finite and >= 0, got {w_smooth}")
    if not (math.isfinite(w_data) and w_data > 0.0):
        raise ValueError(f"w_data must be finite and > 0, got {w_data}")
    n_pts = x.shape[0]
    h = half_widths(max_deviation_m, n_pts, clearance)
    if n_pts < 3:
        return QPSmoothResult(x.copy(), "solved", 0, True, smoothing_cost(x, x, w_smooth, w_data), 0.0, 0, 0)
    n = n_pts - 2
    hi = h[1:-1]
    c = x[2:] - 2.0 * x[1:-1] + x[:-2]  # (n, 2) second differences of the input
    tc = -2.0 * c
    tc[1:] += c[:-1]
    tc[:-1] += c[1:]
    q = w_smooth * tc  # (n, 2) linear terms, one column per coordinate

    # Presolve: the unconstrained minimiser (one banded Cholesky solve). Where it lies inside the box it is
    # the QP's exact solution (strictly convex cost); otherwise at least one bound is active and OSQP runs.
    offsets = penta_solve(
        smoothing_matrix_diagonal(n, float(w_smooth), float(w_data)),
        np.full(max(n - 1, 0), -4.0 * w_smooth),
        np.full(max(n - 2, 0), float(w_smooth)),
        -q,
    )
    need_osqp = [bool(np.any(np.abs(offsets[:, axis]) > hi)) for axis in range(2)]
    iterations = 0
    polished = True
    violation = 0.0
    if any(need_osqp):
        bound = np.minimum(hi, 1e20)
        solver = osqp.OSQP(algebra="builtin")  # explicit: skips probing for (absent) CUDA/MKL modules
        first = need_osqp.index(True)
        solver.setup(
            _pentadiagonal_upper(n, w_smooth, w_data),
            np.ascontiguousarray(q[:, first]),
            _identity(n),
            -bound,
            bound,
            verbose=False,
            scaling=0,  # P has a uniform diagonal and A = I: equilibration would only cost set-up time
            rho=1.5 * math.sqrt(w_data * (16.0 * w_smooth + w_data)),  # ~ geometric mean of P's spectrum
            eps_abs=_EPS,
            eps_rel=_EPS,
            check_termination=5,
            adaptive_rho_interval=50,  # fixed (not time-based) so that runs are reproducible
            polishing=False,  # replaced by the banded active-set polish below (OSQP's is the fallback)
            max_iter=_MAX_ITER,
        )
        for axis in range(first, 2):
            if not need_osqp[axis]:
                continue
            if axis != first:
                solver.update(q=np.ascontiguousarray(q[:, axis]))
            solver.warm_start(x=np.clip(offsets[:, axis], -bound, bound), y=np.zeros(n))
            res = solver.solve(raise_error=False)
            if res.info.status_val != osqp.SolverStatus.OSQP_SOLVED:
                raise SolverError(f"OSQP did not solve the {'xy'[axis]} smoothing QP", str(res.info.status))
            iterations += int(res.info.iter)
            violation = max(violation, float(np.max(np.abs(res.x) - bound)))
            ok, exact = active_set_polish(
                np.asarray(res.x), np.asarray(res.y), q[:, axis].copy(), hi, float(w_smooth), float(w_data), 1e-9
            )
            if not ok:  # active set not settled yet: let OSQP continue and polish itself
                solver.update_settings(polishing=True)
                solver.warm_start(x=res.x, y=res.y)
                res = solver.solve(raise_error=False)
                solver.update_settings(polishing=False)
                if res.info.status_val != osqp.SolverStatus.OSQP_SOLVED:
                    raise SolverError(f"OSQP did not solve the {'xy'[axis]} smoothing QP", str(res.info.status))
                iterations += int(res.info.iter)
                polished = polished and res.info.status_polish == 1
                exact = res.x
            offsets[:, axis] = exact
    np.clip(offsets, -hi[:, None], hi[:, None], out=offsets)
    active = int(np.count_nonzero(np.abs(offsets) >= hi[:, None] - 1e-12))
    out = x.copy()
    out[1:-1] += offsets
    return QPSmoothResult(
        out,
        "solved",
        iterations,
        polished,
        smoothing_cost(out, x, w_smooth, w_data),
        max(violation, 0.0),
        active,
        sum(need_osqp),
    )


def qp_smooth(
    path: ArrayLike,
    *,
    max_deviation_m: float | ArrayLike,
    w_smooth: float = 1.0,
    w_data: float = 0.1,
    clearance: ArrayLike | None = None,
) -> FloatArray:
    """Smooth a path by solving the seed's cost as a sparse box-constrained QP with OSQP.

    Minimises J(s) = sum_i w_smooth |s_{i+1} - 2 s_i + s_{i-1}|^2 + w_data |s_i - x_i|^2 with the end
    points fixed and every interior point inside the axis-aligned box |s_i - x_i| <= h_i (per
    coordinate). See the module docstring for the formulation.

    Args:
        path: (N, 2) input positions x, metres, N >= 2.
        max_deviation_m: box half-width h, metres: a scalar or (N,) values (entries 0 and N-1 are unused
            because the end points are fixed); 0 pins a point, inf leaves it free.
        w_smooth: weight of the second-difference term, >= 0.
        w_data: weight of the data term, > 0.
        clearance: optional (N,) distance from each input point to the nearest obstacle, metres (e.g. read
            from a distance transform of the inflated costmap). The half-width becomes
            min(max_deviation_m, clearance / sqrt(2)), so each box lies inside the free disc around its
            point and the smoothed points cannot enter an obstacle.

    Returns:
        (N, 2) smoothed positions, metres; every point satisfies its box exactly (the solver's answer is
        clipped into the box after the solve).

    Raises:
        PathError: fewer than 2 points, wrong shape or non-finite values.
        InfeasibleProblem: a negative half-width or clearance (the box cannot contain the input point).
        ValueError: invalid weights, NaN or wrongly shaped ``max_deviation_m``/``clearance``.
        SolverError: OSQP did not reach the "solved" status (the status text is attached).
    """
    return qp_smooth_detailed(
        path, max_deviation_m=max_deviation_m, w_smooth=w_smooth, w_data=w_data, clearance=clearance
    ).path

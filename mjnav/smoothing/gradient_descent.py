"""Path smoothing by gradient descent on the seed's quadratic cost."""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from mjnav.smoothing._bounds import half_widths
from mjnav.smoothing.path import check_path


@njit(cache=True)
def _descend(
    x: NDArray[np.float64],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    w_smooth: float,
    w_data: float,
    step: float,
    tol: float,
    max_iter: int,
) -> tuple[NDArray[np.float64], int]:  # pragma: no cover - compiled
    n = x.shape[0]
    s = x.copy()
    g = np.zeros_like(x)
    dd = np.zeros_like(x)
    it = 0
    while it < max_iter:
        it += 1
        # second differences dd[i] = s[i+1] - 2 s[i] + s[i-1] for interior points
        for i in range(1, n - 1):
            for c in range(2):
                dd[i, c] = s[i + 1, c] - 2.0 * s[i, c] + s[i - 1, c]
        # half-gradient of J: w_s * D^T D s + w_d (s - x); D^T dd at i = dd[i-1] - 2 dd[i] + dd[i+1]
        for i in range(1, n - 1):
            for c in range(2):
                acc = -2.0 * dd[i, c]
                if i - 1 >= 1:
                    acc += dd[i - 1, c]
                if i + 1 <= n - 2:
                    acc += dd[i + 1, c]
                g[i, c] = w_smooth * acc + w_data * (s[i, c] - x[i, c])
        biggest = 0.0
        for i in range(1, n - 1):
            for c in range(2):
                new = s[i, c] - step * g[i, c]
                if new < lo[i, c]:
                    new = lo[i, c]
                elif new > hi[i, c]:
                    new = hi[i, c]
                change = abs(new - s[i, c])
                if change > biggest:
                    biggest = change
                s[i, c] = new
        if biggest < tol:
            break
    return s, it


def gradient_descent(
    path: ArrayLike,
    w_smooth: float = 1.0,
    w_data: float = 0.1,
    tol: float = 1e-7,
    max_iter: int = 20_000,
    *,
    max_deviation_m: float | ArrayLike = math.inf,
) -> NDArray[np.float64]:
    """Smooth a path by (projected) gradient descent on the seed's cost, end points fixed.

    Minimises J(s) = sum_i w_smooth |Δs_{i+1} - Δs_i|^2 + w_data |s_i - x_i|^2, where x is the input path,
    s the smoothed one and Δs_i = s_i - s_{i-1}, so Δs_{i+1} - Δs_i = s_{i+1} - 2 s_i + s_{i-1} is the
    second difference. The first and last points stay where they are. Each iteration moves every interior
    point against the gradient with the fixed step 2 / (λ_min + λ_max), where [λ_min, λ_max] =
    [w_data, 16 w_smooth + w_data] bounds the spectrum of ½∇²J, so the iteration always converges.
    With a finite ``max_deviation_m`` every step is projected back into the box
    |s_i - x_i| <= max_deviation_m (per coordinate), which makes it projected gradient descent on the same
    box-constrained problem that :func:`mjnav.smoothing.qp_smooth` solves with OSQP.

    Args:
        path: (N, 2) positions, metres, N >= 2.
        w_smooth: weight of the second-difference (smoothness) term, >= 0.
        w_data: weight of the data (fidelity) term, > 0.
        tol: stop once no coordinate moved more than this in one iteration, metres, > 0.
        max_iter: iteration cap; the iterate after ``max_iter`` steps is returned even if ``tol`` was not
            reached (the cost decreases monotonically, so it is never worse than the input).
        max_deviation_m: scalar or (N,) box half-width per coordinate, metres (inf: unconstrained).

    Returns:
        (N, 2) smoothed positions, metres.

    Raises:
        PathError: fewer than 2 points, wrong shape or non-finite values.
        InfeasibleProblem: a negative ``max_deviation_m``.
        ValueError: invalid weights, ``tol`` or ``max_iter``.
    """
    x = check_path(path)
    if not (math.isfinite(w_smooth) and w_smooth >= 0.0):
        raise ValueError(f"w_smooth must be finite and >= 0, got {w_smooth}")
    if not (math.isfinite(w_data) and w_data > 0.0):
        raise ValueError(f"w_data must be finite and > 0, got {w_data}")
    if not (math.isfinite(tol) and tol > 0.0):
        raise ValueError(f"tol must be finite and > 0, got {tol}")
    if int(max_iter) < 1:
        raise ValueError(f"max_iter must be >= 1, got {max_iter}")
    h = half_widths(max_deviation_m, x.shape[0])
    if x.shape[0] < 3:
        return x.copy()
    lo = x - h[:, None]
    hi = x + h[:, None]
    # the half-gradient's Hessian w_s D^T D + w_d I has its spectrum in [w_d, 16 w_s + w_d]
    step = 2.0 / (16.0 * w_smooth + 2.0 * w_data)
    s, _ = _descend(x, lo, hi, float(w_smooth), float(w_data), step, float(tol), int(max_iter))
    return np.asarray(s)

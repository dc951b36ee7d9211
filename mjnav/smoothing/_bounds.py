"""Per-point deviation bounds shared by the constrained smoothers."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mjnav.smoothing.errors import InfeasibleProblem


def half_widths(
    max_deviation_m: float | ArrayLike, n_points: int, clearance: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Per-point half-widths of the axis-aligned box each smoothed point must stay in.

    The half-width is ``max_deviation_m`` (scalar or per point), further limited to ``clearance / sqrt(2)``
    when a clearance is given: the box's corners are then no farther than the clearance from the original
    point, so a smoothed point can never reach an obstacle that is at least that far away.

    Args:
        max_deviation_m: scalar or (N,) maximum deviation per coordinate, metres, >= 0 (inf allowed).
        n_points: N, number of path points.
        clearance: optional (N,) distance from each original point to the nearest obstacle, metres.

    Returns:
        (N,) half-widths, metres, >= 0.

    Raises:
        InfeasibleProblem: a negative half-width or clearance (the box would not contain the original point).
        ValueError: wrong shape or NaN.
    """
    h = np.asarray(max_deviation_m, dtype=np.float64)
    if h.ndim == 0:
        h = np.full(n_points, float(h))
    elif h.shape != (n_points,):
        raise ValueError(f"max_deviation_m must be a scalar or shape ({n_points},), got {h.shape}")
    else:
        h = h.copy()
    if np.isnan(h).any():
        raise ValueError("max_deviation_m contains NaN")
    if (h < 0.0).any():
        i = int(np.flatnonzero(h < 0.0)[0])
        raise InfeasibleProblem(f"max_deviation_m is negative at point {i} ({h[i]} m): the box is empty")
    if clearance is not None:
        c = np.asarray(clearance, dtype=np.float64)
        if c.ndim == 0:
            c = np.full(n_points, float(c))
        if c.shape != (n_points,):
            raise ValueError(f"clearance must be a scalar or shape ({n_points},), got {c.shape}")
        if np.isnan(c).any():
            raise ValueError("clearance contains NaN")
        if (c < 0.0).any():
            i = int(np.flatnonzero(c < 0.0)[0])
            raise InfeasibleProblem(
                f"clearance is negative at point {i} ({c[i]} m): the input path is already inside an obstacle"
            )
        h = np.minimum(h, c / math.sqrt(2.0))
    return h

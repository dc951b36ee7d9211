"""Grid distance metrics used as search heuristics.

All metrics take points as (row, col) pairs (any real numbers, usually cell indices) and return distances in
cells. They broadcast like NumPy: ``octile(a, b)`` with ``a`` of shape (N, 2) and ``b`` of shape (2,) returns
an (N,) array; two single points give a Python ``float``.

Admissibility on an 8-connected grid with diagonal steps of length √2: ``octile`` is exact on an empty grid,
``euclidean`` and ``chebyshev`` are admissible but weaker, ``manhattan`` overestimates (not admissible, A* with
it is not guaranteed optimal). On a 4-connected grid all four are admissible and ``manhattan`` is exact on an
empty grid.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from mjnav.planning.errors import InvalidInput

SQRT2 = math.sqrt(2.0)

#: Heuristic names and the integer codes the compiled kernels use.
HEURISTIC_CODES: dict[str, int] = {"manhattan": 0, "euclidean": 1, "chebyshev": 2, "octile": 3}


def _deltas(a: ArrayLike, b: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Absolute row and column differences of two broadcastable (..., 2) point arrays."""
    pa = np.asarray(a, dtype=np.float64)
    pb = np.asarray(b, dtype=np.float64)
    if pa.shape[-1:] != (2,) or pb.shape[-1:] != (2,):
        raise InvalidInput(f"points must have shape (..., 2) (row, col); got {pa.shape} and {pb.shape}")
    d = np.abs(pa - pb)
    return d[..., 0], d[..., 1]


def _out(x: NDArray[np.float64]) -> float | NDArray[np.float64]:
    return float(x) if x.ndim == 0 else x


def manhattan(a: ArrayLike, b: ArrayLike) -> float | NDArray[np.float64]:
    """L1 distance |Δrow| + |Δcol|, cells.

    Args:
        a: (..., 2) points (row, col).
        b: (..., 2) points (row, col), broadcastable against ``a``.

    Returns:
        The distances, cells: a float for two single points, else an array of the broadcast shape.
    """
    dr, dc = _deltas(a, b)
    return _out(dr + dc)


def euclidean(a: ArrayLike, b: ArrayLike) -> float | NDArray[np.float64]:
    """L2 distance √(Δrow² + Δcol²), cells. Arguments and result as in :func:`manhattan`."""
    dr, dc = _deltas(a, b)
    return _out(np.hypot(dr, dc))


def chebyshev(a: ArrayLike, b: ArrayLike) -> float | NDArray[np.float64]:
    """L∞ distance max(|Δrow|, |Δcol|), cells. Arguments and result as in :func:`manhattan`."""
    dr, dc = _deltas(a, b)
    return _out(np.maximum(dr, dc))


def octile(a: ArrayLike, b: ArrayLike) -> float | NDArray[np.float64]:
    """Octile distance max + (√2 − 1)·min of |Δrow|, |Δcol|, cells: the 8-connected length with √2 diagonals.

    Arguments and result as in :func:`manhattan`.
    """
    dr, dc = _deltas(a, b)
    return _out(np.maximum(dr, dc) + (SQRT2 - 1.0) * np.minimum(dr, dc))


#: The metrics by name.
METRICS = {"manhattan": manhattan, "euclidean": euclidean, "chebyshev": chebyshev, "octile": octile}


def heuristic_code(name: str) -> int:
    """The kernel code of a heuristic name; raises :class:`InvalidInput` for an unknown name."""
    try:
        return HEURISTIC_CODES[name]
    except KeyError:
        raise InvalidInput(f"unknown heuristic {name!r}; choose one of {sorted(HEURISTIC_CODES)}") from None


@njit(cache=True, inline="always")
def heuristic_value(code: int, dr: float, dc: float) -> float:  # pragma: no cover - compiled
    """Distance for absolute differences ``dr``, ``dc`` (cells) under the metric with kernel ``code``."""
    if code == 3:
        return max(dr, dc) + (SQRT2 - 1.0) * min(dr, dc)
    if code == 0:
        return dr + dc
    if code == 1:
        return math.sqrt(dr * dr + dc * dc)
    return max(dr, dc)

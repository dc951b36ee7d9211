"""Line rasterisation on a grid: Bresenham, Bresenham with diagonal addition, and the exact supercover.

Cells are addressed (row, col). Two coordinate conventions are used and each function states its own:

* **Cell indices** (integers) for :func:`bresenham` and :func:`diagonal_addition`: the line joins the
  *centres* of cell (r0, c0) and cell (r1, c1).
* **Continuous cell coordinates** (floats) for :func:`supercover`: cell (r, c) is the closed unit square
  [r, r + 1] × [c, c + 1], so a world point (x, y) on an :class:`~mjnav.mapping.OccupancyGrid` has continuous
  coordinates (row, col) = ((y − oy)/res, (x − ox)/res) and the centre of cell (r, c) is (r + 0.5, c + 0.5).

All three return an (N, 2) int64 array of (row, col) cells ordered from the first endpoint to the second, with
no duplicates. Their relation for integer endpoints (segment between cell centres)::

    bresenham ⊆ diagonal_addition ⊆ supercover(r0 + .5, c0 + .5, r1 + .5, c1 + .5)
    len(bresenham) = max(|Δr|, |Δc|) + 1,   len(diagonal_addition) = |Δr| + |Δc| + 1

Bresenham tie rule (shared with :meth:`OccupancyGrid.integrate_scan`): walk the axis with the larger
extent (the *major* axis; columns when |Δc| = |Δr|) from the endpoint with the *smaller* major coordinate; at
step i the minor offset is i·|Δminor|/|Δmajor| rounded to the nearest integer, exact halves rounded toward that
endpoint's minor coordinate. Because the walk always starts from the same endpoint, ``bresenham(a, b)`` is
exactly ``bresenham(b, a)`` reversed.
"""

from __future__ import annotations

import math
import operator
from typing import SupportsIndex

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mjnav.mapping.errors import InvalidParameterError

__all__ = ["bresenham", "diagonal_addition", "supercover"]

#: Longest line any of these functions will rasterise, in cells (guards against absurd allocations).
MAX_LINE_CELLS = 50_000_000


def _cell_index(value: SupportsIndex, name: str) -> int:
    """An integer cell index from an int-like value; floats and other types raise."""
    try:
        v = operator.index(value)
    except TypeError as exc:
        raise InvalidParameterError(
            f"{name} must be an integer cell index, got {value!r} ({type(value).__name__})"
        ) from exc
    if abs(v) > 2**52:
        raise InvalidParameterError(f"{name} = {v} is out of the supported range (|index| <= 2**52)")
    return v


def _check_length(n_cells: float) -> None:
    if n_cells > MAX_LINE_CELLS:
        raise InvalidParameterError(f"line would cover {n_cells:.3g} cells, more than {MAX_LINE_CELLS}")


@njit(cache=True)
def _bresenham_kernel(r0: int, c0: int, r1: int, c1: int, add_diagonal: bool) -> NDArray[np.int64]:
    """Canonical Bresenham (see module docstring); optionally 4-connected by diagonal addition."""
    adr = abs(r1 - r0)
    adc = abs(c1 - c0)
    col_major = adc >= adr
    if col_major:
        d_major = adc
        d_minor = adr
        forward = c1 >= c0
    else:
        d_major = adr
        d_minor = adc
        forward = r1 >= r0
    # Canonical start P: the endpoint with the smaller major coordinate.
    if forward:
        pr, pc, qr, qc = r0, c0, r1, c1
    else:
        pr, pc, qr, qc = r1, c1, r0, c0
    minor_up = qr >= pr if col_major else qc >= pc
    minor_step = 1 if minor_up else -1
    n = d_major + 1 + (d_minor if add_diagonal else 0)
    out = np.empty((n, 2), dtype=np.int64)
    two_major = 2 * d_major
    rem = d_major - 1  # (2·i·d_minor + d_major − 1) mod 2·d_major at i = 0
    k = 0  # minor offset (absolute)
    j = 0  # output slot in canonical order
    for i in range(d_major + 1):
        if col_major:
            out[j, 0] = pr + minor_step * k
            out[j, 1] = pc + i
        else:
            out[j, 0] = pr + i
            out[j, 1] = pc + minor_step * k
        j += 1
        if i == d_major:
            break
        rem += 2 * d_minor
        if rem >= two_major:
            rem -= two_major
            if add_diagonal:
                # The true segment v = u·d_minor/d_major crosses v = k + ½ at u* = (k + ½)·d_major/d_minor.
                # u* < i + ½: it enters the minor neighbour (i, k+1) first; otherwise (ties included: the
                # segment passes exactly through the corner) take the major neighbour (i+1, k).
                if (2 * k + 1) * d_major < (2 * i + 1) * d_minor:
                    ui, vk = i, k + 1
                else:
                    ui, vk = i + 1, k
                if col_major:
                    out[j, 0] = pr + minor_step * vk
                    out[j, 1] = pc + ui
                else:
                    out[j, 0] = pr + ui
                    out[j, 1] = pc + minor_step * vk
                j += 1
            k += 1
    if not forward:
        out = out[::-1].copy()
    return out


def bresenham(r0: SupportsIndex, c0: SupportsIndex, r1: SupportsIndex, c1: SupportsIndex) -> NDArray[np.int64]:
    """Bresenham's line between the centres of two cells (8-connected).

    Args:
        r0: start row (integer cell index; may be negative or outside any grid).
        c0: start column.
        r1: end row.
        c1: end column.

    Returns:
        (N, 2) int64 array of (row, col), N = max(|r1 − r0|, |c1 − c0|) + 1, from (r0, c0) to (r1, c1)
        inclusive. Consecutive cells differ by one step along the major axis and at most one along the minor
        axis. Exact ties follow the symmetric rule in the module docstring.

    Raises:
        InvalidParameterError: an endpoint is not an integer (floats are refused, not truncated) or the line
            would be absurdly long.
    """
    a, b, c, d = (_cell_index(v, n) for v, n in ((r0, "r0"), (c0, "c0"), (r1, "r1"), (c1, "c1")))
    _check_length(max(abs(c - a), abs(d - b)) + 1)
    return _bresenham_kernel(a, b, c, d, False)


def diagonal_addition(r0: SupportsIndex, c0: SupportsIndex, r1: SupportsIndex, c1: SupportsIndex) -> NDArray[np.int64]:
    """Bresenham's line made 4-connected by adding one cell at every diagonal step.

    The traversal is exactly :func:`bresenham`; whenever Bresenham moves diagonally (both row and column
    change), the side cell the true centre-to-centre segment passes through is inserted between the two
    diagonal neighbours: the minor-axis neighbour if the segment crosses the minor cell boundary first, the
    major-axis neighbour if it crosses the major boundary first. When it passes exactly through the shared
    corner (e.g. every step of a 45° line) the major-axis neighbour is taken (columns are the major axis at
    45°), i.e. the cell keeping the minor coordinate of the endpoint with the smaller major coordinate.

    Unlike :func:`bresenham`, consecutive cells always share an edge, so a ray traced this way cannot slip
    diagonally between two occupied cells that touch at a corner. Unlike :func:`supercover`, it adds only one
    of the two side cells at an exact corner crossing, so it is not conservative there.

    Args:
        r0: start row (integer cell index).
        c0: start column.
        r1: end row.
        c1: end column.

    Returns:
        (N, 2) int64 array of (row, col), N = |r1 − r0| + |c1 − c0| + 1, from (r0, c0) to (r1, c1) inclusive;
        consecutive cells are 4-neighbours. It contains every :func:`bresenham` cell, and is contained in the
        :func:`supercover` of the segment between the two cell centres.

    Raises:
        InvalidParameterError: an endpoint is not an integer or the line would be absurdly long.
    """
    a, b, c, d = (_cell_index(v, n) for v, n in ((r0, "r0"), (c0, "c0"), (r1, "r1"), (c1, "c1")))
    _check_length(abs(c - a) + abs(d - b) + 1)
    return _bresenham_kernel(a, b, c, d, True)


@njit(cache=True)
def _y_at(x: float, x0: float, y0: float, x1: float, y1: float) -> float:
    """y of the line through (x0, y0), (x1, y1) at x (x0 != x1); exact at the endpoints."""
    if x == x0:
        return y0
    if x == x1:
        return y1
    return y0 + ((x - x0) * (y1 - y0)) / (x1 - x0)


@njit(cache=True)
def _supercover_kernel(r0: float, c0: float, r1: float, c1: float) -> NDArray[np.int64]:
    """Closed-cell supercover by column strips; x = column coordinate, y = row coordinate."""
    x0, y0, x1, y1 = c0, r0, c1, r1
    xlo = min(x0, x1)
    xhi = max(x0, x1)
    ylo_all = min(y0, y1)
    yhi_all = max(y0, y1)
    cmin = math.ceil(xlo) - 1
    cmax = math.floor(xhi)
    ncols = cmax - cmin + 1
    col_first = cmin if x1 >= x0 else cmax
    col_step = 1 if x1 >= x0 else -1
    row_up = y1 >= y0
    # Pass 1: row range of every strip.
    rmins = np.empty(ncols, dtype=np.int64)
    rmaxs = np.empty(ncols, dtype=np.int64)
    total = 0
    for s in range(ncols):
        col = col_first + col_step * s
        if x0 == x1:
            ya = ylo_all
            yb = yhi_all
        else:
            xa = max(float(col), xlo)
            xb = min(float(col + 1), xhi)
            ya = _y_at(xa, x0, y0, x1, y1)
            yb = _y_at(xb, x0, y0, x1, y1)
        lo = min(ya, yb)
        hi = max(ya, yb)
        rmin = math.ceil(lo) - 1
        rmax = math.floor(hi)
        rmins[s] = rmin
        rmaxs[s] = rmax
        total += rmax - rmin + 1
    out = np.empty((total, 2), dtype=np.int64)
    j = 0
    for s in range(ncols):
        col = col_first + col_step * s
        n = rmaxs[s] - rmins[s] + 1
        for t in range(n):
            out[j, 0] = rmins[s] + t if row_up else rmaxs[s] - t
            out[j, 1] = col
            j += 1
    return out


def supercover(r0: float, c0: float, r1: float, c1: float) -> NDArray[np.int64]:
    """Every cell a segment touches: the conservative (collision-detection) supercover.

    Endpoints are **continuous cell coordinates** (see the module docstring): cell (r, c) is the closed square
    [r, r + 1] × [c, c + 1], so pass ``r + 0.5, c + 0.5`` for the centre of cell (r, c), or
    ``(y − oy)/res, (x − ox)/res`` for a world point. A cell is included iff its closed square intersects the
    segment. Consequences of that rule, all intended for collision checking:

    * where the segment passes exactly through a grid corner, all four cells sharing the corner are included
      (not only the two it enters and leaves);
    * a segment running exactly along a grid line includes the cells on both sides of it;
    * an endpoint exactly on a cell boundary also includes the neighbouring cell(s) sharing that boundary.

    Decisions are computed in float64 with the crossing ordinate evaluated as y0 + ((x − x0)·Δy)/Δx, which is
    exact whenever that product and quotient are representable (e.g. endpoints with a few fractional bits such
    as 0.5 or 0.25); for arbitrary reals, a crossing within ~1e-15 cells of a corner may be decided either
    way.

    Args:
        r0: start row coordinate, cells (float).
        c0: start column coordinate, cells.
        r1: end row coordinate, cells.
        c1: end column coordinate, cells.

    Returns:
        (N, 2) int64 array of (row, col), ordered along the segment from (r0, c0) to (r1, c1) (cells touched
        at the same point are listed in an arbitrary but deterministic order), without duplicates.

    Raises:
        InvalidParameterError: an endpoint is NaN/inf or the segment would cover an absurd number of cells.
    """
    vals = []
    for v, name in ((r0, "r0"), (c0, "c0"), (r1, "r1"), (c1, "c1")):
        try:
            f = float(v)
        except (TypeError, ValueError) as exc:
            raise InvalidParameterError(f"{name} must be a real number, got {v!r}") from exc
        if not math.isfinite(f):
            raise InvalidParameterError(f"{name} must be finite, got {f}")
        if abs(f) > 2.0**52:
            raise InvalidParameterError(f"{name} = {f} is out of the supported range (|coordinate| <= 2**52)")
        vals.append(f)
    a, b, c, d = vals
    _check_length(abs(c - a) + 3 * (abs(d - b) + 2))
    return _supercover_kernel(a, b, c, d)

"""Path utilities: validation, arc length, resampling, headings, curvature and roughness.

A path is an (N, 2) float array of (x, y) positions in metres, in order of travel.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mjnav.smoothing.errors import PathError

FloatArray = NDArray[np.float64]


def check_path(path: ArrayLike, *, min_points: int = 2, name: str = "path") -> FloatArray:
    """Validate a path and return it as a C-contiguous float64 array.

    Args:
        path: (N, 2) array-like of (x, y) positions, metres.
        min_points: smallest acceptable N.
        name: argument name used in error messages.

    Returns:
        (N, 2) float64 array (a copy only when a conversion was needed).

    Raises:
        PathError: wrong shape, fewer than ``min_points`` points, or NaN/inf values.
    """
    try:
        arr = np.ascontiguousarray(path, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise PathError(f"{name} is not a numeric (N, 2) array: {exc}") from exc
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise PathError(f"{name} must have shape (N, 2), got {arr.shape}")
    if arr.shape[0] < min_points:
        raise PathError(f"{name} needs at least {min_points} points, got {arr.shape[0]}")
    if not np.isfinite(arr).all():
        bad = int(np.flatnonzero(~np.isfinite(arr).all(axis=1))[0])
        raise PathError(f"{name} has a non-finite value at point {bad}: {arr[bad].tolist()}")
    return arr


def segment_lengths(path: ArrayLike) -> FloatArray:
    """Lengths of the N-1 segments of a path.

    Args:
        path: (N, 2) positions, metres.

    Returns:
        (N-1,) segment lengths, metres.
    """
    p = check_path(path)
    d = np.diff(p, axis=0)
    return np.hypot(d[:, 0], d[:, 1])


def cumulative_length(path: ArrayLike) -> FloatArray:
    """Arc length from the first point to every point.

    Args:
        path: (N, 2) positions, metres.

    Returns:
        (N,) non-decreasing arc lengths, metres; the first entry is 0.
    """
    seg = segment_lengths(path)
    out = np.empty(seg.shape[0] + 1)
    out[0] = 0.0
    np.cumsum(seg, out=out[1:])
    return out


def path_length(path: ArrayLike) -> float:
    """Total length of a path (sum of segment lengths), metres."""
    return float(segment_lengths(path).sum())


def remove_duplicates(path: ArrayLike, *, tol_m: float = 1e-9) -> FloatArray:
    """Drop points closer than ``tol_m`` to their predecessor in the input (consecutive repeats).

    The first and the last input points are always kept: when the last point repeats its predecessor,
    the predecessor is dropped instead.

    Args:
        path: (N, 2) positions, metres.
        tol_m: consecutive points closer than this are treated as repeats, metres.

    Returns:
        (M, 2) positions, metres, 1 <= M <= N.
    """
    p = check_path(path, min_points=1)
    if p.shape[0] < 2:
        return p.copy()
    d = np.diff(p, axis=0)
    keep = np.r_[True, np.hypot(d[:, 0], d[:, 1]) >= tol_m]
    if not keep[-1]:
        kept = np.flatnonzero(keep)
        if kept[-1] != 0:
            keep[kept[-1]] = False
        keep[-1] = kept[-1] != 0 or bool(np.hypot(*(p[-1] - p[0])) >= tol_m)
    return p[keep]


def resample(path: ArrayLike, spacing_m: float) -> FloatArray:
    """Resample a path at equal arc-length spacing (linear interpolation along the segments).

    The first and last points are kept exactly; the last interval is the remainder, so it may be shorter
    than ``spacing_m`` (it is never shorter than 1e-9 m: a remainder that small replaces the previous point).

    Args:
        path: (N, 2) positions, metres, N >= 2 and a non-zero total length.
        spacing_m: target distance between consecutive output points, metres, > 0.

    Returns:
        (M, 2) positions, metres, with M = ceil(length / spacing_m) + 1.

    Raises:
        PathError: invalid path or zero total length.
        ValueError: ``spacing_m`` not positive and finite.
    """
    if not (np.isfinite(spacing_m) and spacing_m > 0.0):
        raise ValueError(f"spacing_m must be positive and finite, got {spacing_m}")
    p = check_path(path)
    s = cumulative_length(p)
    total = float(s[-1])
    if total <= 0.0:
        raise PathError("path has zero length; cannot resample")
    # drop zero-length segments so the arc-length abscissa is strictly increasing for np.interp
    keep = np.r_[True, np.diff(s) > 0.0]
    s, p = s[keep], p[keep]
    targets = np.arange(0.0, total, spacing_m)
    if total - targets[-1] < 1e-9:
        targets = targets[:-1]
    targets = np.append(targets, total)
    return np.column_stack((np.interp(targets, s, p[:, 0]), np.interp(targets, s, p[:, 1])))


def headings(path: ArrayLike) -> FloatArray:
    """Tangent direction at every point.

    Interior points use the chord between their neighbours (central difference); the two end points use
    their one-sided segment.

    Args:
        path: (N, 2) positions, metres, N >= 2.

    Returns:
        (N,) headings, radians in [-pi, pi], counter-clockwise from +x.
    """
    p = check_path(path)
    d = np.empty_like(p)
    d[0] = p[1] - p[0]
    d[-1] = p[-1] - p[-2]
    d[1:-1] = p[2:] - p[:-2]
    return np.arctan2(d[:, 1], d[:, 0])


def curvature(path: ArrayLike) -> FloatArray:
    """Signed curvature at every point from the circle through each point and its two neighbours.

    For interior point i with neighbours a = p[i-1], b = p[i], c = p[i+1] this is the Menger curvature
    kappa = 2 * cross(b - a, c - b) / (|b - a| |c - b| |c - a|), positive when the path turns left
    (counter-clockwise). The end points copy their neighbour's value; degenerate triples (repeated
    points) give 0. A 2-point path has zero curvature.

    Args:
        path: (N, 2) positions, metres, N >= 2.

    Returns:
        (N,) signed curvature, 1/metres.
    """
    p = check_path(path)
    n = p.shape[0]
    k = np.zeros(n)
    if n < 3:
        return k
    ab = p[1:-1] - p[:-2]
    bc = p[2:] - p[1:-1]
    ac = p[2:] - p[:-2]
    cross = ab[:, 0] * bc[:, 1] - ab[:, 1] * bc[:, 0]
    denom = np.hypot(ab[:, 0], ab[:, 1]) * np.hypot(bc[:, 0], bc[:, 1]) * np.hypot(ac[:, 0], ac[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        k[1:-1] = np.where(denom > 0.0, 2.0 * cross / np.where(denom > 0.0, denom, 1.0), 0.0)
    k[0] = k[1]
    k[-1] = k[-2]
    return k


def roughness(path: ArrayLike) -> float:
    """Summed squared second differences, sum_i |p[i+1] - 2 p[i] + p[i-1]|^2, square metres.

    This is the smoothness term of the smoothers' cost (without its weight); 0 for a uniformly sampled
    straight line.

    Args:
        path: (N, 2) positions, metres.
    """
    p = check_path(path)
    if p.shape[0] < 3:
        return 0.0
    dd = p[2:] - 2.0 * p[1:-1] + p[:-2]
    return float(np.sum(dd * dd))

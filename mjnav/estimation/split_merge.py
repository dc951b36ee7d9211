"""Line extraction from a 2-D range scan by split-and-merge, and corners where extracted lines meet.

Algorithm (Pavlidis & Horowitz 1974; the variant compared in Nguyen et al., "A comparison of line extraction
algorithms using 2D laser rangefinder", IROS 2005):

1. the points, in scan order, are cut into runs wherever two consecutive points are more than ``max_gap_m``
   apart;
2. split: a run is split at its point farthest from the chord through its first and last points while that
   distance exceeds ``split_threshold_m``;
3. merge: two neighbouring pieces of the same run are joined when the total-least-squares line of their
   union stays within ``split_threshold_m`` of every point;
4. each piece with at least ``min_points`` points and ``min_length_m`` length is fitted by total least squares
   in the polar form x·cos α + y·sin α = ρ (ρ >= 0; Arras & Siegwart 1997).

Covariance of (ρ, α) for isotropic point noise σ (``point_sigma_m``): with n points, S = Σ (sᵢ − s̄)² their
spread along the line and s_c the centroid's coordinate along the line direction (−sin α, cos α),
Var α = σ²/S, Var ρ = σ²/n + s_c²·σ²/S, Cov(ρ, α) = s_c·σ²/S.

Frames: everything is in the frame of the input points (the sensor frame for a scan), metres and radians.
The (ρ, α) lines and the corners are the usual EKF-SLAM landmarks (Siegwart & Nourbakhsh, ch. 5).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mjnav.estimation.errors import EstimationError

__all__ = ["Corner", "LineSegment", "SplitMergeError", "fit_line", "line_corners", "split_and_merge"]


class SplitMergeError(EstimationError, ValueError):
    """Malformed input to line extraction (wrong shape, non-positive thresholds)."""


@dataclass(frozen=True, eq=False)
class LineSegment:
    """One extracted line.

    Attributes:
        rho: distance of the infinite line from the origin, metres (>= 0).
        alpha: direction of the line's normal (from the origin towards the line), radians in [−π, π).
        start: (2,) first point's projection onto the line, metres (scan order).
        end: (2,) last point's projection onto the line, metres.
        covariance: (2, 2) covariance of (ρ, α): m², m·rad, rad².
        n_points: number of points fitted.
        first_index: index of the first fitted point in the (finite) input points.
        last_index: index of the last fitted point (inclusive). For a segment that wraps past the end of a
            full-circle scan, first_index > last_index (points first_index..N−1 then 0..last_index).
    """

    rho: float
    alpha: float
    start: NDArray[np.float64]
    end: NDArray[np.float64]
    covariance: NDArray[np.float64]
    n_points: int
    first_index: int
    last_index: int

    @property
    def length_m(self) -> float:
        """Distance between the endpoints, metres."""
        return float(np.hypot(*(self.end - self.start)))


@dataclass(frozen=True, eq=False)
class Corner:
    """Intersection of two neighbouring extracted lines.

    Attributes:
        xy: (2,) position, metres, frame of the points.
        covariance: (2, 2) covariance of ``xy`` propagated from the two lines' (ρ, α) covariances, m².
        segments: indices (i, j) of the two lines in the tuple :func:`split_and_merge` returned.
        angle_rad: angle between the two lines, radians in (0, π/2].
    """

    xy: NDArray[np.float64]
    covariance: NDArray[np.float64]
    segments: tuple[int, int]
    angle_rad: float


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def fit_line(points_xy: ArrayLike, point_sigma_m: float = 0.01) -> tuple[float, float, NDArray[np.float64]]:
    """Total-least-squares line through points, in polar form.

    Args:
        points_xy: (N, 2) points, N >= 2, metres.
        point_sigma_m: isotropic standard deviation of each point, metres.

    Returns:
        (ρ >= 0 metres, α radians in [−π, π), (2, 2) covariance of (ρ, α)); see the module doc.

    Raises:
        SplitMergeError: fewer than 2 points, or all points coincide.
    """
    p = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
    n = p.shape[0]
    if n < 2:
        raise SplitMergeError(f"a line needs at least 2 points, got {n}")
    m = p.mean(axis=0)
    d = p - m
    sxx, syy, sxy = float(d[:, 0] @ d[:, 0]), float(d[:, 1] @ d[:, 1]), float(d[:, 0] @ d[:, 1])
    if sxx + syy <= 0.0:
        raise SplitMergeError("all points coincide: the line is undefined")
    alpha = 0.5 * math.atan2(-2.0 * sxy, syy - sxx)
    rho = m[0] * math.cos(alpha) + m[1] * math.sin(alpha)
    if rho < 0.0:
        rho, alpha = -rho, alpha + math.pi
    alpha = _wrap(alpha)
    c, s = math.cos(alpha), math.sin(alpha)
    along = -d[:, 0] * s + d[:, 1] * c
    spread = float(along @ along)
    s_c = -m[0] * s + m[1] * c
    var_a = point_sigma_m**2 / spread
    cov = np.array([[point_sigma_m**2 / n + s_c * s_c * var_a, s_c * var_a], [s_c * var_a, var_a]])
    return float(rho), float(alpha), cov


def _max_chord_distance(p: NDArray[np.float64]) -> tuple[int, float]:
    """Index (into p) and distance of the point farthest from the chord p[0]–p[-1]."""
    a, b = p[0], p[-1]
    e = b - a
    L = math.hypot(e[0], e[1])
    d = p - a
    dist = np.abs(d[:, 0] * e[1] - d[:, 1] * e[0]) / L if L > 0 else np.hypot(d[:, 0], d[:, 1])
    k = int(np.argmax(dist))
    return k, float(dist[k])


def _max_line_distance(p: NDArray[np.float64]) -> float:
    if not np.any(p != p[0]):
        return 0.0  # coincident points lie on every line
    rho, alpha, _ = fit_line(p, 1.0)
    return float(np.max(np.abs(p[:, 0] * math.cos(alpha) + p[:, 1] * math.sin(alpha) - rho)))


def _trim_ends(q: NDArray[np.float64], a: int, b: int, n: int) -> tuple[NDArray[np.float64], int, int]:
    """Drop end points that fit the rest of the piece worse than 3 × its RMS residual: the point at a split
    (nearest the corner) may belong to the neighbouring wall."""
    for _ in range(2):
        if q.shape[0] < 4 or not np.any(q[1:-1] != q[1]):
            break
        rho, alpha, _ = fit_line(q[1:-1], 1.0)
        r = q[:, 0] * math.cos(alpha) + q[:, 1] * math.sin(alpha) - rho
        rms = float(np.sqrt(np.mean(r[1:-1] ** 2)))
        lim = 3.0 * rms + 1e-9
        first, last = abs(r[0]) > lim, abs(r[-1]) > lim
        if not (first or last):
            break
        q = q[int(first) : q.shape[0] - int(last)]
        a, b = (a + int(first)) % n, (b - int(last)) % n
    return q, a, b


def split_and_merge(
    scan_xy: ArrayLike,
    *,
    split_threshold_m: float = 0.05,
    max_gap_m: float = 0.5,
    min_points: int = 5,
    min_length_m: float = 0.2,
    point_sigma_m: float = 0.01,
) -> tuple[LineSegment, ...]:
    """Extract line segments from scan points (see the module doc).

    Args:
        scan_xy: (N, 2) points in scan (angular) order, metres; non-finite rows are dropped first.
        split_threshold_m: largest allowed distance of a point from its segment's line, metres.
        max_gap_m: consecutive points farther apart than this belong to different runs, metres.
        min_points: segments with fewer points are dropped (>= 2).
        min_length_m: segments shorter than this (endpoint to endpoint) are dropped, metres.
        point_sigma_m: point noise σ for the (ρ, α) covariances, metres.

    Returns:
        The segments in scan order (possibly empty); a segment wrapping past the end of a full-circle scan
        comes last.

    Raises:
        SplitMergeError: wrong shape or a non-positive/non-finite parameter.
    """
    try:
        raw = np.asarray(scan_xy, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise SplitMergeError("scan_xy must be an (N, 2) array of numbers") from exc
    if raw.ndim != 2 or raw.shape[1] != 2:
        raise SplitMergeError(f"scan_xy must have shape (N, 2), got {raw.shape}")
    for name, v in (
        ("split_threshold_m", split_threshold_m),
        ("max_gap_m", max_gap_m),
        ("point_sigma_m", point_sigma_m),
    ):
        if not (math.isfinite(v) and v > 0):
            raise SplitMergeError(f"{name} must be finite and > 0, got {v}")
    if not (math.isfinite(min_length_m) and min_length_m >= 0):
        raise SplitMergeError(f"min_length_m must be finite and >= 0, got {min_length_m}")
    if int(min_points) != min_points or min_points < 2:
        raise SplitMergeError(f"min_points must be an integer >= 2, got {min_points}")
    p = raw[np.all(np.isfinite(raw), axis=1)]
    n = p.shape[0]
    if n < 2:
        return ()
    # 1. runs separated by gaps.
    gaps = np.flatnonzero(np.hypot(*np.diff(p, axis=0).T) > max_gap_m)
    bounds = np.concatenate(([0], gaps + 1, [n]))
    pieces: list[tuple[int, int]] = []  # inclusive index ranges
    for r0, r1 in itertools.pairwise(bounds):
        run = [(int(r0), int(r1) - 1)]
        # 2. split.
        done: list[tuple[int, int]] = []
        while run:
            a, b = run.pop()
            if b - a < 2:
                done.append((a, b))
                continue
            k, dist = _max_chord_distance(p[a : b + 1])
            if dist > split_threshold_m and 0 < k < b - a:
                run.append((a + k, b))
                run.append((a, a + k))
            else:
                done.append((a, b))
        done.sort()
        # Split pieces share their split point; give it to the earlier piece only.
        shared = [(a if i == 0 else a + 1, b) for i, (a, b) in enumerate(done)]
        shared = [(a, b) for a, b in shared if b >= a]
        # 3. merge neighbours while the union still fits one line.
        merged = True
        while merged and len(shared) > 1:
            merged = False
            for i in range(len(shared) - 1):
                a, b = shared[i][0], shared[i + 1][1]
                if b - a >= 1 and _max_line_distance(p[a : b + 1]) <= split_threshold_m:
                    shared[i : i + 2] = [(a, b)]
                    merged = True
                    break
        pieces.extend(shared)
    # A full-circle scan starts and ends on the same wall: join the last piece with the first when they are
    # within max_gap_m of each other and fit one line (the joined piece has first_index > last_index).
    wrap = None
    if len(pieces) > 1 and math.hypot(*(p[-1] - p[0])) <= max_gap_m:
        (a0, b0), (a1, b1) = pieces[0], pieces[-1]
        joined = np.concatenate((p[a1 : b1 + 1], p[a0 : b0 + 1]))
        if b1 == n - 1 and a0 == 0 and _max_line_distance(joined) <= split_threshold_m:
            wrap = (a1, b0)
            pieces = pieces[1:-1]
    # 4. fit.
    out: list[LineSegment] = []
    for a, b in [*pieces, *([wrap] if wrap else [])]:
        q = p[a : b + 1] if a <= b else np.concatenate((p[a:], p[: b + 1]))
        q, a, b = _trim_ends(q, a, b, n)
        if q.shape[0] < min_points or not np.any(q != q[0]):
            continue
        rho, alpha, cov = fit_line(q, point_sigma_m)
        nrm = np.array([math.cos(alpha), math.sin(alpha)])
        start = q[0] - (q[0] @ nrm - rho) * nrm
        end = q[-1] - (q[-1] @ nrm - rho) * nrm
        if math.hypot(*(end - start)) < min_length_m:
            continue
        out.append(LineSegment(rho, alpha, start, end, cov, int(q.shape[0]), a, b))
    return tuple(out)


def line_corners(
    segments: tuple[LineSegment, ...] | list[LineSegment],
    *,
    min_angle_rad: float = math.radians(30.0),
    max_distance_m: float = 0.3,
) -> tuple[Corner, ...]:
    """Corners where neighbouring segments (consecutive in scan order, and last with first) meet.

    A corner is reported when the two lines differ in direction by at least ``min_angle_rad`` and their
    intersection lies within ``max_distance_m`` of the end of the first segment and of the start of the
    second.

    Args:
        segments: the output of :func:`split_and_merge`.
        min_angle_rad: smallest angle between the lines, radians in (0, π/2].
        max_distance_m: largest distance from the intersection to the segments' adjacent endpoints, metres.

    Returns:
        The corners, in scan order.
    """
    if not (0.0 < min_angle_rad <= 0.5 * math.pi):
        raise SplitMergeError(f"min_angle_rad must be in (0, pi/2], got {min_angle_rad}")
    if not (math.isfinite(max_distance_m) and max_distance_m > 0):
        raise SplitMergeError(f"max_distance_m must be finite and > 0, got {max_distance_m}")
    n = len(segments)
    pairs = [(i, i + 1) for i in range(n - 1)]
    if n > 2:
        pairs.append((n - 1, 0))
    out: list[Corner] = []
    for i, j in pairs:
        si, sj = segments[i], segments[j]
        d = abs(_wrap(si.alpha - sj.alpha))
        angle = min(d, math.pi - d)
        if angle < min_angle_rad:
            continue
        A = np.array([[math.cos(si.alpha), math.sin(si.alpha)], [math.cos(sj.alpha), math.sin(sj.alpha)]])
        Ainv = np.linalg.inv(A)
        xy = Ainv @ np.array([si.rho, sj.rho])
        if np.hypot(*(xy - si.end)) > max_distance_m or np.hypot(*(xy - sj.start)) > max_distance_m:
            continue
        # x = A⁻¹ b: ∂x/∂ρ_k = A⁻¹ e_k, ∂x/∂α_k = −A⁻¹ e_k (−sin α_k x + cos α_k y).
        J = np.zeros((2, 4))
        for col, (seg, k) in enumerate(((si, 0), (sj, 1))):
            J[:, 2 * col] = Ainv[:, k]
            J[:, 2 * col + 1] = -Ainv[:, k] * (-math.sin(seg.alpha) * xy[0] + math.cos(seg.alpha) * xy[1])
        C = np.zeros((4, 4))
        C[:2, :2] = si.covariance
        C[2:, 2:] = sj.covariance
        cov = J @ C @ J.T
        out.append(Corner(xy, 0.5 * (cov + cov.T), (i, j), float(angle)))
    return tuple(out)

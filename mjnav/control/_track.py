"""Path geometry for the trackers: a prepared path, the forward closest-point search and the lookahead.

The hot loops are compiled with numba; a path is prepared (validated, arc lengths, curvature) once when it
changes, so a control step does no per-call work proportional to the whole path.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from mjnav.geometry import Pose2D
from mjnav.smoothing.errors import PathError
from mjnav.smoothing.path import check_path, curvature, headings, remove_duplicates

FloatArray = NDArray[np.float64]
PoseInput = Pose2D | Sequence[float] | NDArray[np.floating]


def check_params(params: object, positive: Sequence[str] = (), non_negative: Sequence[str] = ()) -> None:
    """Raise ValueError naming ``<class>.<field>`` when a ``positive`` field is not finite and > 0 or a
    ``non_negative`` field not finite and >= 0 (the trackers' parameter checks)."""
    for name in positive:
        v = getattr(params, name)
        if not (math.isfinite(v) and v > 0.0):
            raise ValueError(f"{type(params).__name__}.{name} must be positive and finite, got {v}")
    for name in non_negative:
        v = getattr(params, name)
        if not (math.isfinite(v) and v >= 0.0):
            raise ValueError(f"{type(params).__name__}.{name} must be finite and >= 0, got {v}")


@njit(cache=True)
def project_forward(
    pts: NDArray[np.float64], cum: NDArray[np.float64], x: float, y: float, start: int, window_m: float
) -> tuple[int, float, float]:  # pragma: no cover - compiled
    """Closest point on the segments start, start+1, ... whose start lies within ``window_m`` of arc length.

    Returns:
        (segment index k, fraction t in [0, 1] along it, squared distance m²).
    """
    n = pts.shape[0]
    best_k = start
    best_t = 0.0
    best_d2 = np.inf
    s0 = cum[start]
    for k in range(start, n - 1):
        if k > start and cum[k] - s0 > window_m:
            break
        ax = pts[k, 0]
        ay = pts[k, 1]
        dx = pts[k + 1, 0] - ax
        dy = pts[k + 1, 1] - ay
        l2 = dx * dx + dy * dy
        t = 0.0
        if l2 > 0.0:
            t = ((x - ax) * dx + (y - ay) * dy) / l2
            if t < 0.0:
                t = 0.0
            elif t > 1.0:
                t = 1.0
        qx = ax + t * dx - x
        qy = ay + t * dy - y
        d2 = qx * qx + qy * qy
        if d2 < best_d2:
            best_d2 = d2
            best_k = k
            best_t = t
    return best_k, best_t, best_d2


@njit(cache=True)
def lookahead_point(
    pts: NDArray[np.float64], x: float, y: float, k0: int, t0: float, dist_m: float
) -> tuple[float, float, bool]:  # pragma: no cover - compiled
    """First point at or after the projection (k0, t0) whose distance from (x, y) is >= ``dist_m``.

    Walks the path forward from the projection and intersects the circle of radius ``dist_m`` with the
    first segment that leaves it. When the projection itself is already that far (robot far off the
    path) the projection is returned.

    Returns:
        (x m, y m, reached_end): ``reached_end`` is True when the whole rest of the path lies inside the
        circle, in which case the point is the path's last point.
    """
    n = pts.shape[0]
    r2 = dist_m * dist_m
    ax = pts[k0, 0] + t0 * (pts[k0 + 1, 0] - pts[k0, 0])
    ay = pts[k0, 1] + t0 * (pts[k0 + 1, 1] - pts[k0, 1])
    fx = ax - x
    fy = ay - y
    if fx * fx + fy * fy >= r2:
        return ax, ay, False
    for k in range(k0, n - 1):
        if k > k0:
            ax = pts[k, 0]
            ay = pts[k, 1]
        bx = pts[k + 1, 0]
        by = pts[k + 1, 1]
        if (bx - x) * (bx - x) + (by - y) * (by - y) >= r2:
            dx = bx - ax
            dy = by - ay
            fx = ax - x
            fy = ay - y
            qa = dx * dx + dy * dy
            qb = 2.0 * (fx * dx + fy * dy)
            qc = fx * fx + fy * fy - r2  # < 0: a lies inside the circle
            s = (-qb + math.sqrt(max(qb * qb - 4.0 * qa * qc, 0.0))) / (2.0 * qa)
            return ax + s * dx, ay + s * dy, False
    return pts[n - 1, 0], pts[n - 1, 1], True


class PreparedPath:
    """A validated path with the per-point data the trackers need (built once per path).

    Consecutive repeated points are dropped (they have no direction), so indices refer to the path
    without repeats.

    Attributes:
        points: (N, 2) read-only float64 copy of the path without consecutive repeats, metres.
        cum: (N,) cumulative arc length, metres.
        length_m: total length, metres.
    """

    __slots__ = ("_curv", "_head", "cum", "length_m", "points")

    def __init__(self, path: ArrayLike) -> None:
        pts = remove_duplicates(check_path(path))
        if pts.shape[0] < 2:
            raise PathError("path has fewer than 2 distinct points")
        pts.flags.writeable = False
        d = np.diff(pts, axis=0)
        cum = np.empty(pts.shape[0])
        cum[0] = 0.0
        np.cumsum(np.hypot(d[:, 0], d[:, 1]), out=cum[1:])
        cum.flags.writeable = False
        self.points: FloatArray = pts
        self.cum: FloatArray = cum
        self.length_m = float(cum[-1])
        self._curv: FloatArray | None = None
        self._head: FloatArray | None = None

    @property
    def curvature(self) -> FloatArray:
        """(N,) signed vertex curvature, 1/m (computed on first use)."""
        if self._curv is None:
            self._curv = curvature(self.points)
        return self._curv

    @property
    def headings(self) -> FloatArray:
        """(N,) vertex tangent headings, rad (computed on first use)."""
        if self._head is None:
            self._head = headings(self.points)
        return self._head

    def remaining(self, k: int, t: float) -> float:
        """Arc length from the point at fraction t of segment k to the end, metres."""
        c = self.cum
        return float(c[-1] - (c[k] + t * (c[k + 1] - c[k])))


class PathCache:
    """Keeps the prepared version of the last path handed to a tracker.

    The same array object is recognised by identity (no work); a different object with equal contents is
    recognised by comparing values (O(N), no re-preparation); anything else is prepared afresh and
    reported as new. The contents are copied when a path is first seen, so changing the caller's array
    in place afterwards is not noticed: pass a new array (or reset the tracker) for a new path.
    """

    __slots__ = ("_original", "_prepared", "_source")

    def __init__(self) -> None:
        self._source: object = None
        self._original: FloatArray | None = None
        self._prepared: PreparedPath | None = None

    def clear(self) -> None:
        """Forget the cached path."""
        self._source = None
        self._original = None
        self._prepared = None

    def get(self, path: ArrayLike) -> tuple[PreparedPath, bool]:
        """Return (prepared path, is_new)."""
        prepared = self._prepared
        if prepared is not None and self._original is not None:
            if path is self._source:
                return prepared, False
            try:
                arr = np.asarray(path, dtype=np.float64)
            except (TypeError, ValueError):
                arr = None
            if arr is not None and arr.shape == self._original.shape and np.array_equal(arr, self._original):
                self._source = path
                return prepared, False
        prepared = PreparedPath(path)
        self._prepared = prepared
        self._original = check_path(path).copy()
        self._source = path
        return prepared, True


def signed_cross_track(pts: FloatArray, k: int, x: float, y: float, d2: float) -> float:
    """Distance ``sqrt(d2)`` from (x, y) to segment k, positive when the point lies left of the segment."""
    sx, sy = pts[k + 1, 0] - pts[k, 0], pts[k + 1, 1] - pts[k, 1]
    side = sx * (y - pts[k, 1]) - sy * (x - pts[k, 0])
    return math.copysign(math.sqrt(d2), side) if side != 0.0 else math.sqrt(d2)


#: Distance from the path (metres) beyond which the closest point is searched for over the whole path again.
RELOCATE_M = 0.3


class PathProgress:
    """Where a tracker stands on its current path; the state every tracker shares.

    Holds the prepared-path cache, the closest segment (searched over the whole path on the first call, then
    forward only, within a window), and the goal latch. A path with new contents restarts all of it. When the
    forward search finds the path more than :data:`RELOCATE_M` away, the whole path is searched again: a pose
    corrected backwards along the path (SLAM in a corridor) is then behind the segment the search starts from,
    and the forward search alone measured the distance along the path as an offset from it (issue 30: 1.13 m
    "off the path" on a free route; the controller stopped for good).
    """

    __slots__ = ("cache", "fresh", "index", "reached")

    def __init__(self) -> None:
        self.cache = PathCache()
        self.index = 0
        self.fresh = True
        self.reached = False

    def reset(self) -> None:
        """Forget the path, the closest segment and the goal latch."""
        self.cache.clear()
        self.index = 0
        self.fresh = True
        self.reached = False

    def locate(
        self, path: ArrayLike, x: float, y: float, search_window_m: float
    ) -> tuple[PreparedPath, int, float, float, bool]:
        """Prepare ``path`` (cached) and find the robot's closest point on it.

        Returns:
            (prepared path, segment k, fraction t along it, squared distance d² in m², whether the path is new).
        """
        prepared, is_new = self.cache.get(path)
        if is_new:
            self.index = 0
            self.fresh = True
            self.reached = False
        window = math.inf if self.fresh else search_window_m
        k, t, d2 = project_forward(prepared.points, prepared.cum, x, y, self.index, window)
        if d2 > RELOCATE_M * RELOCATE_M and self.index > 0:
            k0, t0, d0 = project_forward(prepared.points, prepared.cum, x, y, 0, math.inf)
            if d0 < d2:
                k, t, d2 = k0, t0, d0
        self.index = k
        self.fresh = False
        return prepared, k, t, d2, is_new

    def at_goal(self, distance_to_goal_m: float, remaining_m: float, tolerance_m: float) -> bool:
        """Latch and return "reached" once both the goal and the rest of the path are within the tolerance."""
        if not self.reached and distance_to_goal_m <= tolerance_m and remaining_m <= tolerance_m:
            self.reached = True
        return self.reached


def unpack_pose(pose: PoseInput) -> tuple[float, float, float]:
    """(x m, y m, θ rad) floats from a Pose2D, a 3-tuple or a (3,) array; rejects non-finite values."""
    if isinstance(pose, Pose2D):
        return pose.x, pose.y, pose.theta
    try:
        x, y, th = pose
        fx, fy, fth = float(x), float(y), float(th)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"pose must be (x, y, theta), got {pose!r}") from exc
    if not (math.isfinite(fx) and math.isfinite(fy) and math.isfinite(fth)):
        raise ValueError(f"pose must be finite, got ({fx}, {fy}, {fth})")
    return fx, fy, fth


@njit(cache=True)
def chord_blocked(
    x: float, y: float, lx: float, ly: float, obstacles: NDArray[np.float64], clearance_m: float
) -> bool:  # pragma: no cover - compiled
    """True when an obstacle point lies within ``clearance_m`` of the segment (x, y) → (lx, ly)."""
    dx = lx - x
    dy = ly - y
    len2 = dx * dx + dy * dy
    c2 = clearance_m * clearance_m
    for i in range(obstacles.shape[0]):
        px = obstacles[i, 0] - x
        py = obstacles[i, 1] - y
        t = 0.0 if len2 <= 0.0 else min(1.0, max(0.0, (px * dx + py * dy) / len2))
        ex = px - t * dx
        ey = py - t * dy
        if ex * ex + ey * ey < c2:
            return True
    return False

"""Log-odds occupancy grid with a numba ray-casting scan update.

Frame and indexing: the grid is axis-aligned in the map frame (REP-103). Cell (row, col) covers the square
[ox + col·res, ox + (col + 1)·res) × [oy + row·res, oy + (row + 1)·res), i.e. a world point (x, y) lies in

    row = floor((y − oy) / res),    col = floor((x − ox) / res)

so row 0 is the *lowest* y, exactly the ``nav_msgs/OccupancyGrid`` data order (``info.origin`` = (ox, oy)
is the corner of cell (0, 0), ``data[row·W + col]``). Every (H, W) array here uses that layout;
``array.ravel()`` is the ROS ``data`` field.

Filter: the binary Bayes filter in log-odds form (Thrun, Burgard & Fox, *Probabilistic Robotics*, §9.2),

    l_t = clamp(l_{t−1} + l_cell − l_0, l_min, l_max),

with l_cell = ``hit_log_odds`` for the cell a beam ends in and ``miss_log_odds`` for the cells it crosses. The
defaults are OctoMap's (Hornung et al., 2013): p_hit = 0.7, p_miss = 0.4, clamping at p = 0.1192 and 0.971.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from mjnav.geometry import Pose2D
from mjnav.mapping.errors import (
    InvalidGridError,
    InvalidParameterError,
    InvalidPoseError,
    OutsideMapError,
)

if TYPE_CHECKING:
    from mjnav.mapping.ros_map import RosMap

__all__ = ["CellState", "LogOddsModel", "OccupancyGrid", "log_odds_to_prob", "prob_to_log_odds"]


class CellState(enum.IntEnum):
    """Discrete cell states. The values are the ROS occupancy values, so a state array is a valid trinary map.

    ``INFLATED`` never comes out of :meth:`OccupancyGrid.states`; it is the costmap value of a free cell
    within the robot's inscribed radius of an obstacle (see :mod:`mjnav.mapping.inflation`).
    """

    UNKNOWN = -1
    FREE = 0
    INFLATED = 99
    OCCUPIED = 100


def prob_to_log_odds(p: ArrayLike) -> NDArray[np.float64]:
    """Log-odds ln(p / (1 − p)) of probabilities ``p`` in [0, 1] (±inf at 0 and 1); same shape as ``p``."""
    q = np.asarray(p, dtype=np.float64)
    with np.errstate(divide="ignore"):
        return np.log(q) - np.log1p(-q)


def log_odds_to_prob(l: ArrayLike) -> NDArray[np.float64]:  # noqa: E741
    """Probability 1 / (1 + exp(−l)) of log-odds ``l``; same shape as ``l``."""
    q = np.asarray(l, dtype=np.float64)
    return 0.5 * (1.0 + np.tanh(0.5 * q))


def _finite(value: Any, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise InvalidParameterError(f"{name} must be a real number, got {value!r}") from exc
    if not math.isfinite(v):
        raise InvalidParameterError(f"{name} must be finite, got {v}")
    return v


DEFAULT_HIT_LOG_ODDS = math.log(0.7 / 0.3)
DEFAULT_MISS_LOG_ODDS = math.log(0.4 / 0.6)
DEFAULT_PRIOR_LOG_ODDS = 0.0
DEFAULT_MIN_LOG_ODDS = math.log(0.1192 / 0.8808)
DEFAULT_MAX_LOG_ODDS = math.log(0.971 / 0.029)
DEFAULT_FREE_THRESHOLD = -1.9956
DEFAULT_OCCUPIED_THRESHOLD = 1.9956


@dataclass(frozen=True, slots=True)
class LogOddsModel:
    """Parameters of the log-odds binary Bayes filter, all in log-odds units (ln(p / (1 − p))).

    Attributes:
        hit_log_odds: inverse sensor model l_cell for the cell a beam ends in (default ln(0.7/0.3) ≈ 0.847).
        miss_log_odds: l_cell for each cell a beam passes through (default ln(0.4/0.6) ≈ −0.405).
        prior_log_odds: l_0, the prior of every cell and the initial value (default 0, p = 0.5).
        min_log_odds: lower clamp l_min (default ln(0.1192/0.8808) ≈ −2.0): bounds how long a free cell takes
            to turn occupied again.
        max_log_odds: upper clamp l_max (default ln(0.971/0.029) ≈ 3.51).
        free_threshold: a cell with l below this is FREE (default −1.9956, p ≈ 0.120).
        occupied_threshold: a cell with l above this is OCCUPIED (default +1.9956, p ≈ 0.880); cells between the
            thresholds, either one included, are UNKNOWN (the seed: "free below, occupied above").

    With the defaults, an unseen cell becomes OCCUPIED after 3 hits and FREE after 5 misses.

    Raises:
        InvalidParameterError: a value is NaN/inf, or the ordering min < free_threshold < occupied_threshold
            < max, min <= prior <= max, miss < prior < hit does not hold.
    """

    hit_log_odds: float = DEFAULT_HIT_LOG_ODDS
    miss_log_odds: float = DEFAULT_MISS_LOG_ODDS
    prior_log_odds: float = DEFAULT_PRIOR_LOG_ODDS
    min_log_odds: float = DEFAULT_MIN_LOG_ODDS
    max_log_odds: float = DEFAULT_MAX_LOG_ODDS
    free_threshold: float = DEFAULT_FREE_THRESHOLD
    occupied_threshold: float = DEFAULT_OCCUPIED_THRESHOLD

    def __post_init__(self) -> None:
        for name in self.__slots__:
            object.__setattr__(self, name, _finite(getattr(self, name), name))
        if not self.min_log_odds < self.max_log_odds:
            raise InvalidParameterError(
                f"min_log_odds ({self.min_log_odds}) must be < max_log_odds ({self.max_log_odds})"
            )
        if not self.min_log_odds <= self.prior_log_odds <= self.max_log_odds:
            raise InvalidParameterError(f"prior_log_odds ({self.prior_log_odds}) must lie within the clamp bounds")
        if not self.free_threshold < self.occupied_threshold:
            raise InvalidParameterError(
                f"free_threshold ({self.free_threshold}) must be < occupied_threshold ({self.occupied_threshold})"
            )
        if not (self.min_log_odds < self.free_threshold and self.occupied_threshold < self.max_log_odds):
            raise InvalidParameterError(
                "thresholds must lie strictly within the clamp bounds, or cells could never become free/occupied: "
                f"need {self.min_log_odds} < {self.free_threshold} and {self.occupied_threshold} < "
                f"{self.max_log_odds}"
            )
        if not self.miss_log_odds < self.prior_log_odds < self.hit_log_odds:
            raise InvalidParameterError(
                f"need miss_log_odds ({self.miss_log_odds}) < prior_log_odds ({self.prior_log_odds}) < "
                f"hit_log_odds ({self.hit_log_odds})"
            )


# ---------------------------------------------------------------------------------------------------------
# Scan kernel
# ---------------------------------------------------------------------------------------------------------


@njit(cache=True)
def _clip_segment(
    x0: float, y0: float, x1: float, y1: float, xmin: float, xmax: float, ymin: float, ymax: float
) -> tuple[bool, float, float]:
    """Liang–Barsky: parameter interval [t0, t1] ⊆ [0, 1] of the segment inside the box; ok=False if none."""
    t0 = 0.0
    t1 = 1.0
    dx = x1 - x0
    dy = y1 - y0
    for side in range(4):
        if side == 0:
            p, q = -dx, x0 - xmin
        elif side == 1:
            p, q = dx, xmax - x0
        elif side == 2:
            p, q = -dy, y0 - ymin
        else:
            p, q = dy, ymax - y0
        if p == 0.0:
            if q < 0.0:
                return False, t0, t1
        else:
            t = q / p
            if p < 0.0:
                if t > t1:
                    return False, t0, t1
                t0 = max(t0, t)
            else:
                if t < t0:
                    return False, t0, t1
                t1 = min(t1, t)
    return True, t0, t1


@njit(cache=True)
def _bit_length(v: int) -> int:
    """Number of bits of a non-negative integer (0 for 0)."""
    n = 0
    while v > 0:
        v >>= 1
        n += 1
    return n


@njit(cache=True, inline="always")
def _free_line(
    lf: NDArray[np.float64],
    sf: NDArray[np.uint8],
    W: int,
    base: int,
    r0: int,
    c0: int,
    r1: int,
    c1: int,
    d_miss: float,
    lo: float,
    hi: float,
) -> None:
    """Miss update along the canonical Bresenham line between two in-grid cells (flat arrays, row stride W).

    The minor offset of step i is floor((2·i·d_minor + d_major − 1) / (2·d_major)) (the rule of
    :mod:`mjnav.mapping.lines`), evaluated without division as (num·m) >> s with the round-up reciprocal
    m = ceil(2^s / d), s = bits(num_max) + bits(d), exact for every num < 2^bits(num_max) (Granlund &
    Montgomery, 1994). Every step is then independent of the previous one (no loop-carried error term, no
    unpredictable branch). Lines too long for 64-bit products use the classic error-term recurrence (stepped
    branch-free).
    """
    adr = abs(r1 - r0)
    adc = abs(c1 - c0)
    if adc >= adr:
        if c1 < c0:
            r0, c0, r1, c1 = r1, c1, r0, c0
        minor_stride = W if r1 >= r0 else -W
        major_stride = 1
        n = adc
        dm = adr
    else:
        if r1 < r0:
            r0, c0, r1, c1 = r1, c1, r0, c0
        minor_stride = 1 if c1 >= c0 else -1
        major_stride = W
        n = adr
        dm = adc
    start = r0 * W + c0
    b = np.uint8(base)
    done = np.uint8(base + 2)
    num = max(n - 1, 0)  # 2·i·dm + n − 1 at i = 0
    two_dm = 2 * dm
    d = 2 * max(n, 1)
    nbits = _bit_length(two_dm * n + n)
    if nbits <= 30:
        shift = nbits + _bit_length(d)
        mult = ((1 << shift) + d - 1) // d
        for i in range(n + 1):
            idx = start + i * major_stride + ((num * mult) >> shift) * minor_stride
            if sf[idx] < b:
                lf[idx] = min(max(lf[idx] + d_miss, lo), hi)
                sf[idx] = done
            num += two_dm
    else:
        idx = start
        for _ in range(n + 1):
            if sf[idx] < b:
                lf[idx] = min(max(lf[idx] + d_miss, lo), hi)
                sf[idx] = done
            num += two_dm
            step = num >= d
            num -= d * step
            idx += major_stride + minor_stride * step


@njit(cache=True)
def _grazing_stop(ends: NDArray[np.float64], k: int, dx: float, dy: float, margin: float) -> float:
    """How much of return k's beam (unit direction (dx, dy)) runs within ``margin`` of the surface it ends on.

    The surface's direction at the return is taken towards each neighbouring return (k − 1, k + 1); with α the
    angle between the beam and the surface, the beam's last ``margin / sin α`` lies within ``margin`` of it. The
    steeper side counts (a neighbour on another surface, behind an edge, makes its side look shallow). A beam
    that grazes a wall (α small) passes through the cells of the wall's face before it ends further along: its
    misses would clear that face wherever no return of the same scan ends, opening holes that the planner takes
    for a way through the wall. Without a neighbouring return the margin itself is left out.
    """
    sin_a = 0.0
    found = False
    for j in (k - 1, k + 1):
        if 0 <= j < ends.shape[0] and not math.isnan(ends[j, 0]):
            tx = ends[j, 0] - ends[k, 0]
            ty = ends[j, 1] - ends[k, 1]
            d = math.hypot(tx, ty)
            if d > 0.0:
                found = True
                sin_a = max(sin_a, abs(dx * ty - dy * tx) / d)
    if not found:
        return margin
    return margin / max(sin_a, 1e-12)


@njit(cache=True)
def _scan_kernel(
    log_odds: NDArray[np.float64],
    stamp: NDArray[np.uint8],
    base: int,
    sx: float,
    sy: float,
    theta: float,
    angles: NDArray[np.float64],
    ranges: NDArray[np.float64],
    marks: NDArray[np.bool_],
    inv_res: float,
    max_range: float,
    min_range: float,
    d_hit: float,
    d_miss: float,
    lo: float,
    hi: float,
    trig_angles: NDArray[np.float64],
    trig_cos: NDArray[np.float64],
    trig_sin: NDArray[np.float64],
    grazing: float,
) -> None:
    """Update ``log_odds`` in place with one scan. Positions, ``max_range``, ``min_range`` and ``grazing`` are
    in cell units (1 cell = res metres); ``ranges`` are metres and are multiplied by ``inv_res``.

    ``stamp`` dedups per scan (1 <= base <= 252): values < base are untouched this scan, base itself the end
    cell of a beam with ``marks[k]`` False (no miss, no hit unless another beam ends there), base + 1 a pending
    hit, base + 2 a cell already updated. Each cell gets at most one update per scan; a hit beats a
    pass-through. ``trig_*`` cache cos/sin of the beam angles between calls (recomputed where the angle
    changed). ``grazing`` > 0: a return's free cells stop where its beam comes within ``grazing`` of the surface
    it ends on (:func:`_grazing_stop`).
    """
    H, W = log_odds.shape
    lf = log_odds.reshape(-1)
    sf = stamp.reshape(-1)
    b = np.uint8(base)
    pending = np.uint8(base + 1)
    done = np.uint8(base + 2)
    n = angles.shape[0]
    seg = np.empty((n, 4), dtype=np.int64)
    hit = np.zeros(n, dtype=np.bool_)
    hit_cell = np.empty(n, dtype=np.int64)
    valid = np.zeros(n, dtype=np.bool_)
    ends = np.full((n, 2), np.nan)  # every return's end point (NaN: no return), for the surfaces' directions
    cut = np.zeros(n)  # how much of each beam's end its free cells leave out
    ct = math.cos(theta)
    st = math.sin(theta)
    fw = float(W)
    fh = float(H)
    # Pass 1: each beam's direction and length; the end points of returns.
    live = np.zeros(n, dtype=np.bool_)
    length = np.zeros(n)
    dirs = np.zeros((n, 2))
    for k in range(n):
        ak = angles[k]
        r = ranges[k] * inv_res
        if not math.isfinite(ak) or r < min_range or r <= 0.0:
            continue  # -inf "too close", below min range, bad angle: no information (NaN compares false: kept)
        if ak != trig_angles[k]:
            trig_angles[k] = ak
            trig_cos[k] = math.cos(ak)
            trig_sin[k] = math.sin(ak)
        dirs[k, 0] = ct * trig_cos[k] - st * trig_sin[k]
        dirs[k, 1] = st * trig_cos[k] + ct * trig_sin[k]
        if r >= max_range or math.isnan(r):  # +inf or NaN: no return within range, free up to max range
            r = max_range
        else:
            ends[k, 0] = sx + r * dirs[k, 0]
            ends[k, 1] = sy + r * dirs[k, 1]
        length[k] = r
        live[k] = True
    if grazing > 0.0:
        for k in range(n):
            if not math.isnan(ends[k, 0]):
                cut[k] = _grazing_stop(ends, k, dirs[k, 0], dirs[k, 1], grazing)
    # Pass 1b: pending hits; free segments clipped to the grid rectangle.
    for k in range(n):
        if not live[k]:
            continue
        dx = dirs[k, 0]
        dy = dirs[k, 1]
        if not math.isnan(ends[k, 0]):
            r1 = math.floor(ends[k, 1])
            c1 = math.floor(ends[k, 0])
            if 0 <= r1 < H and 0 <= c1 < W:  # a return outside the grid marks nothing
                idx = r1 * W + c1
                if marks[k]:
                    hit[k] = True
                    hit_cell[k] = idx
                    if sf[idx] <= b:
                        sf[idx] = pending
                elif sf[idx] < b:
                    sf[idx] = b
        free = length[k] - cut[k]
        if free <= 0.0:
            continue  # the whole beam grazes its surface: it frees nothing
        ex = sx + free * dx
        ey = sy + free * dy
        ok, t0, t1 = _clip_segment(sx, sy, ex, ey, 0.0, fw, 0.0, fh)
        if not ok:
            continue
        bx = sx
        by = sy
        if t0 > 0.0:
            bx = sx + t0 * (ex - sx)
            by = sy + t0 * (ey - sy)
        if t1 < 1.0:
            ex = sx + t1 * (ex - sx)
            ey = sy + t1 * (ey - sy)
        # Clipped points lie on the closed rectangle; clamp the cells on its far edges (x = W, y = H) inward.
        seg[k, 0] = min(max(math.floor(by), 0), H - 1)
        seg[k, 1] = min(max(math.floor(bx), 0), W - 1)
        seg[k, 2] = min(max(math.floor(ey), 0), H - 1)
        seg[k, 3] = min(max(math.floor(ex), 0), W - 1)
        valid[k] = True
    # Pass 2: free cells along each beam (canonical Bresenham, see mjnav.mapping.lines).
    for k in range(n):
        if valid[k]:
            _free_line(lf, sf, W, base, seg[k, 0], seg[k, 1], seg[k, 2], seg[k, 3], d_miss, lo, hi)
    # Pass 3: hits, once per cell.
    for k in range(n):
        if hit[k]:
            idx = hit_cell[k]
            if sf[idx] == pending:
                lf[idx] = min(max(lf[idx] + d_hit, lo), hi)
                sf[idx] = done


# ---------------------------------------------------------------------------------------------------------
# Grid
# ---------------------------------------------------------------------------------------------------------


#: Longest max range, and farthest sensor position, integrate_scan accepts, in cells.
_MAX_RANGE_CELLS = 1e12


def _positive_int(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise InvalidGridError(f"{name} must be an integer, got {value!r} ({type(value).__name__})")
    v = int(value)
    if v <= 0:
        raise InvalidGridError(f"{name} must be positive (an empty map is not allowed), got {v}")
    return v


def _pose_tuple(pose: Pose2D | ArrayLike) -> tuple[float, float, float]:
    if isinstance(pose, Pose2D):
        return pose.x, pose.y, pose.theta
    if isinstance(pose, tuple) and len(pose) == 3 and all(type(v) is float for v in pose):
        if not all(math.isfinite(v) for v in pose):
            raise InvalidPoseError(f"pose must be finite, got {pose}")
        return pose[0], pose[1], pose[2]
    try:
        v = np.asarray(pose, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InvalidPoseError(f"pose must be (x, y, theta) numbers, got {pose!r}") from exc
    if v.shape != (3,):
        raise InvalidPoseError(f"pose must have 3 values (x, y, theta), got {v.shape[0]}")
    if not np.all(np.isfinite(v)):
        raise InvalidPoseError(f"pose must be finite, got {tuple(float(a) for a in v)}")
    return float(v[0]), float(v[1]), float(v[2])


def _beam_array(values: ArrayLike, name: str) -> NDArray[np.float64]:
    if isinstance(values, np.ndarray) and values.dtype == np.float64 and values.ndim == 1:
        return np.ascontiguousarray(values)
    try:
        a = np.asarray(values)
    except (TypeError, ValueError) as exc:
        raise InvalidGridError(f"{name} must be a 1-D numeric array") from exc
    if a.ndim != 1:
        raise InvalidGridError(f"{name} must be 1-D, got shape {a.shape}")
    if a.dtype.kind not in "iuf":
        raise InvalidGridError(f"{name} must be a real numeric array, got dtype {a.dtype}")
    return np.ascontiguousarray(a, dtype=np.float64)


class OccupancyGrid:
    """A 2-D log-odds occupancy grid (see the module docstring for indexing and the filter).

    Args:
        width_cells: number of columns W (> 0).
        height_cells: number of rows H (> 0).
        resolution_m: cell edge length, metres (> 0).
        origin_m: (x, y) world position of the outer corner of cell (0, 0), metres (the ROS ``info.origin``;
            the grid is not rotated).
        hit_log_odds: l_cell of the end cell of a beam; see :class:`LogOddsModel` for this and the following
            keyword parameters and their defaults.
        miss_log_odds: l_cell of a cell a beam passes through.
        prior_log_odds: l_0, also the initial value of every cell.
        min_log_odds: lower clamp bound.
        max_log_odds: upper clamp bound.
        free_threshold: log-odds below which a cell is FREE (default −1.9956).
        occupied_threshold: log-odds above which a cell is OCCUPIED (default +1.9956).

    Attributes:
        log_odds: (H, W) float64 log-odds, row 0 = lowest y. Mutable in place; derived views are recomputed on
            every call.
        model: the :class:`LogOddsModel` in use.

    Raises:
        InvalidGridError: a dimension is not a positive integer.
        InvalidParameterError: resolution/origin not finite or resolution <= 0, or an invalid model.
    """

    def __init__(
        self,
        width_cells: int,
        height_cells: int,
        resolution_m: float,
        origin_m: tuple[float, float] | ArrayLike = (0.0, 0.0),
        *,
        hit_log_odds: float = DEFAULT_HIT_LOG_ODDS,
        miss_log_odds: float = DEFAULT_MISS_LOG_ODDS,
        prior_log_odds: float = DEFAULT_PRIOR_LOG_ODDS,
        min_log_odds: float = DEFAULT_MIN_LOG_ODDS,
        max_log_odds: float = DEFAULT_MAX_LOG_ODDS,
        free_threshold: float = DEFAULT_FREE_THRESHOLD,
        occupied_threshold: float = DEFAULT_OCCUPIED_THRESHOLD,
    ) -> None:
        self._width = _positive_int(width_cells, "width_cells")
        self._height = _positive_int(height_cells, "height_cells")
        res = _finite(resolution_m, "resolution_m")
        if res <= 0.0:
            raise InvalidParameterError(f"resolution_m must be > 0, got {res}")
        self._resolution = res
        try:
            o = np.asarray(origin_m, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise InvalidParameterError(f"origin_m must be (x, y), got {origin_m!r}") from exc
        if o.shape != (2,) or not np.all(np.isfinite(o)):
            raise InvalidParameterError(f"origin_m must be 2 finite numbers (x, y), got {origin_m!r}")
        self._origin = (float(o[0]), float(o[1]))
        self.model = LogOddsModel(
            hit_log_odds=hit_log_odds,
            miss_log_odds=miss_log_odds,
            prior_log_odds=prior_log_odds,
            min_log_odds=min_log_odds,
            max_log_odds=max_log_odds,
            free_threshold=free_threshold,
            occupied_threshold=occupied_threshold,
        )
        self._log_odds = np.full((self._height, self._width), self.model.prior_log_odds, dtype=np.float64)
        self._stamp = np.zeros((self._height, self._width), dtype=np.uint8)
        self._scan_count = 0
        self._trig: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] = (
            np.empty(0),
            np.empty(0),
            np.empty(0),
        )

    # -- construction from ROS data --------------------------------------------------------------------------

    @classmethod
    def from_ros(
        cls,
        data: ArrayLike,
        width_cells: int,
        height_cells: int,
        resolution_m: float,
        origin_m: tuple[float, float] | ArrayLike = (0.0, 0.0),
        **model: float,
    ) -> OccupancyGrid:
        """Grid initialised from ROS occupancy values (a prior map, e.g. from map_server).

        Each known value v ∈ [0, 100] becomes ln(p / (1 − p)) with p = v / 100, clamped to the model's bounds
        (so 0 → ``min_log_odds``, 100 → ``max_log_odds``); −1 (unknown) becomes ``prior_log_odds``. Hence
        :meth:`to_ros` reproduces every value whose log-odds lies strictly within the clamp bounds, except
        that a value equal to the prior (50 for the default prior 0) reads back as −1.

        Args:
            data: ROS occupancy values, integer dtype, either flat (H·W,) in ``nav_msgs/OccupancyGrid`` data
                order or (H, W) with row 0 = lowest y.
            width_cells: W (``info.width``).
            height_cells: H (``info.height``).
            resolution_m: cell size, metres.
            origin_m: (x, y) of the corner of cell (0, 0), metres.
            **model: keyword parameters of :class:`LogOddsModel`.

        Returns:
            The new grid.

        Raises:
            InvalidGridError: wrong dtype (not integer), wrong size, values outside {−1} ∪ [0, 100].
        """
        grid = cls(width_cells, height_cells, resolution_m, origin_m, **model)
        arr = np.asarray(data)
        if arr.dtype.kind not in "iu":
            raise InvalidGridError(f"ROS occupancy data must have an integer dtype (int8), got {arr.dtype}")
        if arr.size != grid._width * grid._height or arr.ndim not in (1, 2):
            raise InvalidGridError(
                f"ROS occupancy data has shape {arr.shape}, expected ({grid._height * grid._width},) or "
                f"({grid._height}, {grid._width})"
            )
        if arr.ndim == 2 and arr.shape != (grid._height, grid._width):
            raise InvalidGridError(f"ROS occupancy data has shape {arr.shape}, expected {grid.shape}")
        v = arr.reshape(grid._height, grid._width).astype(np.int64)
        if np.any((v < -1) | (v > 100)):
            raise InvalidGridError("ROS occupancy values must be -1 (unknown) or 0..100")
        m = grid.model
        lo = np.clip(prob_to_log_odds(np.clip(v, 0, 100) / 100.0), m.min_log_odds, m.max_log_odds)
        grid._log_odds[...] = np.where(v < 0, m.prior_log_odds, lo)
        return grid

    @classmethod
    def from_ros_map(cls, ros_map: RosMap, **model: float) -> OccupancyGrid:
        """Grid initialised from a map read by :func:`~mjnav.mapping.read_ros_map` (see :meth:`from_ros`).

        Raises:
            InvalidParameterError: the map's origin has a non-zero yaw (rotated grids are not supported).
        """
        x, y, yaw = ros_map.origin_m
        if yaw != 0.0:
            raise InvalidParameterError(f"rotated map origins are not supported (yaw = {yaw} rad)")
        h, w = ros_map.occupancy.shape
        return cls.from_ros(ros_map.occupancy, w, h, ros_map.resolution_m, (x, y), **model)

    def copy(self) -> OccupancyGrid:
        """An independent copy (same geometry, model and log-odds)."""
        new = OccupancyGrid(self._width, self._height, self._resolution, self._origin, **_model_kwargs(self.model))
        new._log_odds[...] = self._log_odds
        return new

    def grown_to(self, x_min: float, y_min: float, x_max: float, y_max: float) -> OccupancyGrid:
        """This grid extended to cover the rectangle [x_min, x_max] × [y_min, y_max] (metres, map frame) as well.

        The new grid lies on the same cells (its origin moves by whole cells), keeps every log-odds value, and
        starts the added cells at the prior; with nothing to add it is this grid itself. A map that grows with
        what is seen (Nav2's static layer resizing to the map it receives) costs memory in proportion to the area
        covered.

        Raises:
            InvalidParameterError: a bound is not finite, or x_max < x_min or y_max < y_min.
        """
        bounds = [
            _finite(v, name) for v, name in ((x_min, "x_min"), (y_min, "y_min"), (x_max, "x_max"), (y_max, "y_max"))
        ]
        if bounds[2] < bounds[0] or bounds[3] < bounds[1]:
            raise InvalidParameterError(f"empty rectangle x {x_min}..{x_max}, y {y_min}..{y_max}")
        res, (ox, oy) = self._resolution, self._origin
        c0 = min(0, math.floor((bounds[0] - ox) / res))
        r0 = min(0, math.floor((bounds[1] - oy) / res))
        c1 = max(self._width, math.ceil((bounds[2] - ox) / res))
        r1 = max(self._height, math.ceil((bounds[3] - oy) / res))
        if (c0, r0, c1, r1) == (0, 0, self._width, self._height):
            return self
        new = OccupancyGrid(c1 - c0, r1 - r0, res, (ox + c0 * res, oy + r0 * res), **_model_kwargs(self.model))
        new._log_odds[-r0 : -r0 + self._height, -c0 : -c0 + self._width] = self._log_odds
        return new

    # -- geometry --------------------------------------------------------------------------------------------

    @property
    def width_cells(self) -> int:
        """Number of columns W."""
        return self._width

    @property
    def height_cells(self) -> int:
        """Number of rows H."""
        return self._height

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W)."""
        return (self._height, self._width)

    @property
    def resolution_m(self) -> float:
        """Cell edge length, metres."""
        return self._resolution

    @property
    def origin_m(self) -> tuple[float, float]:
        """(x, y) of the outer corner of cell (0, 0), metres."""
        return self._origin

    @property
    def extent_m(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of the area the grid covers, metres."""
        ox, oy = self._origin
        return (ox, ox + self._width * self._resolution, oy, oy + self._height * self._resolution)

    @property
    def log_odds(self) -> NDArray[np.float64]:
        """(H, W) float64 log-odds array (the filter state; modify in place only)."""
        return self._log_odds

    def contains(self, x: float, y: float) -> bool:
        """True if world point (x, y) (metres) lies in a cell of the grid; False for NaN/inf."""
        try:
            x = float(x)
            y = float(y)
        except (TypeError, ValueError) as exc:
            raise InvalidPoseError(f"point must be two real numbers, got ({x!r}, {y!r})") from exc
        ox, oy = self._origin
        col = math.floor((x - ox) / self._resolution) if math.isfinite(x) else -1
        row = math.floor((y - oy) / self._resolution) if math.isfinite(y) else -1
        return 0 <= row < self._height and 0 <= col < self._width

    def world_to_cell(self, x: float, y: float) -> tuple[int, int]:
        """Cell holding world point (x, y).

        Args:
            x: metres, map frame.
            y: metres, map frame.

        Returns:
            (row, col) with row = floor((y − oy)/res), col = floor((x − ox)/res).

        Raises:
            InvalidPoseError: x or y is NaN/inf or not a real number.
            OutsideMapError: the point is outside the grid.
        """
        try:
            xf = float(x)
            yf = float(y)
        except (TypeError, ValueError) as exc:
            raise InvalidPoseError(f"point must be two real numbers, got ({x!r}, {y!r})") from exc
        if not (math.isfinite(xf) and math.isfinite(yf)):
            raise InvalidPoseError(f"point must be finite, got ({xf}, {yf})")
        ox, oy = self._origin
        row = math.floor((yf - oy) / self._resolution)
        col = math.floor((xf - ox) / self._resolution)
        if not (0 <= row < self._height and 0 <= col < self._width):
            raise OutsideMapError((row, col), self.shape)
        return row, col

    def cell_to_world(self, row: int, col: int) -> tuple[float, float]:
        """World position of the centre of a cell.

        Args:
            row: cell row (0 = lowest y).
            col: cell column (0 = lowest x).

        Returns:
            (x, y) metres: (ox + (col + ½)·res, oy + (row + ½)·res).

        Raises:
            OutsideMapError: the cell is not in the grid.
            InvalidParameterError: row or col is not an integer.
        """
        if isinstance(row, bool) or isinstance(col, bool):
            raise InvalidParameterError("row and col must be integers")
        if not isinstance(row, int | np.integer) or not isinstance(col, int | np.integer):
            raise InvalidParameterError(f"row and col must be integers, got {row!r}, {col!r}")
        r, c = int(row), int(col)
        if not (0 <= r < self._height and 0 <= c < self._width):
            raise OutsideMapError((r, c), self.shape)
        ox, oy = self._origin
        return (ox + (c + 0.5) * self._resolution, oy + (r + 0.5) * self._resolution)

    # -- derived views ---------------------------------------------------------------------------------------

    def probabilities(self) -> NDArray[np.float64]:
        """(H, W) float64 occupancy probabilities 1 / (1 + exp(−l))."""
        return log_odds_to_prob(self._log_odds)

    def states(self) -> NDArray[np.int8]:
        """(H, W) int8 :class:`CellState` values: OCCUPIED (100) where l > occupied_threshold, FREE (0) where
        l < free_threshold, UNKNOWN (−1) otherwise. This is also a valid trinary ROS occupancy array."""
        m = self.model
        out = np.full(self.shape, CellState.UNKNOWN, dtype=np.int8)
        out[self._log_odds < m.free_threshold] = CellState.FREE
        out[self._log_odds > m.occupied_threshold] = CellState.OCCUPIED
        return out

    def to_ros(self, *, trinary: bool = False) -> NDArray[np.int8]:
        """ROS ``nav_msgs/OccupancyGrid`` values.

        Args:
            trinary: False (default): round(100·p) in 0..100 for every cell whose log-odds differ from
                the prior, −1 where they equal it (never observed, or no net evidence); rounding is
                half-to-even.
                True: :meth:`states` (0 free, 100 occupied, −1 unknown by the thresholds).

        Returns:
            (H, W) int8, row 0 = lowest y; ``.ravel()`` is the message's ``data`` field (row-major).
        """
        if trinary:
            return self.states()
        p = np.rint(100.0 * self.probabilities()).astype(np.int8)
        p[self._log_odds == self.model.prior_log_odds] = -1
        return p

    # -- update ----------------------------------------------------------------------------------------------

    def integrate_scan(
        self,
        pose: Pose2D | ArrayLike,
        angles_rad: ArrayLike,
        ranges_m: ArrayLike,
        max_range_m: float,
        *,
        min_range_m: float = 0.0,
        marks: ArrayLike | None = None,
        grazing_margin_m: float = 0.0,
    ) -> None:
        """Fuse one planar range scan into the grid (in place).

        Each beam k leaves the sensor at world heading θ + angles_rad[k] and is traced with the Bresenham
        rule of :mod:`mjnav.mapping.lines` from the sensor's cell to its end cell. Per scan, every cell
        receives **at most one** update: l_hit if any beam ends in it, otherwise l_miss if any beam crosses
        it (the OctoMap rule; a hit wins over a pass-through, so grazing beams do not erase walls, and cells
        near the sensor are not over-counted by the many beams crossing them).

        Beam handling (REP-117 semantics for special values):

        * ``min_range_m <= r < max_range_m`` (finite): free cells from the sensor up to the end cell, end
          cell hit.
        * ``r >= max_range_m``, ``+inf`` or NaN (no return within range): free cells up to max range, no hit.
          (REP-117 reads NaN as an invalid measurement; mjnav treats it as no return, as its spec asks, so a
          sensor that reports nothing-in-range as NaN still clears free space.)
        * ``−inf`` (too close to measure), ``r < min_range_m`` or ``r <= 0``: beam skipped.
        * NaN/inf beam angle: beam skipped.

        Beams are clipped at the map edge: each beam segment is clipped to the grid rectangle (Liang–Barsky)
        before it is rasterised between the cells of the clipped end points, so a beam ending outside the grid
        marks no hit, and a sensor outside the grid still updates the part of each beam inside it. Work per
        beam is bounded by the grid size whatever ``max_range_m`` is. For beams that stay inside the grid the
        traced cells are exactly ``bresenham(sensor cell, end cell)``.

        Args:
            pose: sensor pose (x, y, θ) in the map frame (metres, radians): a
                :class:`~mjnav.geometry.Pose2D` or a length-3 sequence/array.
            angles_rad: (N,) beam angles relative to the sensor heading, radians.
            ranges_m: (N,) measured ranges, metres (same length as ``angles_rad``).
            max_range_m: sensor maximum range, metres (finite, > 0).
            min_range_m: sensor minimum range, metres (>= 0); shorter readings are skipped.
            marks: (N,) bool, default all True. A beam with False is clearing-only (Nav2's obstacle layer has
                marking and clearing sources; a moving obstacle's return is the case here): it frees the cells
                before its end cell and leaves the end cell as it is (unless another beam ends there).
            grazing_margin_m: > 0: a return frees no cell where its beam runs within this distance of the surface
                it ends on (the surface's direction from the neighbouring returns; the last
                ``grazing_margin_m / sin α`` of a beam meeting it at angle α). A beam grazing a wall otherwise
                crosses the cells of the wall's face before it ends further along, and its misses clear the face
                wherever no return of the same scan ends: holes a planner takes for a way through. 0 (default):
                the textbook update above.

        Raises:
            InvalidPoseError: the pose has NaN/inf or not 3 components.
            InvalidGridError: angles/ranges are not 1-D real arrays of equal length, or marks is not a bool array
                of their length.
            InvalidParameterError: max_range_m not finite/positive or over 1e12 cells, or min_range_m or
                grazing_margin_m negative/non-finite.

        A sensor more than 1e12 cells from the grid origin cannot reach it within ``max_range_m``; such a
        scan is a no-op.
        """
        x, y, theta = _pose_tuple(pose)
        angles = _beam_array(angles_rad, "angles_rad")
        ranges = _beam_array(ranges_m, "ranges_m")
        if angles.shape != ranges.shape:
            raise InvalidGridError(
                f"angles_rad and ranges_m must have the same length, got {angles.shape[0]} and {ranges.shape[0]}"
            )
        if marks is None:
            mark = np.ones(angles.shape[0], dtype=np.bool_)
        else:
            mark = np.asarray(marks)
            if mark.dtype != np.bool_ or mark.shape != angles.shape:
                raise InvalidGridError(
                    f"marks must be a bool array of shape {angles.shape}, got {mark.dtype} {mark.shape}"
                )
        max_r = _finite(max_range_m, "max_range_m")
        if max_r <= 0.0:
            raise InvalidParameterError(f"max_range_m must be > 0, got {max_r}")
        min_r = _finite(min_range_m, "min_range_m")
        if min_r < 0.0:
            raise InvalidParameterError(f"min_range_m must be >= 0, got {min_r}")
        grazing = _finite(grazing_margin_m, "grazing_margin_m")
        if grazing < 0.0:
            raise InvalidParameterError(f"grazing_margin_m must be >= 0, got {grazing}")
        inv_res = 1.0 / self._resolution
        if max_r * inv_res > _MAX_RANGE_CELLS:
            raise InvalidParameterError(
                f"max_range_m = {max_r} is {max_r * inv_res:.3g} cells, more than {_MAX_RANGE_CELLS:.0e}"
            )
        ox, oy = self._origin
        sx = (x - ox) * inv_res
        sy = (y - oy) * inv_res
        if angles.shape[0] == 0 or not (abs(sx) <= _MAX_RANGE_CELLS and abs(sy) <= _MAX_RANGE_CELLS):
            return  # nothing to fuse, or a sensor so far away that no beam can reach the grid
        # Per-scan dedup stamps: 3·j for j = 1..84 fit uint8 (≤ 254); the array is cleared when j wraps.
        self._scan_count = self._scan_count % 84 + 1
        if self._scan_count == 1:
            self._stamp.fill(0)
        base = 3 * self._scan_count
        m = self.model
        _scan_kernel(
            self._log_odds,
            self._stamp,
            base,
            sx,
            sy,
            theta,
            angles,
            ranges,
            mark,
            inv_res,
            max_r * inv_res,
            min_r * inv_res,
            m.hit_log_odds - m.prior_log_odds,
            m.miss_log_odds - m.prior_log_odds,
            m.min_log_odds,
            m.max_log_odds,
            *self._trig_cache(angles.shape[0]),
            grazing * inv_res,
        )

    def _trig_cache(self, n: int) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(angles, cos, sin) arrays of length n the kernel keeps up to date (NaN angles force a refresh)."""
        if self._trig[0].shape[0] != n:
            self._trig = (np.full(n, np.nan), np.zeros(n), np.zeros(n))
        return self._trig

    def __repr__(self) -> str:
        return (
            f"OccupancyGrid(width_cells={self._width}, height_cells={self._height}, "
            f"resolution_m={self._resolution}, origin_m={self._origin})"
        )


def _model_kwargs(model: LogOddsModel) -> Mapping[str, float]:
    """Keyword arguments reproducing ``model`` (for constructors)."""
    return {name: getattr(model, name) for name in model.__slots__}

"""Online 2-D graph SLAM on laser scans and wheel odometry, and localization on a saved map.

:class:`GraphSlam` is fed one scan at a time (:meth:`GraphSlam.update`) with the wheel-odometry pose of the robot
at the scan's time; it returns the pose in the ``map`` frame with a covariance and keeps a pose graph of keyframes.

Front end (every scan): the odometry increment since the previous scan predicts the pose; the scan is matched
against a *local map* (the points of the last ``local_map_keyframes`` keyframes at their current estimates) by
correlative scan matching (Olson 2009: branch and bound over a rasterised likelihood field, a small window around
the prediction) and the result refined by point-to-line ICP (Censi 2008) against the same points. A scan becomes
a keyframe when the robot has moved ``keyframe_distance_m`` or turned ``keyframe_angle_rad`` since the last one;
consecutive keyframes are joined by an edge carrying the front end's relative pose.

Back end (every keyframe): every ``submap_keyframes`` consecutive keyframes form a rigid *submap* (their points in
the frame of its first keyframe, the anchor), with the space its scans observed (free or hit, a coarse grid). A new
keyframe is matched against finished submaps whose keyframes lie within ``loop_search_radius_m`` of it (excluding
the keyframes of the local map) and whose observed space holds at least ``loop_min_overlap`` of its scan at the
current estimate (largest overlap first, at most ``loop_candidates`` per keyframe), by the multi-resolution branch
and bound of Hess et al. (ICRA 2016) on a coarse likelihood field, then refined by point-to-line ICP; it is accepted
when the correlative score and the ICP inlier share pass their thresholds. Both scores are taken over the scan points
inside the submap's observed space only: a partial view (the far end of a corridor mapped earlier) can close a loop,
and points in space the submap never saw neither support nor excuse a match, while a scan from the next corridor,
whose walls line up with the submap's a corridor width aside, is scored against what the submap saw there and
fails (tests/estimation/test_slam.py: scored over the whole scan, most such closures were accepted).
The search window of a candidate follows how uncertain the keyframe's pose is relative
to the submap's anchor: ``loop_window_sigmas`` standard deviations of the edge variances summed along the least
uncertain chain of graph edges between them (Dijkstra), clamped between ``loop_min_window_*`` and ``loop_window_*``.
A place first revisited after a long loop gets the wide window; once a closure has joined the two passes, the next
keyframes there are searched in a small one, which is most of the loop-search time saved. An accepted match is a
loop-closure edge (anchor → keyframe); the pose graph is then optimised (sparse Levenberg–Marquardt with CHOLMOD,
Huber kernel, from the current poses; :func:`~mjnav.estimation.posegraph.optimize_pose_graph`), the keyframes
move to the optimum, the local map is rebuilt from them and the occupancy grid is re-rendered from them on the
next request (:meth:`GraphSlam.occupancy_grid`).

Frames (REP-105): ``map`` is fixed; ``odom`` is where wheel odometry integrates; ``base_link`` is the robot. The
``map → odom`` transform is pose_map ∘ pose_odom⁻¹ (:meth:`GraphSlam.map_to_odom`). The laser sits at
``laser_offset`` in ``base_link``; every pose here is a ``base_link`` pose.

Edge information: a front-end edge over a relative motion of d metres and |Δθ| radians has at least the covariance
diag(σ_t², σ_t², σ_θ²) with σ_t² = ``edge_sigma_m``² + ``edge_sigma_per_m``²·d and
σ_θ² = ``edge_sigma_rad``² + ``edge_sigma_rad_per_rad``²·|Δθ|, raised to the front-end match's own covariance
(rotated into the edge's frame) where that is larger, with a direction the match cannot observe counted as one
dead-reckoned scan (0.05 m, 2°): along a corridor the edge stays soft and a loop closure, not the corridor's
ambiguous match, places the keyframe there. A loop edge has the covariance of its PL-ICP match, shape and
correlations kept but scaled so that its best-constrained translational direction has σ = ``loop_sigma_m`` (PL-ICP's
own σ, a few millimetres, is far too confident) and its heading σ at least ``loop_sigma_rad``: a closure in a
corridor, whose match slides along it, holds the keyframe across the corridor and hardly along it.

:class:`Localizer` tracks the pose on a fixed occupancy map from an initial pose and covariance (as RViz's
"2D Pose Estimate" sends it): odometry predicts the pose and grows the covariance; the scan is matched by branch
and bound against the map's likelihood field in a window of three standard deviations (clamped), then refined by
point-to-line ICP against the map's occupied cells.

Everything here is pure: numpy arrays and small frozen dataclasses in, the same out. Units are metres, radians and
seconds.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mjnav.estimation._graph_kernels import shortest_paths
from mjnav.estimation.errors import EstimationError
from mjnav.estimation.posegraph import PoseGraph, optimize_pose_graph
from mjnav.estimation.scan_matching import (
    CorrelativeGridMatcher,
    PointReference,
    ScanMatchError,
    likelihood_field,
    scan_to_points,
)
from mjnav.mapping import CellState, GridFrame, LogOddsModel, OccupancyGrid

__all__ = [
    "GraphSlam",
    "Localizer",
    "LocalizerConfig",
    "PoseEstimate",
    "SlamConfig",
    "SlamError",
    "compose",
    "invert",
    "relative",
]

FloatArray = NDArray[np.float64]


_DEAD_RECKONING_SIGMA = (0.05, math.radians(2.0))  # σ added to the pose of an unmatched scan (metres, radians)


class SlamError(EstimationError, ValueError):
    """Bad input to the SLAM or localization classes (a malformed scan or pose, an invalid configuration)."""


# ---------------------------------------------------------------------------------------------------------------
# SE(2) helpers (vectorised over leading axes)


def compose(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """a ∘ b of (..., 3) poses (x, y, θ): b expressed in a's frame, returned in a's parent frame."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    th = np.remainder(a[..., 2] + b[..., 2] + np.pi, 2.0 * np.pi) - np.pi
    return np.stack((x, y, th), axis=-1)


def invert(a: ArrayLike) -> FloatArray:
    """a⁻¹ of (..., 3) poses (x, y, θ)."""
    a = np.asarray(a, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -(c * a[..., 0] + s * a[..., 1])
    y = s * a[..., 0] - c * a[..., 1]
    return np.stack((x, y, -a[..., 2]), axis=-1)


def relative(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """a⁻¹ ∘ b of (..., 3) poses: b seen from a."""
    return compose(invert(a), b)


def _relative1(a: FloatArray, b: FloatArray) -> FloatArray:
    """a⁻¹ ∘ b of two single (3,) poses (:func:`relative` without the array overhead)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    th = (b[2] - a[2] + math.pi) % (2.0 * math.pi) - math.pi
    return np.array((c * dx + s * dy, -s * dx + c * dy, th))


def _compose1(a: FloatArray, b: FloatArray) -> FloatArray:
    """a ∘ b of two single (3,) poses (:func:`compose` without the array overhead)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    th = (a[2] + b[2] + math.pi) % (2.0 * math.pi) - math.pi
    return np.array((a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], th))


def _transform(pose: FloatArray, pts: FloatArray) -> FloatArray:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.column_stack((c * pts[:, 0] - s * pts[:, 1] + pose[0], s * pts[:, 0] + c * pts[:, 1] + pose[1]))


def _pose_arg(value: ArrayLike, name: str) -> FloatArray:
    try:
        p = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise SlamError(f"{name} must be (x, y, theta), got {value!r}") from exc
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise SlamError(f"{name} must be 3 finite numbers (x, y, theta), got {value!r}")
    return p


def _cov_arg(value: ArrayLike, name: str) -> FloatArray:
    try:
        c = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise SlamError(f"{name} must be a (3, 3) covariance") from exc
    if c.shape != (3, 3) or not np.all(np.isfinite(c)):
        raise SlamError(f"{name} must be a finite (3, 3) covariance, got shape {c.shape}")
    c = 0.5 * (c + c.T)
    if np.linalg.eigvalsh(c)[0] < -1e-12:
        raise SlamError(f"{name} must be positive semi-definite")
    return c


def _check_config(cfg: Any) -> None:
    for f in fields(cfg):
        v = getattr(cfg, f.name)
        if isinstance(v, bool) or not isinstance(v, int | float):
            continue
        if not math.isfinite(v):
            raise SlamError(f"{type(cfg).__name__}.{f.name} must be finite, got {v}")
        if v < 0 or (v == 0 and f.name not in _MAY_BE_ZERO):
            bound = ">= 0" if f.name in _MAY_BE_ZERO else "> 0"
            raise SlamError(f"{type(cfg).__name__}.{f.name} must be {bound}, got {v}")


_MAY_BE_ZERO = {
    "loop_candidates",
    "edge_sigma_per_m",
    "edge_sigma_rad_per_rad",
    "motion_sigma_per_m",
    "motion_sigma_rad_per_rad",
    "loop_min_separation_keyframes",
    "loop_min_travel_m",
    "loop_min_overlap",
    "optimize_min_chi2",
    "match_translation_cost",
    "match_rotation_cost",
}


def _floor_cov(cov: ArrayLike, sigma_m: float, sigma_rad: float) -> FloatArray:
    """Symmetrised covariance whose standard deviations are raised to at least (σ_m, σ_m, σ_rad), correlations
    kept."""
    c = np.asarray(cov, dtype=np.float64)
    c = 0.5 * (c + c.T)
    var = np.maximum(np.diag(c), 0.0)
    floor = np.array([sigma_m**2, sigma_m**2, sigma_rad**2])
    scale = np.sqrt(np.maximum(var, floor) / np.maximum(var, 1e-300))
    scale[var <= 0.0] = 1.0
    out = c * np.outer(scale, scale)
    out[np.diag_indices(3)] = np.maximum(var, floor)
    return out


@dataclass(frozen=True)
class PoseEstimate:
    """A pose estimate in the map frame.

    Attributes:
        pose: (3,) x, y (metres), θ (radians) of ``base_link`` in ``map``.
        covariance: (3, 3) covariance of ``pose`` (m², m·rad, rad²), order x, y, θ.
        map_to_odom: (3,) the ``map → odom`` transform (x, y, θ) that places the odometry pose at ``pose``.
        score: front-end match quality in [0, 1] (share of scan points with an ICP correspondence; 0 when the
            scan could not be matched and the pose is the odometry prediction).
        matched: True when the scan was matched, False when the pose is dead reckoning.
        keyframe: index of the keyframe this scan created, or −1.
        degenerate: the match pinned the pose only partly (a corridor: across it, not along it; the odometry
            carries the rest).
    """

    pose: FloatArray
    covariance: FloatArray
    map_to_odom: FloatArray
    score: float
    matched: bool
    keyframe: int = -1
    degenerate: bool = False


# ---------------------------------------------------------------------------------------------------------------
# Configuration


@dataclass(frozen=True)
class SlamConfig:
    """Parameters of :class:`GraphSlam` (defaults suit a 10 Hz indoor lidar with wheel odometry).

    Attributes:
        map_resolution_m: occupancy-grid cell size, metres.
        max_range_m: beams longer than this are neither matched nor marked as hits (the grid clears free space up
            to it), metres.
        laser_offset: (x, y, θ) of the laser in ``base_link``, metres and radians.
        match_resolution_m: cell of the front end's likelihood field, metres.
        match_window_m: front-end search half-width in x and y around the odometry prediction, metres.
        match_window_rad: front-end search half-width in θ, radians.
        match_angular_step_rad: angular step of the front end's correlative search, radians.
        match_translation_cost, match_rotation_cost: the front end's prior towards the odometry prediction (mean
            score per m² and per rad², :meth:`~mjnav.estimation.scan_matching.CorrelativeGridMatcher.match`).
            Without it, along a wall seen only side-on every offset scores alike and the search takes the first
            of them, a window's width (0.3 m) off (PL-ICP, flagging the match degenerate, then starts again
            from the prediction; a weaker feature may keep it from being flagged). 0.1 each, the weights of
            Cartographer's real-time matcher.
        icp_max_correspondence_m: PL-ICP correspondences farther than this are ignored, metres.
        min_match_inliers: a refined match with fewer than this share of scan points matched is rejected.
        keyframe_distance_m: a scan becomes a keyframe after this much translation since the last one, metres.
        keyframe_angle_rad: ... or this much rotation, radians.
        local_map_keyframes: keyframes in the front end's local map (the newest ones).
        submap_keyframes: consecutive keyframes per loop-closure submap.
        loop_search_radius_m: submaps with a keyframe this close to the new keyframe are loop candidates, metres.
        loop_candidates: at most this many candidate submaps are matched per keyframe (0 disables loop closure).
        loop_min_separation_keyframes: a submap is a candidate only when its last keyframe is at least this many
            keyframes older than the local map's oldest one ...
        loop_min_travel_m: ... and the robot has travelled at least this far since it (so a loop closure is a
            return to a place, not the corridor just driven), metres.
        loop_resolution_m: cell of the submaps' likelihood fields, metres.
        loop_window_m: loop search half-width in x and y, metres (the largest: the window of a candidate is
            ``loop_window_sigmas`` standard deviations of its pose relative to the new keyframe, along the least
            uncertain chain of graph edges, clamped to [``loop_min_window_m``, ``loop_window_m``]).
        loop_window_rad: loop search half-width in θ, radians (likewise, clamped to [``loop_min_window_rad``,
            ``loop_window_rad``]).
        loop_window_sigmas: loop search half-widths in standard deviations of the relative pose.
        loop_min_window_m: smallest loop search half-width in x and y, metres.
        loop_min_window_rad: smallest loop search half-width in θ, radians.
        loop_max_range_m: submap points and loop-scan points beyond this range from their keyframe are dropped,
            metres.
        loop_min_score: minimum mean likelihood (0..1) of an accepted loop match.
        loop_min_inliers: minimum PL-ICP inlier share of an accepted loop match.
        loop_min_overlap: a submap is a loop candidate when at least this share of the keyframe's scan (within
            ``loop_max_range_m``) falls, at the current estimate, in space the submap's scans observed; the match is
            scored on those points only. 0: every candidate within ``loop_search_radius_m``, nearest first, scored
            on the whole scan (the method before; on a scan from the neighbouring corridor it closes false loops).
        edge_sigma_m: front-end edge translational σ at zero motion, metres (a floor: the match's own σ counts
            where larger).
        edge_sigma_per_m: its growth: σ_t² = edge_sigma_m² + edge_sigma_per_m²·d, metres per √metre.
        edge_sigma_rad: front-end edge rotational σ at zero motion, radians.
        edge_sigma_rad_per_rad: its growth with the turned angle, √radians.
        loop_sigma_m: σ of a loop edge's best-constrained translational direction (the match covariance's shape
            sets the others), metres.
        loop_sigma_rad: floor of a loop edge's rotational σ, radians.
        optimize_min_chi2: the graph is optimised once the loop edges added since the last optimisation have a
            summed χ² error (under their information, at the current poses) above this; smaller disagreements
            wait for the next closure.
        min_sigma_m: floor of the reported translational standard deviation, metres.
        min_sigma_rad: floor of the reported rotational standard deviation, radians.
        cached_submaps: submap matchers kept in memory (least recently used are rebuilt when needed).
        map_model: the log-odds sensor model the map is rendered with. Its default weakens a miss to
            ln(0.45/0.55) ≈ −0.20 (OctoMap's −0.41 elsewhere), so a cell stays occupied when at least ~19 % of the
            scans that see it end in it. A beam that grazes a wall passes through the free sliver of the wall's
            face cells before it ends further along, and its traversal marks them free; seen at grazing angles a
            wall's face cells get more of those misses than hits, and with OctoMap's weights 7 % of the warehouse's
            observed wall cells ended below occupied (recall 0.926, seed 0; 0.967 with this model, precision
            0.998 → 0.994). SLAM maps are static maps: slam_toolbox (Karto) calls a cell occupied from a 10 % hit
            share, GMapping from 25 %.
    """

    map_resolution_m: float = 0.05
    max_range_m: float = 30.0
    laser_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    match_resolution_m: float = 0.05
    match_window_m: float = 0.3
    match_window_rad: float = math.radians(10.0)
    match_angular_step_rad: float = math.radians(0.5)
    match_translation_cost: float = 0.1
    match_rotation_cost: float = 0.1
    icp_max_correspondence_m: float = 0.3
    min_match_inliers: float = 0.3
    keyframe_distance_m: float = 0.3
    keyframe_angle_rad: float = math.radians(15.0)
    local_map_keyframes: int = 10
    submap_keyframes: int = 10
    loop_search_radius_m: float = 6.0
    loop_candidates: int = 2
    loop_min_separation_keyframes: int = 5
    loop_min_travel_m: float = 10.0
    loop_resolution_m: float = 0.1
    loop_window_m: float = 2.0
    loop_window_rad: float = math.radians(30.0)
    loop_window_sigmas: float = 3.0
    loop_min_window_m: float = 0.3
    loop_min_window_rad: float = math.radians(5.0)
    loop_max_range_m: float = 15.0
    loop_min_score: float = 0.5
    loop_min_inliers: float = 0.6
    loop_min_overlap: float = 0.3
    edge_sigma_m: float = 0.01
    edge_sigma_per_m: float = 0.02
    edge_sigma_rad: float = math.radians(0.25)
    edge_sigma_rad_per_rad: float = 0.02
    loop_sigma_m: float = 0.05
    loop_sigma_rad: float = math.radians(1.0)
    optimize_min_chi2: float = 1.0
    min_sigma_m: float = 0.005
    min_sigma_rad: float = math.radians(0.2)
    cached_submaps: int = 16
    map_model: LogOddsModel = field(default_factory=lambda: LogOddsModel(miss_log_odds=math.log(0.45 / 0.55)))

    def __post_init__(self) -> None:
        _check_config(self)
        if len(self.laser_offset) != 3 or not all(math.isfinite(v) for v in self.laser_offset):
            raise SlamError(f"SlamConfig.laser_offset must be 3 finite numbers, got {self.laser_offset!r}")
        for name in ("local_map_keyframes", "submap_keyframes", "loop_candidates", "cached_submaps"):
            if not isinstance(getattr(self, name), int):
                raise SlamError(f"SlamConfig.{name} must be an integer")
        for name in ("min_match_inliers", "loop_min_score", "loop_min_inliers", "loop_min_overlap"):
            if getattr(self, name) > 1.0:
                raise SlamError(f"SlamConfig.{name} must lie in [0, 1]")
        if self.match_window_rad > math.pi or self.loop_window_rad > math.pi:
            raise SlamError("angular windows must be at most pi")


# ---------------------------------------------------------------------------------------------------------------
# Scan input


@dataclass(frozen=True)
class _Scan:
    """One scan in the laser frame, with its points in base_link (valid beams only)."""

    ranges: FloatArray
    angles: FloatArray
    range_min: float
    range_max: float
    points: FloatArray  # (M, 2) base_link, beams within [range_min, min(range_max, cfg.max_range_m))


def _scan(
    ranges_m: ArrayLike,
    angles_rad: ArrayLike,
    range_min_m: float,
    range_max_m: float,
    max_range_m: float,
    laser_offset: tuple[float, float, float],
) -> _Scan:
    try:
        r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
        a = np.asarray(angles_rad, dtype=np.float64).reshape(-1)
        rmin, rmax = float(range_min_m), float(range_max_m)
    except (TypeError, ValueError) as exc:
        raise SlamError("ranges, angles and range limits must be numbers") from exc
    if r.shape != a.shape or r.size == 0:
        raise SlamError(f"ranges and angles must be non-empty and of equal length, got {r.size} and {a.size}")
    if not (math.isfinite(rmin) and math.isfinite(rmax) and 0.0 <= rmin < rmax):
        raise SlamError(f"need finite 0 <= range_min < range_max, got {rmin}, {rmax}")
    pts = scan_to_points(r, a, min_range_m=rmin, max_range_m=min(rmax, max_range_m))
    off = np.asarray(laser_offset, dtype=np.float64)
    if np.any(off != 0.0):
        pts = _transform(off, pts)
    return _Scan(r, a, rmin, rmax, pts)


# ---------------------------------------------------------------------------------------------------------------
# The SLAM


@dataclass
class _Submap:
    anchor: int  # keyframe index of the submap frame
    members: range  # keyframe indices
    points: FloatArray  # (P, 2) in the anchor's frame
    known: NDArray[np.bool_]  # (H, W) cells its scans observed (free or hit), anchor frame, loop_resolution_m cells
    known_origin: tuple[float, float]  # (x, y) outer corner of known's cell (0, 0) in the anchor frame, metres

    def observed(self, pts: FloatArray, resolution_m: float) -> NDArray[np.bool_]:
        """(P,) True where the points (anchor frame) fall in a cell the submap's scans observed."""
        h, w = self.known.shape
        col = np.floor((pts[:, 0] - self.known_origin[0]) / resolution_m).astype(np.int64)
        row = np.floor((pts[:, 1] - self.known_origin[1]) / resolution_m).astype(np.int64)
        inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
        out = np.zeros(pts.shape[0], dtype=bool)
        out[inside] = self.known[row[inside], col[inside]]
        return out


@dataclass
class _Graph:
    poses: list[FloatArray] = field(default_factory=list)
    edges: list[tuple[int, int]] = field(default_factory=list)
    measurements: list[FloatArray] = field(default_factory=list)
    information: list[FloatArray] = field(default_factory=list)
    loop: list[bool] = field(default_factory=list)
    var_t: list[float] = field(default_factory=list)  # per edge: translational variance (1 / information[0, 0])
    var_r: list[float] = field(default_factory=list)  # per edge: rotational variance (1 / information[2, 2])


class GraphSlam:
    """Incremental graph SLAM (see the module doc for the method).

    Args:
        config: parameters; default :class:`SlamConfig`.
        initial_pose: (x, y, θ) of ``base_link`` in ``map`` at the first scan; default the first odometry pose
            (``map`` and ``odom`` coincide at the start, REP-105).

    Typical use (a service or an offline run)::

        slam = GraphSlam()
        for t, odom, ranges, angles in scans:
            est = slam.update(t, odom, ranges, angles, range_min_m=0.1, range_max_m=12.0)
            publish(est.pose, est.covariance, est.map_to_odom)
        grid = slam.occupancy_grid()          # mjnav.mapping.OccupancyGrid, re-rendered after loop closures
    """

    def __init__(self, config: SlamConfig | None = None, *, initial_pose: ArrayLike | None = None) -> None:
        self.config = config or SlamConfig()
        self._initial = None if initial_pose is None else _pose_arg(initial_pose, "initial_pose")
        self._graph = _Graph()
        self._kf_scans: list[_Scan] = []
        self._kf_stamps: list[float] = []
        self._kf_travel: list[float] = []  # path length from the first keyframe, metres
        self._submaps: list[_Submap] = []
        self._submap_cache: OrderedDict[int, tuple[CorrelativeGridMatcher, PointReference]] = OrderedDict()
        self._local: tuple[CorrelativeGridMatcher, PointReference] | None = None
        self._pose = np.zeros(3)
        self._odom = np.zeros(3)
        self._cov = np.eye(3)
        self._stamps: list[float] = []
        self._scan_kf: list[int] = []
        self._scan_rel: list[FloatArray] = []
        self._loop_closures = 0
        self._optimizations = 0
        self._pending_chi2 = 0.0
        self._grid: OccupancyGrid | None = None
        self._grid_kfs = 0
        self._grid_dirty = True

    def reanchor(self, odom_pose: ArrayLike, pose: ArrayLike) -> None:
        """Continue from ``pose`` (``base_link`` in ``map``) at odometry ``odom_pose``: after the odometry was reset
        (a restarted driver or simulator) or the robot was carried off (kidnapped). The map and graph are kept; the
        next scan is predicted from here, and the next keyframe joins the graph with the jump as its odometry edge.

        Raises:
            SlamError: malformed pose.
        """
        self._odom = _pose_arg(odom_pose, "odom_pose")
        self._pose = _pose_arg(pose, "pose")

    # -- pickling (checkpoints) --------------------------------------------------------------------------------

    def __getstate__(self) -> dict[str, Any]:
        """The state without its caches: the front end's local map and the loop search's submap matchers are
        derived from the keyframes, and each matcher is ~1 MB (maze, 63 keyframes, 6 submap matchers cached: 8.3 MB
        and 17.5 ms to pickle with them, 1.6 MB and 5.8 ms without)."""
        state = self.__dict__.copy()
        state["_local"] = None
        state["_submap_cache"] = OrderedDict()
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        if self._graph.poses:
            # The same keyframes at the same poses as when it was last built (only a new keyframe moves poses).
            self._rebuild_local_map()

    #: State lists that only ever grow, their items never changed once made: the keyframes' scans and the finished
    #: submaps (the bulk of the state: 5.4 of 5.7 MB after 288 keyframes). A checkpoint writes each item once.
    APPEND_ONLY: tuple[str, ...] = ("_kf_scans", "_submaps")

    def split_state(self) -> tuple[dict[str, Any], dict[str, list[Any]]]:
        """The picklable state as (the rest, the :attr:`APPEND_ONLY` lists by name), for checkpoints that append
        the lists' new items and rewrite only the rest (:meth:`from_split_state` puts them together again)."""
        state = self.__getstate__()
        return state, {name: state.pop(name) for name in self.APPEND_ONLY}

    @classmethod
    def from_split_state(cls, state: dict[str, Any], lists: dict[str, list[Any]]) -> GraphSlam:
        """The SLAM :meth:`split_state` described, continuing exactly as the original would."""
        missing = set(cls.APPEND_ONLY) - set(lists)
        if missing:
            raise SlamError(f"split state lacks {sorted(missing)}")
        slam = cls.__new__(cls)
        slam.__setstate__({**state, **{name: list(lists[name]) for name in cls.APPEND_ONLY}})
        return slam

    # -- public state ------------------------------------------------------------------------------------------

    @property
    def pose(self) -> FloatArray:
        """(3,) the latest ``base_link`` pose in ``map`` (x, y, θ)."""
        return self._pose.copy()

    @property
    def covariance(self) -> FloatArray:
        """(3, 3) covariance of :attr:`pose`."""
        return self._cov.copy()

    @property
    def loop_closures(self) -> int:
        """Loop-closure edges accepted so far."""
        return self._loop_closures

    @property
    def optimizations(self) -> int:
        """Pose-graph optimisations run so far."""
        return self._optimizations

    @property
    def num_keyframes(self) -> int:
        """Keyframes (pose-graph vertices) so far."""
        return len(self._graph.poses)

    @property
    def num_scans(self) -> int:
        """Scans fed to :meth:`update` so far."""
        return len(self._stamps)

    def map_to_odom(self) -> FloatArray:
        """(3,) the ``map → odom`` transform (x, y, θ): pose_map ∘ pose_odom⁻¹ at the latest scan."""
        return _compose1(self._pose, _relative1(self._odom, np.zeros(3)))

    def keyframe_poses(self) -> FloatArray:
        """(K, 3) keyframe poses in ``map`` (the pose-graph vertices, optimised after each loop closure)."""
        return np.array(self._graph.poses, dtype=np.float64).reshape(-1, 3)

    def keyframe_stamps(self) -> FloatArray:
        """(K,) time of each keyframe's scan, seconds."""
        return np.array(self._kf_stamps, dtype=np.float64)

    def trajectory(self) -> tuple[FloatArray, FloatArray]:
        """Every scan's pose in ``map``, as the optimised graph places it.

        Returns:
            (stamps (S,) seconds, poses (S, 3)): each scan's pose is its keyframe's current pose composed with the
            front end's motion from that keyframe.
        """
        if not self._stamps:
            return np.zeros(0), np.zeros((0, 3))
        kf = self.keyframe_poses()[np.asarray(self._scan_kf)]
        return np.array(self._stamps), compose(kf, np.array(self._scan_rel))

    def pose_graph(self) -> PoseGraph:
        """The pose graph (vertices = keyframes at their current poses; front-end and loop edges).

        Raises:
            SlamError: no scan yet.
        """
        g = self._graph
        if not g.poses:
            raise SlamError("no scan yet: the pose graph is empty")
        return PoseGraph(
            np.array(g.poses),
            np.array(g.edges, dtype=np.int64).reshape(-1, 2),
            np.array(g.measurements).reshape(-1, 3),
            np.array(g.information).reshape(-1, 3, 3),
        )

    def loop_edges(self) -> NDArray[np.int64]:
        """(L, 2) keyframe index pairs (anchor, keyframe) of the accepted loop closures."""
        g = self._graph
        idx = [e for e, is_loop in zip(g.edges, g.loop, strict=True) if is_loop]
        return np.array(idx, dtype=np.int64).reshape(-1, 2)

    # -- the update ----------------------------------------------------------------------------------------------

    def update(
        self,
        stamp_s: float,
        odom_pose: ArrayLike,
        ranges_m: ArrayLike,
        angles_rad: ArrayLike,
        *,
        range_min_m: float,
        range_max_m: float,
    ) -> PoseEstimate:
        """Process one scan.

        Args:
            stamp_s: scan time, seconds (recorded in the trajectory; the estimate does not use it).
            odom_pose: (x, y, θ) of ``base_link`` in ``odom`` at the scan's time (wheel odometry).
            ranges_m: (N,) ranges, metres; values outside [range_min_m, range_max_m) or non-finite are no return
                (REP-117: +inf no return, −inf too close).
            angles_rad: (N,) beam angles in the laser frame, radians.
            range_min_m: sensor minimum range, metres.
            range_max_m: sensor maximum range, metres.

        Returns:
            :class:`PoseEstimate` of ``base_link`` in ``map`` after this scan.

        Raises:
            SlamError: malformed scan, pose or time.
        """
        t = float(stamp_s)
        if not math.isfinite(t):
            raise SlamError(f"stamp_s must be finite, got {stamp_s}")
        odom = _pose_arg(odom_pose, "odom_pose")
        cfg = self.config
        scan = _scan(ranges_m, angles_rad, range_min_m, range_max_m, cfg.max_range_m, cfg.laser_offset)
        if not self._graph.poses:
            self._pose = odom.copy() if self._initial is None else self._initial.copy()
            self._odom = odom
            self._cov = np.diag([cfg.min_sigma_m**2, cfg.min_sigma_m**2, cfg.min_sigma_rad**2])
            self._add_keyframe(t, scan, loop=False)
            self._record(t)
            return self._estimate(1.0, True, 0)
        predicted = _compose1(self._pose, _relative1(self._odom, odom))
        pose, cov, score, matched, degenerate = self._match_local(scan, predicted)
        self._pose, self._odom = pose, odom
        self._cov = cov
        kf = -1
        last = self._graph.poses[-1]
        d = _relative1(last, pose)
        if math.hypot(d[0], d[1]) >= cfg.keyframe_distance_m or abs(d[2]) >= cfg.keyframe_angle_rad:
            kf = self._add_keyframe(t, scan, loop=True)
        self._record(t)
        return self._estimate(score, matched, kf, degenerate)

    def _estimate(self, score: float, matched: bool, kf: int, degenerate: bool = False) -> PoseEstimate:
        return PoseEstimate(self.pose, self.covariance, self.map_to_odom(), float(score), matched, kf, degenerate)

    def _record(self, t: float) -> None:
        k = len(self._graph.poses) - 1
        self._stamps.append(t)
        self._scan_kf.append(k)
        self._scan_rel.append(_relative1(self._graph.poses[k], self._pose))

    def _floor_cov(self, cov: FloatArray) -> FloatArray:
        return _floor_cov(cov, self.config.min_sigma_m, self.config.min_sigma_rad)

    def _match_local(self, scan: _Scan, predicted: FloatArray) -> tuple[FloatArray, FloatArray, float, bool, bool]:
        """Front end: CSM then PL-ICP against the local map; the prediction when both fail. Returns the pose, its
        covariance, the match quality, whether the scan was matched and whether the match was degenerate."""
        cfg = self.config
        local = self._local
        sm, sr = _DEAD_RECKONING_SIGMA
        dead_reckoning = (predicted, self._cov + np.diag([sm * sm, sm * sm, sr * sr]), 0.0, False, False)
        if local is None or scan.points.shape[0] < 3:
            return dead_reckoning
        matcher, ref = local
        try:
            coarse = matcher.match(
                scan.points,
                predicted,
                linear_window_m=cfg.match_window_m,
                angular_window_rad=cfg.match_window_rad,
                angular_step_rad=cfg.match_angular_step_rad,
                min_score=0.0,
                translation_cost=cfg.match_translation_cost,
                rotation_cost=cfg.match_rotation_cost,
            )
        except ScanMatchError:
            return dead_reckoning
        try:
            fine = ref.match(
                scan.points, coarse.pose, "plicp", max_correspondence_m=cfg.icp_max_correspondence_m, max_iterations=50
            )
            degenerate = fine.degenerate
            if degenerate:
                # A corridor: the correlative search is flat along it and may pick any offset there; PL-ICP from
                # the odometry prediction keeps the prediction in the unobservable direction instead.
                corr = cfg.icp_max_correspondence_m
                fine = ref.match(scan.points, predicted, "plicp", max_correspondence_m=corr, max_iterations=50)
                coarse = fine
        except ScanMatchError:
            return coarse.pose.copy(), self._floor_cov(coarse.covariance), 0.0, True, False
        jump = _relative1(coarse.pose, fine.pose)
        if (
            fine.score < cfg.min_match_inliers
            or math.hypot(jump[0], jump[1]) > 2.0 * cfg.match_resolution_m + 0.05
            or abs(jump[2]) > 2.0 * cfg.match_angular_step_rad + math.radians(1.0)
        ):
            return coarse.pose.copy(), self._floor_cov(coarse.covariance), float(fine.score), True, degenerate
        return fine.pose.copy(), self._floor_cov(fine.covariance), float(fine.score), True, degenerate

    # -- keyframes, submaps, loops ------------------------------------------------------------------------------

    def _edge_information(self, z: FloatArray, frame_theta: float) -> FloatArray:
        """Information of a front-end edge z (in the frame of its first keyframe, heading ``frame_theta``): the
        motion model's covariance, raised to the front-end match's covariance (map frame, rotated into the edge's)
        where the match is less certain, so a direction the local map hardly constrains (along a corridor) stays
        soft in the graph."""
        cfg = self.config
        d = math.hypot(z[0], z[1])
        st = cfg.edge_sigma_m**2 + cfg.edge_sigma_per_m**2 * d
        sr = cfg.edge_sigma_rad**2 + cfg.edge_sigma_rad_per_rad**2 * abs(z[2])
        c, s = math.cos(frame_theta), math.sin(frame_theta)
        rot = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
        match = rot @ self._cov @ rot.T
        # An unobservable direction of the match (variance 1e6) is known as well as one dead-reckoned scan knows
        # it: eigenvalues capped in units where both of its σ are 1.
        scale = np.array(
            [1.0 / _DEAD_RECKONING_SIGMA[0], 1.0 / _DEAD_RECKONING_SIGMA[0], 1.0 / _DEAD_RECKONING_SIGMA[1]]
        )
        w, v = np.linalg.eigh(match * np.outer(scale, scale))
        match = ((v * np.minimum(w, 1.0)) @ v.T) / np.outer(scale, scale)
        info = np.linalg.inv(_floor_cov(match, math.sqrt(st), math.sqrt(sr)))
        return 0.5 * (info + info.T)

    def _add_keyframe(self, t: float, scan: _Scan, *, loop: bool) -> int:
        g = self._graph
        k = len(g.poses)
        g.poses.append(self._pose.copy())
        self._kf_scans.append(scan)
        self._kf_stamps.append(t)
        if k > 0:
            z = _relative1(g.poses[k - 1], g.poses[k])
            self._kf_travel.append(self._kf_travel[-1] + math.hypot(z[0], z[1]))
        else:
            self._kf_travel.append(0.0)
        if k > 0:
            g.edges.append((k - 1, k))
            g.measurements.append(z)
            info = self._edge_information(z, float(g.poses[k - 1][2]))
            g.information.append(info)
            g.loop.append(False)
            g.var_t.append(1.0 / info[0, 0])
            g.var_r.append(1.0 / info[2, 2])
        cfg = self.config
        if (k + 1) % cfg.submap_keyframes == 0:
            self._finish_submap(range(k + 1 - cfg.submap_keyframes, k + 1))
        if loop and cfg.loop_candidates > 0:
            self._pending_chi2 += self._close_loops(k)
            if self._pending_chi2 > cfg.optimize_min_chi2:
                self._optimize()
                self._pending_chi2 = 0.0
        self._rebuild_local_map()
        if self._grid is not None and not self._grid_dirty:
            self._grid_dirty = not self._insert_into_grid(k)
        return k

    def _points_in(self, frame_pose: FloatArray, kfs: range, max_range: float) -> FloatArray:
        """Points of keyframes ``kfs`` (within ``max_range`` of their keyframe) in the frame ``frame_pose``."""
        chunks = []
        for j in kfs:
            p = self._kf_scans[j].points
            if max_range < self.config.max_range_m:
                p = p[np.einsum("ij,ij->i", p, p) < max_range * max_range]
            if p.shape[0]:
                chunks.append(_transform(_relative1(frame_pose, self._graph.poses[j]), p))
        return np.concatenate(chunks) if chunks else np.zeros((0, 2))

    def _rebuild_local_map(self) -> None:
        cfg = self.config
        k = len(self._graph.poses)
        kfs = range(max(0, k - cfg.local_map_keyframes), k)
        pts = self._points_in(np.zeros(3), kfs, cfg.max_range_m)
        if pts.shape[0] < 3:
            self._local = None
            return
        table, frame, scale = likelihood_field(pts, cfg.match_resolution_m)
        w = math.ceil(cfg.match_window_m / cfg.match_resolution_m)
        # Three levels (blocks of 4 × 4 cells) bound the small front-end window tightly; every further level
        # costs a pass over the whole table at each keyframe and saves less search than it costs.
        depth = max(1, min(3, math.ceil(math.log2(2 * w + 1))))
        try:
            self._local = (
                CorrelativeGridMatcher(table, frame, depth=depth, loglik_scale=scale),
                PointReference(pts),
            )
        except ScanMatchError:
            self._local = None

    def _finish_submap(self, members: range) -> None:
        cfg = self.config
        anchor = members.start
        frame = self._graph.poses[anchor]
        pts = self._points_in(frame, members, cfg.loop_max_range_m)
        if pts.shape[0] < 3:
            return
        # The space the members' beams observed (free or hit) within loop_max_range_m, over the box of their hits.
        res = cfg.loop_resolution_m
        lasers = [_compose1(_relative1(frame, self._graph.poses[j]), np.asarray(cfg.laser_offset)) for j in members]
        xy = np.concatenate([pts, np.array(lasers)[:, :2]])
        lo, hi = xy.min(axis=0) - res, xy.max(axis=0) + res
        reach = cfg.loop_max_range_m
        origin = (math.floor(lo[0] / res) * res, math.floor(lo[1] / res) * res)
        grid = OccupancyGrid(math.ceil((hi[0] - origin[0]) / res), math.ceil((hi[1] - origin[1]) / res), res, origin)
        for j, laser in zip(members, lasers, strict=True):
            s = self._kf_scans[j]
            grid.integrate_scan(laser, s.angles, s.ranges, min(s.range_max, reach), min_range_m=s.range_min)
        known = grid.log_odds != grid.model.prior_log_odds
        self._submaps.append(_Submap(anchor, members, pts, known, grid.origin_m))

    def _submap_matchers(self, index: int) -> tuple[CorrelativeGridMatcher, PointReference]:
        cache = self._submap_cache
        if index in cache:
            cache.move_to_end(index)
            return cache[index]
        cfg = self.config
        sub = self._submaps[index]
        table, frame, scale = likelihood_field(sub.points, cfg.loop_resolution_m)
        w = math.ceil(cfg.loop_window_m / cfg.loop_resolution_m)
        depth = max(1, min(7, math.ceil(math.log2(2 * w + 1))))
        entry = (CorrelativeGridMatcher(table, frame, depth=depth, loglik_scale=scale), PointReference(sub.points))
        cache[index] = entry
        while len(cache) > cfg.cached_submaps:
            cache.popitem(last=False)
        return entry

    def _chain_variances(self, k: int) -> tuple[FloatArray, FloatArray]:
        """Uncertainty of every keyframe relative to keyframe k: (K,) translational (m²) and (K,) rotational
        (rad²) variances summed along the least uncertain chain of graph edges (Dijkstra; ∞ if unconnected).

        A chain's relative pose is the composition of its edges, so their variances add; an edge's heading
        variance also moves the chain's far end, counted at the lever ``loop_search_radius_m`` (the distance
        at which loop candidates are searched). Loop-closure edges shorten the chains: after a closure the
        places it joined are close in the graph, and the loop search around them needs only a small window.
        """
        g = self._graph
        e = np.asarray(g.edges, dtype=np.int64).reshape(-1, 2)
        v_r = np.asarray(g.var_r, dtype=np.float64)
        v_t = np.asarray(g.var_t, dtype=np.float64) + v_r * self.config.loop_search_radius_m**2
        d = shortest_paths(e[:, 0].copy(), e[:, 1].copy(), np.stack((v_t, v_r)), len(g.poses), k)
        return d[0], d[1]

    def _close_loops(self, k: int) -> float:
        """Match keyframe k against nearby older submaps and add the accepted loop edges; returns the sum of their
        χ² errors at the current poses (0 when none was added)."""
        cfg = self.config
        g = self._graph
        newest_excluded = k - cfg.local_map_keyframes - cfg.loop_min_separation_keyframes
        subs = self._submaps
        if not subs:
            return 0.0
        poses = np.array(g.poses)
        here = poses[k]
        # Distance from keyframe k to each submap's nearest member (members are contiguous index ranges).
        bounds = np.array([(sub.members.start, sub.members.stop) for sub in subs], dtype=np.int64)
        dist = np.append(np.hypot(poses[:, 0] - here[0], poses[:, 1] - here[1]), np.inf)
        d_sub = np.minimum.reduceat(dist, bounds.ravel())[::2]
        travel = np.asarray(self._kf_travel)
        last = bounds[:, 1] - 1
        ok = (
            (last <= newest_excluded)
            & (travel[k] - travel[last] >= cfg.loop_min_travel_m)
            & (d_sub <= cfg.loop_search_radius_m)
        )
        if not np.any(ok):
            return 0.0
        scan = self._kf_scans[k].points
        r2 = cfg.loop_max_range_m**2
        scan = scan[np.einsum("ij,ij->i", scan, scan) < r2]
        if scan.shape[0] < 10:
            return 0.0
        if cfg.loop_min_overlap > 0.0:
            # Candidates by overlap: the share of the scan, at the current estimate, inside each submap's observed
            # space; the largest first.
            res = cfg.loop_resolution_m
            inside = {
                int(i): subs[i].observed(_transform(_relative1(poses[subs[i].anchor], here), scan), res)
                for i in np.flatnonzero(ok)
            }
            share = {i: float(np.mean(mask)) for i, mask in inside.items()}
            candidates = sorted((-v, i) for i, v in share.items() if v >= cfg.loop_min_overlap)
        else:
            candidates = sorted(zip(d_sub[ok].tolist(), np.flatnonzero(ok).tolist(), strict=True))
        if not candidates:
            return 0.0
        d_max = float(np.sqrt(np.max(np.einsum("ij,ij->i", scan, scan))))
        step = cfg.loop_resolution_m / max(d_max, 1.0)  # the farthest point moves at most one cell per step
        chi2 = 0.0
        var_t, var_r = self._chain_variances(k)
        for _d, i in candidates[: cfg.loop_candidates]:
            sub = self._submaps[i]
            matcher, ref = self._submap_matchers(i)
            init = _relative1(poses[sub.anchor], here)
            s_t = cfg.loop_window_sigmas * math.sqrt(var_t[sub.anchor])
            s_r = cfg.loop_window_sigmas * math.sqrt(var_r[sub.anchor])
            # Only the part of the scan inside the space the submap observed can agree or disagree with it: the
            # scores are taken over that part, which must be at least loop_min_overlap of the scan.
            seen = scan if cfg.loop_min_overlap == 0.0 else scan[inside[i]]  # the mask ranked it: at init
            if seen.shape[0] < max(10, cfg.loop_min_overlap * scan.shape[0]):
                continue
            try:
                coarse = matcher.match(
                    seen,
                    init,
                    linear_window_m=min(cfg.loop_window_m, max(cfg.loop_min_window_m, s_t)),
                    angular_window_rad=min(cfg.loop_window_rad, max(cfg.loop_min_window_rad, s_r)),
                    angular_step_rad=step,
                    min_score=cfg.loop_min_score,
                )
                if cfg.loop_min_overlap > 0.0:
                    seen = scan[sub.observed(_transform(coarse.pose, scan), cfg.loop_resolution_m)]
                if seen.shape[0] < max(10, cfg.loop_min_overlap * scan.shape[0]):
                    continue
                fine = ref.match(
                    seen, coarse.pose, "plicp", max_correspondence_m=cfg.icp_max_correspondence_m, max_iterations=50
                )
            except ScanMatchError:
                continue
            jump = _relative1(coarse.pose, fine.pose)
            if (
                fine.degenerate  # a corridor: the match slides along it
                or fine.score < cfg.loop_min_inliers
                or math.hypot(jump[0], jump[1]) > 2.0 * cfg.loop_resolution_m
            ):
                continue
            info = self._loop_information(fine.covariance, float(fine.pose[2]))
            g.edges.append((sub.anchor, k))
            g.measurements.append(fine.pose.copy())
            g.information.append(info)
            g.loop.append(True)
            g.var_t.append(1.0 / info[0, 0])
            g.var_r.append(1.0 / info[2, 2])
            self._loop_closures += 1
            e = _relative1(fine.pose, init)
            chi2 += float(e @ info @ e)
        return chi2

    def _loop_information(self, cov: FloatArray, theta: float) -> FloatArray:
        """Information of a loop edge from its PL-ICP match: the match covariance ``cov`` (submap frame, the
        matched keyframe at heading ``theta`` there) keeps its shape but is scaled so that its best-constrained
        translational direction has σ = ``loop_sigma_m`` (PL-ICP's own scale is far too confident), its heading σ
        floored at ``loop_sigma_rad``, and rotated into the keyframe's frame (where the graph measures the edge's
        error). A match that slides along a corridor thus holds the keyframe across the corridor, not along it."""
        cfg = self.config
        c = 0.5 * (cov + cov.T)
        smallest = float(np.linalg.eigvalsh(c[:2, :2])[0])
        if smallest > 0.0:
            c = c * (cfg.loop_sigma_m**2 / smallest)
        ct, st = math.cos(theta), math.sin(theta)
        rot = np.array([[ct, st, 0.0], [-st, ct, 0.0], [0.0, 0.0, 1.0]])
        info = np.linalg.inv(rot @ _floor_cov(c, cfg.loop_sigma_m, cfg.loop_sigma_rad) @ rot.T)
        return 0.5 * (info + info.T)

    def _optimize(self) -> None:
        g = self._graph
        graph = self.pose_graph()
        result = optimize_pose_graph(
            graph, robust="huber", objective="g2o", init="graph", max_iterations=30, tolerance=1e-6
        )
        k = len(g.poses) - 1
        old_last = g.poses[k]
        g.poses = [p.copy() for p in result.poses]
        # The latest pose follows its keyframe (it is keyframe k itself when called from _add_keyframe).
        self._pose = _compose1(g.poses[k], _relative1(old_last, self._pose))
        self._optimizations += 1
        self._grid_dirty = True

    # -- the occupancy grid --------------------------------------------------------------------------------------

    def _laser_pose(self, k: int) -> FloatArray:
        return _compose1(self._graph.poses[k], np.asarray(self.config.laser_offset, dtype=np.float64))

    def _insert_into_grid(self, k: int) -> bool:
        """Fuse keyframe k into the current grid; False when its points fall outside (a re-render is needed)."""
        grid = self._grid
        assert grid is not None
        pts = self._points_in(np.zeros(3), range(k, k + 1), self.config.max_range_m)
        x0, x1, y0, y1 = grid.extent_m
        pose = self._graph.poses[k]
        inside = bool(
            x0 < pose[0] < x1
            and y0 < pose[1] < y1
            and (pts.shape[0] == 0 or (pts[:, 0].min() > x0 and pts[:, 0].max() < x1))
            and (pts.shape[0] == 0 or (pts[:, 1].min() > y0 and pts[:, 1].max() < y1))
        )
        if inside:
            self._integrate(grid, k)
            self._grid_kfs = k + 1
        return inside

    def _integrate(self, grid: OccupancyGrid, k: int) -> None:
        s = self._kf_scans[k]
        grid.integrate_scan(
            self._laser_pose(k),
            s.angles,
            s.ranges,
            min(s.range_max, self.config.max_range_m),
            min_range_m=s.range_min,
        )

    def occupancy_grid(self, *, margin_m: float = 1.0) -> OccupancyGrid:
        """The log-odds occupancy grid of every keyframe scan at its current (optimised) pose.

        Rendered on demand: after a loop closure (or when the map must grow) the whole grid is re-rendered from
        the keyframes; otherwise new keyframes are fused into the grid returned last time. The returned grid is
        the SLAM's own: copy it before modifying it.

        Args:
            margin_m: free border around the scan end points, metres.

        Raises:
            SlamError: no scan yet.
        """
        k = len(self._graph.poses)
        if k == 0:
            raise SlamError("no scan yet: there is no map")
        if self._grid is not None and not self._grid_dirty:
            for j in range(self._grid_kfs, k):
                if not self._insert_into_grid(j):
                    self._grid_dirty = True
                    break
            if not self._grid_dirty:
                return self._grid
        cfg = self.config
        pts = self._points_in(np.zeros(3), range(k), cfg.max_range_m)
        xy = np.concatenate([pts, np.array(self._graph.poses)[:, :2]])
        lo = xy.min(axis=0) - margin_m
        hi = xy.max(axis=0) + margin_m
        res = cfg.map_resolution_m
        origin = (math.floor(lo[0] / res) * res, math.floor(lo[1] / res) * res)
        w = math.ceil((hi[0] - origin[0]) / res)
        h = math.ceil((hi[1] - origin[1]) / res)
        grid = OccupancyGrid(w, h, res, origin, **asdict(cfg.map_model))
        for j in range(k):
            self._integrate(grid, j)
        self._grid, self._grid_kfs, self._grid_dirty = grid, k, False
        return grid


# ---------------------------------------------------------------------------------------------------------------
# Localization


@dataclass(frozen=True)
class LocalizerConfig:
    """Parameters of :class:`Localizer`.

    Attributes:
        max_range_m: beams longer than this are not matched, metres.
        laser_offset: (x, y, θ) of the laser in ``base_link``.
        sigma_m: width of the map's likelihood field, metres (default: 2 cells).
        window_sigmas: search half-widths are this many standard deviations of the predicted covariance ...
        min_window_m: ... but at least this (metres) ...
        max_window_m: ... and at most this (metres);
        min_window_rad: likewise in θ (radians) ...
        max_window_rad: ... (radians).
        max_angular_step_rad: upper bound of the correlative search's angular step, radians.
        motion_sigma_m: odometry noise added per step at zero motion, metres.
        motion_sigma_per_m: its growth with the travelled distance (σ² += motion_sigma_per_m²·d).
        motion_sigma_rad: rotational odometry noise per step, radians.
        motion_sigma_rad_per_rad: its growth with the turned angle.
        min_score: minimum mean likelihood (0..1) of an accepted correlative match.
        min_inliers: minimum PL-ICP inlier share of an accepted refined match.
        icp_max_correspondence_m: PL-ICP correspondences farther than this are ignored, metres.
        min_sigma_m: floor of the reported translational standard deviation, metres.
        min_sigma_rad: floor of the reported rotational standard deviation, radians.
    """

    max_range_m: float = 30.0
    laser_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sigma_m: float | None = None
    window_sigmas: float = 3.0
    min_window_m: float = 0.15
    max_window_m: float = 2.0
    min_window_rad: float = math.radians(5.0)
    max_window_rad: float = math.radians(60.0)
    max_angular_step_rad: float = math.radians(0.5)
    motion_sigma_m: float = 0.005
    motion_sigma_per_m: float = 0.05
    motion_sigma_rad: float = math.radians(0.5)
    motion_sigma_rad_per_rad: float = 0.05
    min_score: float = 0.3
    min_inliers: float = 0.5
    icp_max_correspondence_m: float = 0.3
    min_sigma_m: float = 0.005
    min_sigma_rad: float = math.radians(0.2)

    def __post_init__(self) -> None:
        _check_config(self)
        if self.sigma_m is not None and not (math.isfinite(self.sigma_m) and self.sigma_m > 0):
            raise SlamError(f"LocalizerConfig.sigma_m must be > 0, got {self.sigma_m}")
        if len(self.laser_offset) != 3 or not all(math.isfinite(v) for v in self.laser_offset):
            raise SlamError(f"LocalizerConfig.laser_offset must be 3 finite numbers, got {self.laser_offset!r}")
        if self.min_window_m > self.max_window_m or self.min_window_rad > self.max_window_rad:
            raise SlamError("LocalizerConfig: min windows must not exceed max windows")
        if self.max_window_rad > math.pi:
            raise SlamError("LocalizerConfig.max_window_rad must be at most pi")


class Localizer:
    """Pose tracking on a fixed occupancy map (see the module doc).

    Args:
        grid: the map (e.g. ``OccupancyGrid.from_ros_map(read_ros_map("map.yaml"))``); its OCCUPIED cells are the
            walls the scans are matched to.
        config: parameters; default :class:`LocalizerConfig`.

    Raises:
        SlamError: the map has fewer than 3 occupied cells.

    Use: :meth:`set_pose` with the initial pose (``initialpose``), then :meth:`update` per scan. Before the first
    :meth:`set_pose` the localizer is not initialised and :meth:`update` raises.
    """

    def __init__(self, grid: OccupancyGrid, config: LocalizerConfig | None = None) -> None:
        self.config = cfg = config or LocalizerConfig()
        occupied = grid.states() == CellState.OCCUPIED
        rows, cols = np.nonzero(occupied)
        if rows.size < 3:
            raise SlamError(f"the map has {rows.size} occupied cells; localization needs walls (at least 3)")
        frame = GridFrame(grid.resolution_m, grid.origin_m, grid.shape)
        walls = frame.cells_to_world(np.column_stack((rows, cols)))
        table, tframe, scale = likelihood_field(walls, grid.resolution_m, cfg.sigma_m)
        self.resolution_m = grid.resolution_m
        self._matcher = CorrelativeGridMatcher(table, tframe, depth=7, loglik_scale=scale)
        self._ref = PointReference(walls)
        self._pose: FloatArray | None = None
        self._cov = np.eye(3)
        self._odom: FloatArray | None = None

    @property
    def initialised(self) -> bool:
        """True after :meth:`set_pose`."""
        return self._pose is not None

    @property
    def pose(self) -> FloatArray:
        """(3,) current pose in ``map``.

        Raises:
            SlamError: not initialised.
        """
        if self._pose is None:
            raise SlamError("the localizer has no pose yet: call set_pose (initialpose) first")
        return self._pose.copy()

    @property
    def covariance(self) -> FloatArray:
        """(3, 3) covariance of :attr:`pose`."""
        return self._cov.copy()

    def set_pose(self, pose: ArrayLike, covariance: ArrayLike, odom_pose: ArrayLike | None = None) -> None:
        """(Re)initialise from an operator's estimate (``initialpose``).

        Args:
            pose: (x, y, θ) of ``base_link`` in ``map``.
            covariance: (3, 3) its covariance (RViz sends σ = 0.5 m and 15°: diag(0.25, 0.25, 0.0685)).
            odom_pose: the odometry pose at that moment; default: the next :meth:`update`'s odometry.

        Raises:
            SlamError: malformed pose or covariance.
        """
        self._pose = _pose_arg(pose, "pose")
        self._cov = _cov_arg(covariance, "covariance")
        self._odom = None if odom_pose is None else _pose_arg(odom_pose, "odom_pose")

    def map_to_odom(self) -> FloatArray:
        """(3,) ``map → odom`` (x, y, θ) at the latest update.

        Raises:
            SlamError: not initialised or no update yet.
        """
        if self._pose is None or self._odom is None:
            raise SlamError("map_to_odom needs set_pose and at least one update")
        return compose(self._pose, invert(self._odom))

    def update(
        self,
        odom_pose: ArrayLike,
        ranges_m: ArrayLike,
        angles_rad: ArrayLike,
        *,
        range_min_m: float,
        range_max_m: float,
    ) -> PoseEstimate:
        """Predict with odometry, match the scan to the map, return the pose.

        Args:
            odom_pose: (x, y, θ) of ``base_link`` in ``odom`` at the scan's time.
            ranges_m: (N,) ranges, metres (non-finite or out-of-limit: no return).
            angles_rad: (N,) beam angles in the laser frame, radians.
            range_min_m: sensor minimum range, metres.
            range_max_m: sensor maximum range, metres.

        Returns:
            :class:`PoseEstimate` (``keyframe`` is always −1).

        Raises:
            SlamError: not initialised, or a malformed scan or pose.
        """
        if self._pose is None:
            raise SlamError("the localizer has no pose yet: call set_pose (initialpose) first")
        cfg = self.config
        odom = _pose_arg(odom_pose, "odom_pose")
        scan = _scan(ranges_m, angles_rad, range_min_m, range_max_m, cfg.max_range_m, cfg.laser_offset)
        if self._odom is not None:
            step = relative(self._odom, odom)
            d = math.hypot(step[0], step[1])
            q = np.diag(
                [
                    cfg.motion_sigma_m**2 + cfg.motion_sigma_per_m**2 * d,
                    cfg.motion_sigma_m**2 + cfg.motion_sigma_per_m**2 * d,
                    cfg.motion_sigma_rad**2 + cfg.motion_sigma_rad_per_rad**2 * abs(step[2]),
                ]
            )
            c, s = math.cos(self._pose[2]), math.sin(self._pose[2])
            # Jacobians of pose ∘ step with respect to pose (F) and step (G).
            f = np.array([[1.0, 0.0, -s * step[0] - c * step[1]], [0.0, 1.0, c * step[0] - s * step[1]], [0, 0, 1]])
            gm = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            self._cov = f @ self._cov @ f.T + gm @ q @ gm.T
            self._pose = compose(self._pose, step)
        self._odom = odom
        score, matched = self._correct(scan.points)
        return PoseEstimate(self.pose, self.covariance, self.map_to_odom(), score, matched)

    def _correct(self, pts: FloatArray) -> tuple[float, bool]:
        cfg = self.config
        assert self._pose is not None
        if pts.shape[0] < 10:
            return 0.0, False
        sig = np.sqrt(np.maximum(np.diag(self._cov), 0.0))
        win_m = float(np.clip(cfg.window_sigmas * max(sig[0], sig[1]), cfg.min_window_m, cfg.max_window_m))
        win_rad = float(np.clip(cfg.window_sigmas * sig[2], cfg.min_window_rad, cfg.max_window_rad))
        d_max = float(np.sqrt(np.max(np.einsum("ij,ij->i", pts, pts))))
        step = min(cfg.max_angular_step_rad, self.resolution_m / max(d_max, 1.0))
        try:
            coarse = self._matcher.match(
                pts,
                self._pose,
                linear_window_m=win_m,
                angular_window_rad=win_rad,
                angular_step_rad=step,
                min_score=cfg.min_score,
            )
        except ScanMatchError:
            return 0.0, False
        try:
            fine = self._ref.match(
                pts, coarse.pose, "plicp", max_correspondence_m=cfg.icp_max_correspondence_m, max_iterations=50
            )
            jump = relative(coarse.pose, fine.pose)
            ok = fine.score >= cfg.min_inliers and math.hypot(jump[0], jump[1]) <= 3.0 * self.resolution_m
        except ScanMatchError:
            ok = False
        if ok:
            self._pose = fine.pose.copy()
            self._cov = _floor_cov(fine.covariance, cfg.min_sigma_m, cfg.min_sigma_rad)
            return float(fine.score), True
        self._pose = coarse.pose.copy()
        self._cov = _floor_cov(coarse.covariance, cfg.min_sigma_m, cfg.min_sigma_rad)
        return float(coarse.score), True

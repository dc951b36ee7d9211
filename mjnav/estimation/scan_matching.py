"""2-D scan matching: point-to-point ICP, point-to-line ICP, correlative and branch-and-bound matching.

Pose convention (every function here): ``initial`` and the returned pose are the pose (x, y, θ) — metres,
radians — of the **scan's frame in the reference frame**: scan points p transformed by it,
R(θ)·p + (x, y), land on the reference. For two consecutive laser scans with world poses A (reference) and
B (scan) this is A⁻¹·B, the motion of the sensor between them.

Methods of :func:`scan_match`:

* ``"icp"`` — point-to-point ICP (Besl & McKay 1992): nearest reference point per scan point (exact, through a
  spatial hash), adaptive trimming (pairs with distance > ``outlier_mult`` × the median are dropped), closed-form
  least-squares pose per iteration (Arun et al. 1987). The trimming threshold is floored by an annealed
  distance (first ``max_correspondence_m``, then at most 0.3 × the previous floor and 3 × the distance the
  last update moved a point at the scan's RMS range) so that a direction constrained by a minority of points
  (a far wall) is not trimmed away before the rest has converged; iterations stop only once the floor no
  longer decides (below the adaptive threshold or 1 % of ``max_correspondence_m``) at a fixed point or a
  2-cycle of correspondence sets.
* ``"plicp"`` — point-to-line ICP (Censi, "An ICP variant using a point-to-line metric", ICRA 2008): the
  error of a scan point is its distance to the line through its nearest reference point. The line direction
  is fitted to that point's neighbours (PCA of those within 0.2 m, at least the 5 nearest) instead of Censi's two
  nearest points, which keeps it stable under range noise; corner points (no dominant direction) are not
  used. Each iteration takes one Gauss–Newton step of the point-to-line error with the new correspondences
  (same trimming as ICP, on the point-to-line residual); the fixed point is Censi's.
* ``"csm"`` — correlative scan matching (Olson, "Real-time correlative scan matching", ICRA 2009): the
  reference is rasterised into a lookup table of per-point log-likelihood (a Gaussian of the distance to the
  nearest reference point, mixed with a uniform floor so outliers cost a bounded amount), and every pose of a
  (x, y, θ) window around ``initial`` is scored by summing the table at the transformed scan points.
  Multi-resolution: coarse tables hold the maximum of the fine cells they cover, so the coarse scores bound
  the fine ones and the search (branch and bound, as below) returns the exact best pose of the fine
  lattice. Accuracy is the table resolution (default 2 cm) and the angular step. Covariance from the score
  distribution around the peak (Olson 2009's covariance estimate) plus the lattice's own quantisation
  variance.

:class:`CorrelativeGridMatcher` matches a scan against an occupancy grid (or any [0, 1] score table) by the
branch and bound of Hess et al., "Real-time loop closure in 2D LIDAR SLAM" (ICRA 2016, Cartographer): a
precomputed pyramid of max-pooled grids, a search window in metres and radians (default ±7 m, ±30°), exact
with respect to the brute-force search over the same lattice (:meth:`CorrelativeGridMatcher.match_brute_force`).

Covariances are (3, 3) over (x, y, θ) in m², m·rad, rad². For ICP and PL-ICP it is σ²·(JᵀJ)⁻¹ of the
point-to-line residuals at the solution (σ² estimated from them; Bengtsson & Baerveldt 2003, in Censi's
point-to-line form), for both methods, because point-to-point residuals hide the sliding of a scan along a
wall. A match whose point-to-line information is rank-deficient (a corridor, a single wall, a circle) is
flagged ``degenerate``: the unobservable direction keeps the initial value and gets the variance 1e6 (m²).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mjnav.estimation import _scan_kernels as kern
from mjnav.estimation.errors import EstimationError
from mjnav.mapping import GridFrame, OccupancyGrid, log_odds_to_prob

__all__ = [
    "CorrelativeGridMatcher",
    "InsufficientPointsError",
    "NoMatchError",
    "PointReference",
    "ScanMatchError",
    "ScanMatchResult",
    "likelihood_field",
    "scan_match",
    "scan_to_points",
]

METHODS = ("icp", "plicp", "csm")
_HASH_CELL_M = 0.1
_NORMAL_RADIUS_M = 0.2
_NORMAL_MAX_RADIUS_M = 0.6
_NORMAL_MIN_K = 5
_NORMAL_MAX_RATIO = 0.05
_DEGENERACY_RATIO = 1e-3
_UNOBSERVABLE_VAR = 1e6
_ANNEAL = 0.3
_MAX_COORD_M = 1e5  # the spatial hash's cell keys hold ±2^20 cells of 0.1 m


class ScanMatchError(EstimationError, ValueError):
    """Base class of every scan-matching failure (bad input, or no acceptable match)."""


class InsufficientPointsError(ScanMatchError):
    """Too few valid points (or correspondences, or reference lines) to determine a pose."""


class NoMatchError(ScanMatchError):
    """No pose in the search window scores above the requested minimum (correlative matchers)."""


@dataclass(frozen=True, eq=False)
class ScanMatchResult:
    """The outcome of one match.

    Attributes:
        pose: (3,) float (x, y, θ), metres and radians: the scan frame's pose in the reference frame.
        covariance: (3, 3) symmetric positive semi-definite covariance of ``pose`` (m², m·rad, rad²).
        score: match quality in [0, 1], higher is better. ICP/PL-ICP: fraction of scan points with an inlier
            correspondence. CSM and grid matching: mean lookup value at the scan points (1 = every point on
            a reference point / an occupied cell of probability 1).
        iterations: ICP iterations, or for the correlative matchers the number of candidate poses scored.
        converged: ICP: the last update was below tolerance within ``max_iterations``. Correlative: True.
        degenerate: the geometry does not constrain every direction of the pose (see module doc).
        method: "icp", "plicp", "csm", "bnb" or "brute_force".
    """

    pose: NDArray[np.float64]
    covariance: NDArray[np.float64]
    score: float
    iterations: int
    converged: bool
    degenerate: bool = False
    method: str = ""

    def __post_init__(self) -> None:
        pose = np.array(self.pose, dtype=np.float64).reshape(3)
        cov = np.array(self.covariance, dtype=np.float64).reshape(3, 3)
        pose.setflags(write=False)
        cov.setflags(write=False)
        object.__setattr__(self, "pose", pose)
        object.__setattr__(self, "covariance", cov)


# ---------------------------------------------------------------------------------------------------------
# Input handling
# ---------------------------------------------------------------------------------------------------------


def scan_to_points(
    ranges_m: ArrayLike,
    angles_rad: ArrayLike,
    *,
    min_range_m: float = 0.0,
    max_range_m: float = math.inf,
) -> NDArray[np.float64]:
    """Cartesian points of a range scan in the sensor frame, invalid beams dropped.

    Args:
        ranges_m: (N,) ranges, metres.
        angles_rad: (N,) beam angles relative to the sensor's x axis, radians.
        min_range_m: beams shorter than this (or <= 0) are dropped.
        max_range_m: beams at or beyond this (no return) are dropped; NaN and ±inf always are.

    Returns:
        (M, 2) float64 points (x, y), metres, sensor frame, in beam order.

    Raises:
        ScanMatchError: shapes differ or are not 1-D.
    """
    r = np.asarray(ranges_m, dtype=np.float64)
    a = np.asarray(angles_rad, dtype=np.float64)
    if r.ndim != 1 or r.shape != a.shape:
        raise ScanMatchError(f"ranges and angles must be 1-D of equal length, got {r.shape} and {a.shape}")
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(r) & np.isfinite(a) & (r > 0.0) & (r >= min_range_m) & (r < max_range_m)
    return np.column_stack((r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])))


def _points(xy: ArrayLike, name: str, minimum: int) -> NDArray[np.float64]:
    """(M, 2) C-contiguous float64 finite rows of an (N, 2) array; non-finite rows are dropped."""
    try:
        p = np.asarray(xy, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ScanMatchError(f"{name} must be an (N, 2) array of numbers") from exc
    if p.ndim != 2 or p.shape[1] != 2:
        raise ScanMatchError(f"{name} must have shape (N, 2), got {p.shape}")
    finite = np.isfinite(p)
    p = np.ascontiguousarray(p) if finite.all() else np.ascontiguousarray(p[finite.all(axis=1)])
    if p.shape[0] < minimum:
        raise InsufficientPointsError(f"{name} has {p.shape[0]} finite points, need at least {minimum}")
    if p.size and float(np.abs(p).max()) > _MAX_COORD_M:
        raise ScanMatchError(f"{name} has coordinates beyond ±{_MAX_COORD_M:g} m")
    return p


def _pose3(initial: ArrayLike) -> tuple[float, float, float]:
    try:
        v = np.asarray(initial, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ScanMatchError(f"initial must be (x, y, theta), got {initial!r}") from exc
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ScanMatchError(f"initial must be 3 finite numbers (x, y, theta), got {initial!r}")
    return float(v[0]), float(v[1]), float(v[2])


def _positive(value: float, name: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise ScanMatchError(f"{name} must be finite and > 0, got {value!r}")
    return v


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


# ---------------------------------------------------------------------------------------------------------
# ICP / PL-ICP
# ---------------------------------------------------------------------------------------------------------


def _covariance_from_information(
    H: NDArray[np.float64], sigma2: float, scale: float
) -> tuple[NDArray[np.float64], bool]:
    """σ²·H⁻¹, where rank-deficient directions (relative eigenvalue < _DEGENERACY_RATIO on the problem with θ
    scaled to metres by ``scale``) get the variance _UNOBSERVABLE_VAR (m², or m² per scaled radian) instead;
    returns (covariance, degenerate)."""
    cov, degenerate = kern.information_to_covariance(H, sigma2, scale, _DEGENERACY_RATIO, _UNOBSERVABLE_VAR)
    return cov, bool(degenerate)


def _observable_part(
    H: NDArray[np.float64], scale: float, init: tuple[float, float, float], pose: tuple[float, float, float]
) -> tuple[float, float, float]:
    """``pose`` with its move from ``init`` along the unobservable directions of ``H`` (those
    :func:`_covariance_from_information` flags, θ scaled by ``scale``) taken back: there the scan says nothing, and
    the iterations' steps along them are noise. Along a wall with 1 cm range noise they moved a corridor match
    up to 0.5 m from the prediction, at scan after scan (issue 30: a SLAM estimate 4 m behind the robot after
    13 m along a wall)."""
    d = np.array([1.0, 1.0, scale])
    hs = 0.5 * (H + H.T) / np.outer(d, d)
    w, v = np.linalg.eigh(hs)
    weak = v[:, w < _DEGENERACY_RATIO * max(float(w[-1]), 1e-300)]
    delta = np.array([pose[0] - init[0], pose[1] - init[1], _wrap(pose[2] - init[2])]) * d
    kept = (delta - weak @ (weak.T @ delta)) / d
    return init[0] + float(kept[0]), init[1] + float(kept[1]), init[2] + float(kept[2])


class PointReference:
    """A reference point set prepared once (spatial hash and line normals) for many ICP / PL-ICP matches.

    :func:`scan_match` prepares its reference on every call; a caller matching many scans against the same
    reference (a SLAM front end's local map, a localizer's map points) builds this once and calls :meth:`match`.
    The results are identical to :func:`scan_match` with the same arguments.

    Args:
        reference_xy: (N, 2) reference points, metres, reference frame (non-finite rows dropped). Points from
            consecutive beams of one scan should stay consecutive (the normals use index-contiguous runs).

    Raises:
        InsufficientPointsError: fewer than 3 finite points.
        ScanMatchError: a malformed argument.
    """

    def __init__(self, reference_xy: ArrayLike) -> None:
        ref = _points(reference_xy, "reference_xy", 3)
        self.points = ref
        cell = _HASH_CELL_M
        self._hash = kern.build_hash(ref, cell)
        slot_key, slot_val, starts, order = self._hash
        self._normals, self._line_ok = kern.fit_normals(
            ref,
            slot_key,
            slot_val,
            starts,
            order,
            cell,
            _NORMAL_RADIUS_M,
            _NORMAL_MAX_RADIUS_M,
            _NORMAL_MIN_K,
            _NORMAL_MAX_RATIO,
        )

    def match(
        self,
        scan_xy: ArrayLike,
        initial: ArrayLike = (0.0, 0.0, 0.0),
        method: Literal["icp", "plicp"] = "plicp",
        *,
        max_iterations: int = 100,
        max_correspondence_m: float = 1.0,
        outlier_mult: float = 3.0,
        tolerance_m: float = 1e-5,
        tolerance_rad: float = 1e-6,
    ) -> ScanMatchResult:
        """Register a scan to the prepared reference by ICP or PL-ICP (arguments as :func:`scan_match`).

        Raises:
            InsufficientPointsError: fewer than 3 scan points or correspondences, or (PL-ICP) fewer than 3
                reference points on a line.
            ScanMatchError: unknown method or a malformed argument.
        """
        if method not in ("icp", "plicp"):
            raise ScanMatchError(f"PointReference.match: method must be 'icp' or 'plicp', got {method!r}")
        if not isinstance(max_iterations, int | np.integer) or max_iterations < 1:
            raise ScanMatchError(f"max_iterations must be an integer >= 1, got {max_iterations!r}")
        return self._match(
            _points(scan_xy, "scan_xy", 3),
            _pose3(initial),
            method == "plicp",
            int(max_iterations),
            _positive(max_correspondence_m, "max_correspondence_m"),
            _positive(outlier_mult, "outlier_mult"),
            _positive(tolerance_m, "tolerance_m"),
            _positive(tolerance_rad, "tolerance_rad"),
        )

    def _match(
        self,
        scan: NDArray[np.float64],
        init: tuple[float, float, float],
        point_to_line: bool,
        max_iterations: int,
        max_correspondence_m: float,
        outlier_mult: float,
        tolerance_m: float,
        tolerance_rad: float,
    ) -> ScanMatchResult:
        ref, normals, line_ok = self.points, self._normals, self._line_ok
        slot_key, slot_val, starts, order = self._hash
        if point_to_line and int(line_ok.sum()) < 3:
            raise InsufficientPointsError("the reference has fewer than 3 points on a line (PL-ICP needs lines)")
        scale_len = float(np.sqrt(np.mean(np.sum(scan * scan, axis=1)))) or 1.0
        x, y, th, it, converged, nn, inl = kern.icp_kernel(
            ref,
            normals,
            line_ok,
            slot_key,
            slot_val,
            starts,
            order,
            _HASH_CELL_M,
            scan,
            init[0],
            init[1],
            init[2],
            point_to_line,
            max_iterations,
            max_correspondence_m,
            outlier_mult,
            tolerance_m,
            tolerance_rad,
            1.0 / scale_len,
            _ANNEAL,
        )
        n_in = int(inl.sum())
        if n_in < 3:
            raise InsufficientPointsError(
                f"only {n_in} scan points have a reference point within {max_correspondence_m} m "
                "(too little overlap, or the initial pose is too far off)"
            )
        H, ss, m = kern.point_to_line_hessian(ref, normals, line_ok, scan, nn, inl, x, y, th)
        if m >= 4:
            sigma2 = ss / (m - 3)
        else:  # no lines matched: point-to-point information (isotropic per pair)
            c, s = math.cos(th), math.sin(th)
            pr = scan[inl] @ np.array([[c, s], [-s, c]])
            H = np.zeros((3, 3))
            H[0, 0] = H[1, 1] = n_in
            H[0, 2] = H[2, 0] = -float(pr[:, 1].sum())
            H[1, 2] = H[2, 1] = float(pr[:, 0].sum())
            H[2, 2] = float(np.sum(pr * pr))
            d = ref[nn[inl]] - (pr + np.array([x, y]))
            sigma2 = float(np.sum(d * d)) / max(2 * n_in - 3, 1)
        cov, degenerate = _covariance_from_information(H, sigma2, scale_len)
        if degenerate:
            x, y, th = _observable_part(H, scale_len, init, (x, y, th))
        return ScanMatchResult(
            pose=np.array([x, y, _wrap(th)]),
            covariance=cov,
            score=n_in / scan.shape[0],
            iterations=int(it),
            converged=bool(converged),
            degenerate=degenerate,
            method="plicp" if point_to_line else "icp",
        )


# ---------------------------------------------------------------------------------------------------------
# Correlative matching (CSM, branch and bound)
# ---------------------------------------------------------------------------------------------------------


def _check_depth(depth: int) -> int:
    if not isinstance(depth, int | np.integer) or not 1 <= int(depth) <= 12:
        raise ScanMatchError(f"depth must be an integer in 1..12, got {depth!r}")
    return int(depth)


class CorrelativeGridMatcher:
    """Branch-and-bound correlative matching of scans against one score table (Hess et al. 2016).

    Build once per map (submap), then call :meth:`match` for many scans: the max-pooled pyramid is
    precomputed here. A candidate pose is scored by the mean table value at the cells of the transformed
    scan points (cells outside the table count 0); the search lattice is the table's cells in x and y and a
    fixed angular step in θ, around the initial pose.

    Args:
        values: (H, W) float table, row 0 = lowest y (mjnav grid layout), every value in [0, 1]
            (e.g. occupancy probabilities, or a blurred likelihood).
        frame: the table's :class:`~mjnav.mapping.GridFrame` (axis-aligned: yaw 0).
        depth: pyramid levels (Cartographer's default 7: coarsest cells 64 × 64 fine cells).
        loglik: optional (H, W) table of per-point log-likelihood differences (>= 0, 0 = worst) used for the
            covariance; default log(values / min positive value).
        loglik_scale: instead of ``loglik``: the log-likelihood table is ``values × loglik_scale`` (> 0), as
            :func:`likelihood_field` returns it; no second table is built.

    Raises:
        ScanMatchError: bad shapes, values outside [0, 1], a rotated frame, a bad depth, or both ``loglik`` and
            ``loglik_scale``.
    """

    def __init__(
        self,
        values: ArrayLike,
        frame: GridFrame,
        *,
        depth: int = 7,
        loglik: ArrayLike | None = None,
        loglik_scale: float | None = None,
    ) -> None:
        v = np.asarray(values, dtype=np.float64)
        if v.ndim != 2 or v.size == 0 or tuple(v.shape) != tuple(frame.shape):
            raise ScanMatchError(f"values must be a non-empty (H, W) array matching frame.shape, got {v.shape}")
        finite, lo, hi = kern.table_range(v)
        if not finite or lo < 0.0 or hi > 1.0:
            raise ScanMatchError("values must be finite and within [0, 1]")
        if frame.yaw_rad != 0.0:
            raise ScanMatchError("rotated grid frames are not supported (yaw_rad must be 0)")
        if loglik is not None and loglik_scale is not None:
            raise ScanMatchError("give loglik or loglik_scale, not both")
        self.depth = _check_depth(depth)
        self.frame = frame
        # Pad low sides so a level-h block starting left of/below the grid is representable (exact bounds).
        self._pad = (1 << (self.depth - 1)) if self.depth > 1 else 0
        pad = self._pad
        self._pyramid = kern.max_pyramid(v, pad, self.depth)
        if loglik_scale is not None:
            scale = float(loglik_scale)
            if not (math.isfinite(scale) and scale > 0.0):
                raise ScanMatchError(f"loglik_scale must be finite and > 0, got {loglik_scale!r}")
            self._loglik, self._ll_scale = self._pyramid[0], scale
            return
        if loglik is None:
            pos = v[v > 0.0]
            floor = float(pos.min()) if pos.size else 1.0
            ll = np.log(np.maximum(v, floor) / floor)
        else:
            ll = np.asarray(loglik, dtype=np.float64)
            if ll.shape != v.shape or not np.all(np.isfinite(ll)) or ll.min() < 0.0:
                raise ScanMatchError("loglik must be a finite (H, W) array >= 0 matching values")
        self._loglik = np.zeros((v.shape[0] + pad, v.shape[1] + pad))
        self._loglik[pad:, pad:] = ll
        self._ll_scale = 1.0

    @classmethod
    def from_occupancy_grid(cls, grid: OccupancyGrid, *, depth: int = 7) -> CorrelativeGridMatcher:
        """Matcher over an occupancy grid's probabilities (row 0 = lowest y, the grid's own frame).

        Cells never updated (log-odds exactly the prior) count as the model's lowest probability,
        p(min_log_odds), as Cartographer treats unknown cells; the others use 1 / (1 + exp(−l)).
        """
        p = grid.probabilities()
        p_min = float(log_odds_to_prob(grid.model.min_log_odds))
        p = np.where(grid.log_odds == grid.model.prior_log_odds, p_min, p)
        frame = GridFrame(grid.resolution_m, grid.origin_m, grid.shape)
        return cls(p, frame, depth=depth)

    # -- search ----------------------------------------------------------------------------------------------

    def _lattice(
        self,
        scan: NDArray[np.float64],
        init: tuple[float, float, float],
        linear_window_m: float,
        angular_window_rad: float,
        angular_step_rad: float | None,
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], int, int, float]:
        res = self.frame.resolution_m
        if not (math.isfinite(linear_window_m) and linear_window_m >= 0.0):
            raise ScanMatchError(f"linear_window_m must be finite and >= 0, got {linear_window_m}")
        if not (math.isfinite(angular_window_rad) and 0.0 <= angular_window_rad <= math.pi):
            raise ScanMatchError(f"angular_window_rad must be in [0, pi], got {angular_window_rad}")
        d_max = float(np.sqrt(np.max(np.sum(scan * scan, axis=1))))
        if angular_step_rad is None:
            # Cartographer: the farthest point moves by at most one cell per step.
            arg = 1.0 - res * res / (2.0 * max(d_max, res) ** 2)
            step = math.acos(max(arg, -1.0))
        else:
            step = _positive(angular_step_rad, "angular_step_rad")
        n_ang = math.ceil(angular_window_rad / step - 1e-9) if angular_window_rad > 0 else 0
        w = math.ceil(linear_window_m / res - 1e-9)
        thetas = init[2] + step * np.arange(-n_ang, n_ang + 1)
        c, s = np.cos(thetas)[:, None], np.sin(thetas)[:, None]
        wx = c * scan[:, 0] - s * scan[:, 1] + init[0]
        wy = s * scan[:, 0] + c * scan[:, 1] + init[1]
        ox, oy = self.frame.origin_m
        cols = np.floor((wx - ox) / res).astype(np.int64) + self._pad
        rows = np.floor((wy - oy) / res).astype(np.int64) + self._pad
        return np.ascontiguousarray(rows), np.ascontiguousarray(cols), w, n_ang, step

    def _result(
        self,
        rows: NDArray[np.int64],
        cols: NDArray[np.int64],
        init: tuple[float, float, float],
        a: int,
        dr: int,
        dc: int,
        n_ang: int,
        step: float,
        scored: int,
        method: str,
    ) -> ScanMatchResult:
        res = self.frame.resolution_m
        total = kern.lattice_score(self._pyramid[0], rows, cols, a, dr, dc)
        cov = kern.neighbourhood_moments(self._loglik, rows, cols, a, dr, dc, 2, res, step, self._ll_scale)
        cov = 0.5 * (cov + cov.T) + np.diag([res * res / 12.0, res * res / 12.0, step * step / 12.0])
        pose = np.array([init[0] + dc * res, init[1] + dr * res, _wrap(init[2] + (a - n_ang) * step)])
        return ScanMatchResult(
            pose=pose,
            covariance=cov,
            score=total / rows.shape[1],
            iterations=int(scored),
            converged=True,
            degenerate=False,
            method=method,
        )

    def match(
        self,
        scan_xy: ArrayLike,
        initial: ArrayLike = (0.0, 0.0, 0.0),
        *,
        linear_window_m: float = 7.0,
        angular_window_rad: float = math.radians(30.0),
        angular_step_rad: float | None = None,
        min_score: float = 0.0,
        translation_cost: float = 0.0,
        rotation_cost: float = 0.0,
    ) -> ScanMatchResult:
        """Best pose of the search lattice by branch and bound (exact: equals :meth:`match_brute_force`).

        Args:
            scan_xy: (N, 2) scan points, metres, scan frame (non-finite rows dropped).
            initial: (x, y, θ) centre of the search window: scan frame in the table's frame.
            linear_window_m: half-width of the square window in x and y, metres (Cartographer's
                ``linear_search_window``, default 7 m: offsets in [−7, 7] m).
            angular_window_rad: half-width of the angular window, radians (default 30°).
            angular_step_rad: angular lattice step; default Cartographer's acos(1 − r²/(2·d²)) with r the
                cell size and d the farthest scan point's range.
            min_score: only poses with mean score strictly above this are accepted.
            translation_cost, rotation_cost: a prior towards ``initial``: a pose's mean score counts
                ``translation_cost``·|Δt|² + ``rotation_cost``·Δθ² less (per m², per rad²; Cartographer's
                real-time matcher weighs its candidates the same way). Where the scan pins the pose only partly
                (a corridor: every offset along it scores alike) the search then keeps ``initial`` there instead
                of the first of the equal offsets, a window's width off. 0 (default): no prior.

        Returns:
            :class:`ScanMatchResult` (``iterations`` = candidate nodes scored, method "bnb"; ``score`` without
            the prior).

        Raises:
            InsufficientPointsError: no finite scan point.
            NoMatchError: nothing in the window scores above ``min_score``.
        """
        scan = _points(scan_xy, "scan_xy", 1)
        init = _pose3(initial)
        rows, cols, w, n_ang, step = self._lattice(scan, init, linear_window_m, angular_window_rad, angular_step_rad)
        n = scan.shape[0]
        pen_cell, pen_ang = self._prior(n, step, translation_cost, rotation_cost)
        a, dr, dc, total, scored = kern.branch_and_bound(
            self._pyramid, rows, cols, w, w, float(min_score) * n, n_ang, pen_cell, pen_ang
        )
        if not math.isfinite(total):
            raise NoMatchError(f"no pose within the window scores above {min_score}")
        return self._result(rows, cols, init, a, dr, dc, n_ang, step, scored, "bnb")

    def match_brute_force(
        self,
        scan_xy: ArrayLike,
        initial: ArrayLike = (0.0, 0.0, 0.0),
        *,
        linear_window_m: float = 7.0,
        angular_window_rad: float = math.radians(30.0),
        angular_step_rad: float | None = None,
        translation_cost: float = 0.0,
        rotation_cost: float = 0.0,
    ) -> ScanMatchResult:
        """Score every pose of the lattice :meth:`match` searches (the reference it must equal; slow).

        Same arguments as :meth:`match`; ties keep the first pose in (θ, y, x) order. Method "brute_force".
        """
        scan = _points(scan_xy, "scan_xy", 1)
        init = _pose3(initial)
        rows, cols, w, n_ang, step = self._lattice(scan, init, linear_window_m, angular_window_rad, angular_step_rad)
        pen_cell, pen_ang = self._prior(scan.shape[0], step, translation_cost, rotation_cost)
        a, dr, dc, _total = kern.brute_force(self._pyramid[0], rows, cols, w, w, n_ang, pen_cell, pen_ang)
        scored = rows.shape[0] * (2 * w + 1) ** 2
        return self._result(rows, cols, init, a, dr, dc, n_ang, step, scored, "brute_force")

    def _prior(self, n: int, step: float, translation_cost: float, rotation_cost: float) -> tuple[float, float]:
        """The prior's penalties per lattice cell² and angle step², in summed-score units of ``n`` points."""
        for name, value in (("translation_cost", translation_cost), ("rotation_cost", rotation_cost)):
            if not (math.isfinite(value) and value >= 0.0):
                raise ScanMatchError(f"{name} must be finite and >= 0, got {value}")
        res = self.frame.resolution_m
        return n * translation_cost * res * res, n * rotation_cost * step * step


def likelihood_field(
    reference_xy: ArrayLike, resolution_m: float, sigma_m: float | None = None
) -> tuple[NDArray[np.float64], GridFrame, float]:
    """Olson's (2009) rasterised per-point likelihood of a reference point set (the CSM lookup table).

    Each cell holds log(exp(−d²/2σ²) + 0.01) of the distance d from its centre to the nearest reference point's
    cell (a Gaussian mixed with a uniform floor of weight 1 %, so outliers cost a bounded amount), rescaled
    linearly to [0, 1] (0 = the floor, also the value outside the table). It is evaluated within 4σ of the
    reference cells and is the floor beyond (where the exact value is within 0.5 % of the range above the
    floor). The table covers the points' bounding box grown by 4σ + 2 cells.

    Args:
        reference_xy: (N, 2) reference points, metres (non-finite rows dropped; at least 1).
        resolution_m: cell size, metres.
        sigma_m: likelihood width, metres (default 2 × resolution).

    Returns:
        (table (H, W) in [0, 1], its :class:`~mjnav.mapping.GridFrame`, scale): table × scale is the
        log-likelihood difference to the floor (what :class:`CorrelativeGridMatcher` takes as ``loglik``).

    Raises:
        InsufficientPointsError: no finite point.
        ScanMatchError: a bad resolution or width, or a table of more than 5e7 cells.
    """
    ref = _points(reference_xy, "reference_xy", 1)
    res = _positive(resolution_m, "resolution_m")
    sigma = _positive(sigma_m, "sigma_m") if sigma_m is not None else 2.0 * res
    margin = 4.0 * sigma + 2.0 * res
    lo = ref.min(axis=0) - margin
    hi = ref.max(axis=0) + margin
    shape = (math.ceil((hi[1] - lo[1]) / res) + 1, math.ceil((hi[0] - lo[0]) / res) + 1)
    if shape[0] * shape[1] > 50_000_000:
        raise ScanMatchError(f"likelihood table of {shape} cells is too large; raise the resolution")
    frame = GridFrame(res, (float(lo[0]), float(lo[1])), shape)
    cells = frame.world_to_cells(ref)
    eps = 0.01
    scale = math.log(1.0 + eps) - math.log(eps)
    table = kern.likelihood_stamp(
        np.ascontiguousarray(cells[:, 0]), np.ascontiguousarray(cells[:, 1]), shape[0], shape[1], res, sigma, eps
    )
    return table / scale, frame, scale


def _csm(
    ref: NDArray[np.float64],
    scan: NDArray[np.float64],
    init: tuple[float, float, float],
    resolution_m: float,
    window_m: float,
    window_rad: float,
    sigma_m: float | None,
) -> ScanMatchResult:
    res = _positive(resolution_m, "csm_resolution_m")
    table, frame, scale = likelihood_field(ref, res, sigma_m)
    w = math.ceil(window_m / res - 1e-9)
    depth = max(1, min(8, math.ceil(math.log2(2 * w + 1)) + 1))
    matcher = CorrelativeGridMatcher(table, frame, depth=depth, loglik_scale=scale)
    out = matcher.match(scan, init, linear_window_m=window_m, angular_window_rad=window_rad, min_score=-1.0)
    return ScanMatchResult(
        pose=out.pose,
        covariance=out.covariance,
        score=out.score,
        iterations=out.iterations,
        converged=True,
        degenerate=False,
        method="csm",
    )


# ---------------------------------------------------------------------------------------------------------
# Public entry point
# ---------------------------------------------------------------------------------------------------------


def scan_match(
    reference_xy: ArrayLike,
    scan_xy: ArrayLike,
    initial: ArrayLike = (0.0, 0.0, 0.0),
    method: Literal["icp", "plicp", "csm"] = "icp",
    *,
    max_iterations: int = 100,
    max_correspondence_m: float = 1.0,
    outlier_mult: float = 3.0,
    tolerance_m: float = 1e-5,
    tolerance_rad: float = 1e-6,
    csm_resolution_m: float = 0.02,
    csm_window_m: float = 0.3,
    csm_window_rad: float = math.radians(10.0),
    csm_sigma_m: float | None = None,
) -> ScanMatchResult:
    """Register a 2-D scan to a reference point set.

    Args:
        reference_xy: (N, 2) reference points, metres, reference frame (non-finite rows dropped).
        scan_xy: (M, 2) scan points, metres, scan frame (non-finite rows dropped).
        initial: (x, y, θ) initial guess of the scan frame's pose in the reference frame (see module doc).
        method: "icp" (point-to-point), "plicp" (point-to-line, Censi) or "csm" (correlative, Olson).
        max_iterations: ICP/PL-ICP iteration cap.
        max_correspondence_m: ICP/PL-ICP: a scan point farther than this from every reference point has no
            correspondence.
        outlier_mult: ICP/PL-ICP adaptive trimming: pairs whose residual exceeds this × the median residual
            are ignored in that iteration.
        tolerance_m: ICP/PL-ICP stop when an update moves less than this (metres) ...
        tolerance_rad: ... and turns less than this (radians).
        csm_resolution_m: CSM lookup-table cell size, metres (the accuracy of the result).
        csm_window_m: CSM search half-width in x and y around ``initial``, metres.
        csm_window_rad: CSM search half-width in θ, radians (the step is set by the resolution).
        csm_sigma_m: CSM likelihood width, metres (default 2 × resolution).

    Returns:
        :class:`ScanMatchResult`.

    Raises:
        InsufficientPointsError: fewer than 3 finite points in either set, or too few correspondences.
        ScanMatchError: unknown method or parameter, or a malformed argument.
    """
    if method not in METHODS:
        raise ScanMatchError(f"method must be one of {METHODS}, got {method!r}")
    ref = _points(reference_xy, "reference_xy", 3)
    scan = _points(scan_xy, "scan_xy", 3)
    init = _pose3(initial)
    if method == "csm":
        return _csm(ref, scan, init, csm_resolution_m, csm_window_m, csm_window_rad, csm_sigma_m)
    if not isinstance(max_iterations, int | np.integer) or max_iterations < 1:
        raise ScanMatchError(f"max_iterations must be an integer >= 1, got {max_iterations!r}")
    return PointReference(ref)._match(
        scan,
        init,
        method == "plicp",
        int(max_iterations),
        _positive(max_correspondence_m, "max_correspondence_m"),
        _positive(outlier_mult, "outlier_mult"),
        _positive(tolerance_m, "tolerance_m"),
        _positive(tolerance_rad, "tolerance_rad"),
    )

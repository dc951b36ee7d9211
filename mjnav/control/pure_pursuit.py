"""Regulated pure pursuit path tracking for a differential-drive robot."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from mjnav.control._track import (
    PathProgress,
    PoseInput,
    check_params,
    chord_blocked,
    lookahead_point,
    signed_cross_track,
    unpack_pose,
)
from mjnav.control.regulation import (
    adaptive_lookahead,
    approach_regulated_speed,
    clamp_yaw_rate,
    curvature_regulated_speed,
    proximity_regulated_speed,
    pursuit_curvature,
    rotate_in_place_rate,
)
from mjnav.geometry import wrap_angle

Mode = Literal["idle", "tracking", "rotating", "reached"]


@dataclass(frozen=True, slots=True)
class PurePursuitParams:
    """Parameters of :class:`PurePursuit` (defaults suit a small indoor robot at 0.5 m/s).

    Attributes:
        desired_speed_mps: cruise speed before regulation, m/s, > 0 (overridable per call).
        lookahead_gain_s: g in L = v·g, seconds, >= 0.
        min_lookahead_m: L_min, metres, > 0.
        max_lookahead_m: L_max, metres, >= L_min.
        curvature_threshold_invm: κ_h of the curvature heuristic, 1/m, > 0.
        min_regulated_speed_mps: floor of the curvature heuristic, m/s, >= 0.
        proximity_distance_m: d_prox of the proximity heuristic, metres, > 0.
        approach_distance_m: start of the slow-down before the goal (remaining path length), metres, > 0.
        min_approach_speed_mps: speed floor while approaching, m/s, > 0.
        goal_tolerance_m: stop when the goal is this close (and the remaining path too), metres, > 0.
        rotate_threshold_rad: rotate in place when the lookahead point's bearing exceeds this, rad.
        rotate_gain_per_s: proportional gain of the rotation in place, 1/s.
        max_rotate_speed_radps: yaw-rate limit while rotating in place, rad/s.
        max_angular_speed_radps: yaw-rate limit while tracking (v is lowered to keep the curvature), rad/s.
        search_window_m: how far along the path (from the last closest point) the closest-point search
            looks, metres, > 0.
    """

    desired_speed_mps: float = 0.5
    lookahead_gain_s: float = 1.0
    min_lookahead_m: float = 0.3
    max_lookahead_m: float = 1.5
    curvature_threshold_invm: float = 1.0
    min_regulated_speed_mps: float = 0.1
    proximity_distance_m: float = 0.7
    approach_distance_m: float = 0.6
    min_approach_speed_mps: float = 0.05
    goal_tolerance_m: float = 0.1
    rotate_threshold_rad: float = math.pi / 4.0
    rotate_gain_per_s: float = 2.0
    max_rotate_speed_radps: float = 1.0
    max_angular_speed_radps: float = 1.5
    search_window_m: float = 2.0

    def __post_init__(self) -> None:
        check_params(
            self,
            positive=(
                "desired_speed_mps",
                "min_lookahead_m",
                "max_lookahead_m",
                "curvature_threshold_invm",
                "proximity_distance_m",
                "approach_distance_m",
                "min_approach_speed_mps",
                "goal_tolerance_m",
                "rotate_threshold_rad",
                "rotate_gain_per_s",
                "max_rotate_speed_radps",
                "max_angular_speed_radps",
                "search_window_m",
            ),
            non_negative=("lookahead_gain_s", "min_regulated_speed_mps"),
        )
        if self.max_lookahead_m < self.min_lookahead_m:
            raise ValueError("PurePursuitParams.max_lookahead_m must be >= min_lookahead_m")


@dataclass(frozen=True, slots=True)
class PursuitStatus:
    """What the last :meth:`PurePursuit.compute` call saw and decided.

    Attributes:
        mode: "idle" (no call yet), "tracking", "rotating" (in place) or "reached" (stopped at the goal).
        closest_index: segment index of the closest path point.
        cross_track_m: signed distance from the path (left of the path positive), metres.
        lookahead_m: distance to the lookahead point, metres.
        lookahead_point: (x, y) of the lookahead point, metres.
        curvature_invm: pursuit curvature κ = 2y'/L², 1/m.
        remaining_m: path length from the closest point to the goal, metres.
        distance_to_goal_m: straight-line distance to the goal, metres.
        v_mps: commanded speed, m/s.
        omega_radps: commanded yaw rate, rad/s.
    """

    mode: Mode
    closest_index: int
    cross_track_m: float
    lookahead_m: float
    lookahead_point: tuple[float, float]
    curvature_invm: float
    remaining_m: float
    distance_to_goal_m: float
    v_mps: float
    omega_radps: float


class PurePursuit:
    """Regulated pure pursuit: adaptive lookahead, curvature/proximity/approach regulation, goal stop.

    The tracker keeps state between calls: the first call on a path searches the whole path for the
    closest point, later calls search forward from the previous closest segment only (within
    ``search_window_m``), and "goal reached" latches until
    :meth:`reset` or a different path. Handing the same path array on every call costs nothing; a new
    path (different contents) is prepared once and restarts the tracker automatically. The path is
    copied when first seen, so modifying the caller's array in place is not noticed; pass a new array or
    call :meth:`reset`. Consecutive repeated points are dropped, and :attr:`closest_index` refers to the
    path without them.

    Example:
        >>> pp = PurePursuit()
        >>> v, omega = pp.compute((0.0, 0.0, 0.0), 0.0, path)  # doctest: +SKIP
    """

    def __init__(self, params: PurePursuitParams | None = None) -> None:
        self.params = params if params is not None else PurePursuitParams()
        self._progress = PathProgress()
        self._mode: Mode = "idle"
        self._last = (0.0, 0.0, 0.0, math.nan, math.nan, math.nan, math.nan, 0.0, 0.0)

    def reset(self) -> None:
        """Forget the path and the tracking state (call when a new goal or path arrives)."""
        self._progress.reset()
        self._mode = "idle"

    @property
    def goal_reached(self) -> bool:
        """True once the robot has stopped within the goal tolerance (latched until reset / new path)."""
        return self._progress.reached

    @property
    def closest_index(self) -> int:
        """Segment index of the last closest point (the forward search starts here)."""
        return self._progress.index

    @property
    def status(self) -> PursuitStatus:
        """Details of the last :meth:`compute` call."""
        ct, la, kap, lx, ly, rem, dg, v, w = self._last
        return PursuitStatus(self._mode, self._progress.index, ct, la, (lx, ly), kap, rem, dg, v, w)

    def compute(
        self,
        pose: PoseInput,
        speed_mps: float,
        path: ArrayLike,
        obstacle_distance_m: float = math.inf,
        *,
        target_speed_mps: float | None = None,
        obstacles_xy: ArrayLike | None = None,
        chord_clearance_m: float = 0.0,
    ) -> tuple[float, float]:
        """One control step: the (v, ω) command that pursues the path.

        Steps: closest point (forward search from the last one; the whole path on the first call);
        lookahead L = clamp(|v|·g, L_min, L_max) with v = ``speed_mps``; lookahead point = first path
        point at distance >= L from the robot (interpolated on its segment; the goal when the rest of
        the path is closer); its robot-frame offset (x', y') gives κ = 2y'/L² (L the actual distance to
        it). If the bearing atan2(y', x') exceeds the rotate threshold the robot turns on the spot.
        Otherwise the speed is the target speed reduced by the curvature heuristic, the proximity
        heuristic and the approach slow-down (the smallest wins), ω = κ·v, and |ω| is capped by lowering
        v (keeping κ). Within the goal tolerance the command is (0, 0) and :attr:`goal_reached` becomes
        True.

        Args:
            pose: robot pose (x m, y m, θ rad) as a tuple, (3,) array or Pose2D, path frame.
            speed_mps: current forward speed of the robot, m/s (sets the lookahead).
            path: (N, 2) path, metres, N >= 2; pass the same array each call (or equal contents).
            obstacle_distance_m: distance to the nearest obstacle, metres (inf: none).
            target_speed_mps: cruise speed for this step, m/s (default ``params.desired_speed_mps``),
                e.g. from a velocity profile.
            obstacles_xy: (M, 2) obstacle points in the path frame (e.g. the newest scan), or None. With them the
                lookahead is shortened (by quarters, down to half ``min_lookahead_m``) while the straight chord
                from the robot to the lookahead point passes within ``chord_clearance_m`` of one: the pursuit
                arc stays near the chord, so a long lookahead around a corner would cut it.
            chord_clearance_m: the clearance the chord must keep, metres (the robot's radius plus a margin).

        Returns:
            (v m/s, ω rad/s).

        Raises:
            PathError: invalid path (fewer than 2 distinct points, NaN, wrong shape).
            ValueError: non-finite pose or speed, NaN obstacle distance or negative target speed.
        """
        x, y, th = unpack_pose(pose)
        if not math.isfinite(speed_mps):
            raise ValueError(f"speed_mps must be finite, got {speed_mps}")
        if math.isnan(obstacle_distance_m):
            raise ValueError("obstacle_distance_m is NaN")
        p = self.params
        target = p.desired_speed_mps if target_speed_mps is None else float(target_speed_mps)
        if not (math.isfinite(target) and target >= 0.0):
            raise ValueError(f"target_speed_mps must be finite and >= 0, got {target_speed_mps}")
        prepared, k, t, d2, _ = self._progress.locate(path, x, y, p.search_window_m)
        pts = prepared.points
        remaining = prepared.remaining(k, t)
        goal_x, goal_y = pts[-1, 0], pts[-1, 1]
        dist_goal = math.hypot(goal_x - x, goal_y - y)
        cross = signed_cross_track(pts, k, x, y, d2)

        if self._progress.at_goal(dist_goal, remaining, p.goal_tolerance_m):
            self._mode = "reached"
            self._last = (cross, 0.0, 0.0, goal_x, goal_y, remaining, dist_goal, 0.0, 0.0)
            return 0.0, 0.0

        look = adaptive_lookahead(speed_mps, p.lookahead_gain_s, p.min_lookahead_m, p.max_lookahead_m)
        lx, ly, _ = lookahead_point(pts, x, y, k, t, look)
        if obstacles_xy is not None and chord_clearance_m > 0.0:
            obstacles = np.ascontiguousarray(obstacles_xy, dtype=np.float64).reshape(-1, 2)
            while look > 0.5 * p.min_lookahead_m and chord_blocked(x, y, lx, ly, obstacles, chord_clearance_m):
                look *= 0.75
                lx, ly, _ = lookahead_point(pts, x, y, k, t, look)
        c, s = math.cos(th), math.sin(th)
        dx, dy = lx - x, ly - y
        xr = c * dx + s * dy
        yr = -s * dx + c * dy
        dist = math.hypot(xr, yr)
        bearing = math.atan2(yr, xr)
        if abs(bearing) > p.rotate_threshold_rad:
            omega = rotate_in_place_rate(wrap_angle(bearing), p.rotate_gain_per_s, p.max_rotate_speed_radps)
            self._mode = "rotating"
            self._last = (cross, dist, 0.0, lx, ly, remaining, dist_goal, 0.0, omega)
            return 0.0, omega

        kappa = pursuit_curvature(yr, dist) if dist > 1e-9 else 0.0
        v = min(
            curvature_regulated_speed(target, kappa, p.curvature_threshold_invm, p.min_regulated_speed_mps),
            proximity_regulated_speed(target, obstacle_distance_m, p.proximity_distance_m),
            approach_regulated_speed(target, remaining, p.approach_distance_m, p.min_approach_speed_mps),
        )
        v, omega = clamp_yaw_rate(v, kappa * v, p.max_angular_speed_radps)
        self._mode = "tracking"
        self._last = (cross, dist, kappa, lx, ly, remaining, dist_goal, v, omega)
        return v, omega

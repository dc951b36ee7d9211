"""Path-frame tracking errors and the shared skeleton of the error-feedback trackers (PID, LQR)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from numpy.typing import ArrayLike

from mjnav.control._track import (
    PathProgress,
    PoseInput,
    PreparedPath,
    check_params,
    project_forward,
    signed_cross_track,
    unpack_pose,
)
from mjnav.control.regulation import (
    approach_regulated_speed,
    clamp_yaw_rate,
    proximity_regulated_speed,
    rotate_in_place_rate,
)
from mjnav.geometry import wrap_angle


@dataclass(frozen=True, slots=True)
class TrackingError:
    """The robot's pose relative to its closest path point.

    Attributes:
        segment_index: index k of the closest segment (points k and k+1).
        fraction: position t in [0, 1] of the closest point along segment k.
        cross_track_m: signed lateral error e_y, metres (robot left of the path positive).
        heading_error_rad: e_θ = θ_robot - θ_path, radians in [-π, π).
        path_heading_rad: path tangent heading at the closest point (vertex headings interpolated), rad.
        path_curvature_invm: path curvature at the closest point (vertex curvatures interpolated), 1/m.
        remaining_m: path length from the closest point to the end, metres.
        distance_to_goal_m: straight-line distance from the robot to the last path point, metres.
    """

    segment_index: int
    fraction: float
    cross_track_m: float
    heading_error_rad: float
    path_heading_rad: float
    path_curvature_invm: float
    remaining_m: float
    distance_to_goal_m: float


def _error(prepared: PreparedPath, x: float, y: float, th: float, k: int, t: float, d2: float) -> TrackingError:
    """The tracking error of pose (x, y, θ) whose closest point is at fraction t of segment k (distance² d2)."""
    pts = prepared.points
    cross = signed_cross_track(pts, k, x, y, d2)
    head = prepared.headings
    path_heading = wrap_angle(head[k] + t * wrap_angle(head[k + 1] - head[k]))
    curv = prepared.curvature
    kappa = (1.0 - t) * curv[k] + t * curv[k + 1]
    return TrackingError(
        k,
        t,
        cross,
        wrap_angle(th - path_heading),
        path_heading,
        float(kappa),
        prepared.remaining(k, t),
        math.hypot(pts[-1, 0] - x, pts[-1, 1] - y),
    )


def tracking_error(
    path: ArrayLike, pose: PoseInput, *, start_index: int = 0, search_window_m: float = math.inf
) -> TrackingError:
    """Closest point, lateral and heading error of a pose with respect to a path.

    Args:
        path: (N, 2) path, metres, N >= 2.
        pose: (x m, y m, θ rad) tuple, (3,) array or Pose2D.
        start_index: first segment searched.
        search_window_m: arc length searched beyond ``start_index``, metres (inf: whole path).

    Returns:
        The :class:`TrackingError`.
    """
    prepared = PreparedPath(path)
    if not 0 <= start_index < prepared.points.shape[0] - 1:
        raise ValueError(f"start_index must be in [0, {prepared.points.shape[0] - 2}], got {start_index}")
    x, y, th = unpack_pose(pose)
    k, t, d2 = project_forward(prepared.points, prepared.cum, x, y, start_index, search_window_m)
    return _error(prepared, x, y, th, k, t, d2)


@dataclass(frozen=True, slots=True)
class TrackerParams:
    """Speed, goal and rotation settings shared by :class:`PIDTracker` and :class:`LQRTracker`.

    Attributes:
        desired_speed_mps: cruise speed, m/s, > 0 (overridable per call).
        dt_s: control period, s, > 0 (overridable per call).
        max_angular_speed_radps: yaw-rate limit (v is lowered to keep the curvature), rad/s, > 0.
        proximity_distance_m: d_prox of the proximity heuristic, metres, > 0.
        approach_distance_m: remaining path length where the slow-down starts, metres, > 0.
        min_approach_speed_mps: speed floor while approaching, m/s, > 0.
        goal_tolerance_m: stop within this distance of the goal, metres, > 0.
        rotate_threshold_rad: turn in place when |heading error| exceeds this, rad, > 0.
        rotate_gain_per_s: proportional gain of the rotation in place, 1/s, > 0.
        max_rotate_speed_radps: yaw-rate limit while rotating in place, rad/s, > 0.
        search_window_m: arc length searched ahead of the last closest point, metres, > 0.
    """

    desired_speed_mps: float = 0.5
    dt_s: float = 0.05
    max_angular_speed_radps: float = 1.5
    proximity_distance_m: float = 0.7
    approach_distance_m: float = 0.6
    min_approach_speed_mps: float = 0.05
    goal_tolerance_m: float = 0.1
    rotate_threshold_rad: float = math.pi / 2.0
    rotate_gain_per_s: float = 2.0
    max_rotate_speed_radps: float = 1.0
    search_window_m: float = 2.0

    def __post_init__(self) -> None:
        check_params(
            self,
            positive=(
                "desired_speed_mps",
                "dt_s",
                "max_angular_speed_radps",
                "proximity_distance_m",
                "approach_distance_m",
                "min_approach_speed_mps",
                "goal_tolerance_m",
                "rotate_threshold_rad",
                "rotate_gain_per_s",
                "max_rotate_speed_radps",
                "search_window_m",
            ),
        )


class ErrorFeedbackTracker:
    """Skeleton of a tracker that steers on the path-frame error (subclasses implement :meth:`_steer`).

    Shares the interface of :class:`mjnav.control.PurePursuit`: ``compute``, ``reset``,
    ``goal_reached``; the last :class:`TrackingError` is available as :attr:`last_error`.
    """

    def __init__(self, params: TrackerParams) -> None:
        self.params = params
        self._progress = PathProgress()
        self._last_error: TrackingError | None = None

    def reset(self) -> None:
        """Forget the path and all tracking/controller state."""
        self._progress.reset()
        self._last_error = None
        self._reset_controller()

    def _reset_controller(self) -> None:
        """Clear controller-specific state (integrators, ...)."""

    def _steer(self, error: TrackingError, v_mps: float, dt_s: float) -> float:
        raise NotImplementedError

    @property
    def goal_reached(self) -> bool:
        """True once stopped within the goal tolerance (latched until reset / new path)."""
        return self._progress.reached

    @property
    def last_error(self) -> TrackingError | None:
        """The tracking error seen by the last :meth:`compute` call."""
        return self._last_error

    def compute(
        self,
        pose: PoseInput,
        speed_mps: float,
        path: ArrayLike,
        obstacle_distance_m: float = math.inf,
        *,
        target_speed_mps: float | None = None,
        dt_s: float | None = None,
    ) -> tuple[float, float]:
        """One control step: (v, ω) from the path-frame error.

        The speed is the target speed reduced by the proximity heuristic and the approach slow-down; a
        heading error beyond ``rotate_threshold_rad`` turns the robot in place; within the goal tolerance
        the command is (0, 0) and :attr:`goal_reached` latches.

        Args:
            pose: robot pose (x m, y m, θ rad) as a tuple, (3,) array or Pose2D.
            speed_mps: current forward speed, m/s (accepted for interface parity with PurePursuit; these
                trackers command their own speed and linearise at it).
            path: (N, 2) path, metres.
            obstacle_distance_m: distance to the nearest obstacle, metres.
            target_speed_mps: cruise speed for this step, m/s (default ``params.desired_speed_mps``).
            dt_s: time since the previous call, s (default ``params.dt_s``).

        Returns:
            (v m/s, ω rad/s).
        """
        x, y, th = unpack_pose(pose)
        if not math.isfinite(speed_mps):
            raise ValueError(f"speed_mps must be finite, got {speed_mps}")
        if math.isnan(obstacle_distance_m):
            raise ValueError("obstacle_distance_m is NaN")
        p = self.params
        target = p.desired_speed_mps if target_speed_mps is None else float(target_speed_mps)
        step = p.dt_s if dt_s is None else float(dt_s)
        if not (math.isfinite(target) and target >= 0.0 and math.isfinite(step) and step > 0.0):
            raise ValueError(f"need target speed >= 0 and dt > 0, got ({target_speed_mps}, {dt_s})")
        prepared, k, t, d2, is_new = self._progress.locate(path, x, y, p.search_window_m)
        if is_new:
            self._reset_controller()
        err = _error(prepared, x, y, th, k, t, d2)
        self._last_error = err
        if self._progress.at_goal(err.distance_to_goal_m, err.remaining_m, p.goal_tolerance_m):
            return 0.0, 0.0
        if abs(err.heading_error_rad) > p.rotate_threshold_rad:
            return 0.0, rotate_in_place_rate(-err.heading_error_rad, p.rotate_gain_per_s, p.max_rotate_speed_radps)
        v = min(
            proximity_regulated_speed(target, obstacle_distance_m, p.proximity_distance_m),
            approach_regulated_speed(target, err.remaining_m, p.approach_distance_m, p.min_approach_speed_mps),
        )
        return clamp_yaw_rate(v, self._steer(err, v, step), p.max_angular_speed_radps)

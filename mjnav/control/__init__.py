"""Path-tracking control: regulated pure pursuit and its regulation terms, PID and LQR; the collision monitor
under every velocity command.

All trackers share one interface: ``compute(pose, speed_mps, path, obstacle_distance_m=inf) -> (v, ω)``,
``reset()`` and ``goal_reached``. Paths are (N, 2) float arrays in metres.
"""

from mjnav.control.collision_monitor import (
    CollisionMonitor,
    CollisionMonitorParams,
    MonitorAction,
    MonitorResult,
    Zone,
    convex_polygon,
    default_zones,
    offset_polygon,
)
from mjnav.control.errors import ControlDesignError, MonitorInputError, PathError
from mjnav.control.lqr import LQR, LQRTracker, LQRTrackerParams, lateral_error_model
from mjnav.control.obstacles import moving_away, nearest_obstacle_ahead
from mjnav.control.pid import PID, PIDTracker, PIDTrackerParams
from mjnav.control.pure_pursuit import PurePursuit, PurePursuitParams, PursuitStatus
from mjnav.control.regulation import (
    adaptive_lookahead,
    angular_velocity,
    approach_regulated_speed,
    clamp_yaw_rate,
    curvature_regulated_speed,
    proximity_regulated_speed,
    pursuit_curvature,
    rotate_in_place_rate,
)
from mjnav.control.tracking import ErrorFeedbackTracker, TrackerParams, TrackingError, tracking_error

__all__ = [
    "LQR",
    "PID",
    "CollisionMonitor",
    "CollisionMonitorParams",
    "ControlDesignError",
    "ErrorFeedbackTracker",
    "LQRTracker",
    "LQRTrackerParams",
    "MonitorAction",
    "MonitorInputError",
    "MonitorResult",
    "PIDTracker",
    "PIDTrackerParams",
    "PathError",
    "PurePursuit",
    "PurePursuitParams",
    "PursuitStatus",
    "TrackerParams",
    "TrackingError",
    "Zone",
    "adaptive_lookahead",
    "angular_velocity",
    "approach_regulated_speed",
    "clamp_yaw_rate",
    "convex_polygon",
    "curvature_regulated_speed",
    "default_zones",
    "lateral_error_model",
    "moving_away",
    "nearest_obstacle_ahead",
    "offset_polygon",
    "proximity_regulated_speed",
    "pursuit_curvature",
    "rotate_in_place_rate",
    "tracking_error",
]

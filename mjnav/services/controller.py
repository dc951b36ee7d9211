"""The controller service: pure pursuit on ``path`` → ``cmd_vel`` at ``rate_hz`` of sim time.

Speed is regulated by curvature and by the nearest obstacle the lidar sees in front (``scan``; returns of an obstacle
moving away from the robot do not count: the collision check below predicts them); the robot slows on
approach and stops within ``goal_tolerance_m`` of the goal; when the goal has an orientation it then turns in place
to the goal's yaw (within ``yaw_goal_tolerance_rad``; an all-zero quaternion means any heading) and reports
``reached`` on ``goal_status``. Once within the xy tolerance the goal stays latched there (Nav2's stateful goal
checker): the turn does not restart the approach. Every command then passes a last-line
collision check against the robot's own scan (:func:`mjnav.control.collision.safe_command`): the commanded arc is
rolled forward against the scan's points — moving ones at the velocities two consecutive scans give — and a command
that would collide is replaced by a slower, stopped or (to clear a crossing obstacle) faster one on the same
curvature. It stops (and keeps publishing zero) when there is no path, the goal failed or was canceled, the pose or
the scan is stale, or the robot is further than ``lost_distance_m`` from the path (the planner's next replan gives a
new one).

Every goal ends: besides ``reached``, the controller fails the active goal with ``ERROR_TIMEOUT`` when the robot has
not moved ``progress_radius_m`` in ``progress_timeout_s`` (Nav2's progress checker), or when the planner's
``following`` heartbeat has been silent for ``planner_timeout_s`` (the planner died for good).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from scipy.ndimage import maximum_filter

from mjnav.control import PathError, PurePursuit, PurePursuitParams, moving_away, nearest_obstacle_ahead
from mjnav.control.collision import CollisionCheckParams, TrackedScan, TrackingParams, safe_command, track_scan
from mjnav.geometry import Pose2D, wrap_angle
from mjnav.mapping.frame import GridFrame
from mjnav.msgs import msg_class, ros
from mjnav.runtime import Service
from mjnav.runtime.pose import PoseInput

_STATUS = "mjnav_msgs/msg/GoalStatus"
#: Map value (occupancy probability, %) from which a cell counts as a wall for the collision check.
OCCUPIED = 65


@dataclass(frozen=True)
class ControllerConfig:
    """Controller settings (``services/controller.toml``).

    Attributes:
        rate_hz: command rate (sim time).
        pose_source: ``slam`` (SLAM's ``map → odom`` ∘ the sim's ``odom → base_link``, both on ``tf``; see
            :mod:`mjnav.runtime.pose`),
            ``ground_truth`` (the sim's truth) or ``odom``.
        max_speed_mps: cruise speed v_max.
        lookahead_gain_s, min_lookahead_m, max_lookahead_m: L = clamp(v·g, L_min, L_max).
        curvature_threshold_invm: κ_h of the curvature heuristic.
        proximity_distance_m: d_prox of the proximity heuristic (distance from the robot's edge).
        goal_tolerance_m: xy goal tolerance: stop within this distance of the goal.
        approach_distance_m: the speed falls linearly to the goal over this much remaining path (regulated pure
            pursuit's approach scaling). 0.6 m (Nav2's default) made the last 0.6 m take 2 s of an 11 s mission;
            0.3 m asks at most 0.8 m/s² of braking from 0.5 m/s.
        yaw_goal_tolerance_rad: then turn in place until the heading is within this of the goal's yaw.
        rotate_gain_per_s: turn rate per radian of heading error, ω = k·e, clamped to
            [``rotate_min_radps``, ``rotate_max_radps``] in magnitude.
        robot_radius_m: subtracted from lidar ranges to get the distance from the robot's edge.
        front_sector_rad: full width of the sector in front whose nearest return slows the robot (returns the
            tracker sees moving away from the robot left out).
        pose_timeout_s: stop when the newest pose is older than this (sim seconds).
        path_timeout_s: stop when no path arrived for this long (sim seconds; the planner re-sends every second).
        lost_distance_m: stop when the robot is further than this from the path.
        collision_margin_m: clearance the collision check keeps beyond ``robot_radius_m``.
        chord_margin_m: the straight line to the lookahead point keeps this beyond ``robot_radius_m`` from every
            scan point, else the lookahead shrinks (pure pursuit cuts a corner along that line); as the smoother
            keeps its path ``margin_m`` off the inscribed radius.
        collision_static_horizon_s: how far ahead (seconds of the commanded arc) static scan points are checked.
        collision_moving_horizon_s: how far ahead moving scan points are checked.
        moving_speed_mps: scan points moving faster than this between two scans count as moving.
        scan_timeout_s: stop when the newest scan is older than this (sim s): the collision check needs one.
        progress_timeout_s, progress_radius_m: fail the goal (``ERROR_TIMEOUT``) when the robot stayed within
            ``progress_radius_m`` for ``progress_timeout_s`` sim seconds while the goal was active.
        planner_timeout_s: fail the goal (``ERROR_TIMEOUT``) when the planner's ``following`` heartbeat (every
            second) has been silent this long, sim seconds.
    """

    rate_hz: float = 20.0
    pose_source: Literal["slam", "ground_truth", "odom"] = "slam"
    max_speed_mps: float = 0.5
    lookahead_gain_s: float = 1.2
    min_lookahead_m: float = 0.35
    max_lookahead_m: float = 1.0
    curvature_threshold_invm: float = 1.5
    proximity_distance_m: float = 0.5
    goal_tolerance_m: float = 0.1
    approach_distance_m: float = 0.3
    yaw_goal_tolerance_rad: float = 0.1
    rotate_gain_per_s: float = 1.5
    rotate_min_radps: float = 0.2
    rotate_max_radps: float = 1.0
    robot_radius_m: float = 0.19
    front_sector_rad: float = 1.6
    pose_timeout_s: float = 0.5
    path_timeout_s: float = 3.0
    lost_distance_m: float = 1.0
    collision_margin_m: float = 0.02
    chord_margin_m: float = 0.1
    collision_static_horizon_s: float = 0.3
    collision_moving_horizon_s: float = 4.0
    moving_speed_mps: float = 0.25
    scan_timeout_s: float = 0.5
    progress_timeout_s: float = 20.0
    progress_radius_m: float = 0.25
    planner_timeout_s: float = 15.0

    def __post_init__(self) -> None:
        for name in (
            "max_speed_mps",
            "goal_tolerance_m",
            "pose_timeout_s",
            "path_timeout_s",
            "lost_distance_m",
            "front_sector_rad",
            "scan_timeout_s",
            "progress_timeout_s",
            "progress_radius_m",
            "planner_timeout_s",
            "yaw_goal_tolerance_rad",
            "rotate_gain_per_s",
            "rotate_min_radps",
        ):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not self.chord_margin_m >= 0:
            raise ValueError(f"chord_margin_m must be >= 0, got {self.chord_margin_m}")
        if not self.rotate_max_radps >= self.rotate_min_radps:
            raise ValueError(f"rotate_max_radps must be >= rotate_min_radps, got {self.rotate_max_radps}")

    def pursuit_params(self) -> PurePursuitParams:
        """The pure-pursuit parameters these settings stand for."""
        return PurePursuitParams(
            desired_speed_mps=self.max_speed_mps,
            lookahead_gain_s=self.lookahead_gain_s,
            min_lookahead_m=self.min_lookahead_m,
            max_lookahead_m=self.max_lookahead_m,
            curvature_threshold_invm=self.curvature_threshold_invm,
            proximity_distance_m=self.proximity_distance_m,
            goal_tolerance_m=self.goal_tolerance_m,
            approach_distance_m=self.approach_distance_m,
        )

    def collision_params(self) -> CollisionCheckParams:
        """The collision check these settings stand for."""
        return CollisionCheckParams(
            robot_radius_m=self.robot_radius_m,
            margin_m=self.collision_margin_m,
            static_horizon_s=self.collision_static_horizon_s,
            moving_horizon_s=self.collision_moving_horizon_s,
            moving_speed_mps=self.moving_speed_mps,
            max_speed_mps=self.max_speed_mps,
        )


def goal_yaw_error(goal_pose: Any, yaw_rad: float) -> float | None:
    """Heading error (goal yaw − ``yaw_rad``, wrapped to [−π, π)) of a geometry_msgs/Pose goal, or None when the
    goal has no orientation (an all-zero quaternion: any final heading will do)."""
    if not ros.has_orientation(goal_pose):
        return None
    return wrap_angle(ros.pose2d(goal_pose).theta - yaw_rad)


class ControllerService(Service[ControllerConfig]):
    """Follows the smoothed path with pure pursuit."""

    name = "controller"
    config_class = ControllerConfig

    def configure(self) -> None:
        self.pursuit = PurePursuit(self.config.pursuit_params())
        self.collision = self.config.collision_params()
        self.tracking = TrackingParams(moving_speed_mps=self.config.moving_speed_mps)
        self.path_sub = self.bus.subscribe("path")
        self.pose_in = PoseInput(self.bus, self.config.pose_source)
        self.scan_sub = self.bus.subscribe("scan")
        self.map_sub = self.bus.subscribe("map")
        self.status_sub = self.bus.subscribe("goal_status")
        self.cmd_pub = self.bus.publisher("cmd_vel")
        self.status_pub = self.bus.publisher("goal_status")
        self.status_cls = msg_class(_STATUS)
        self.finished: set[int] = set()  # goal ids that ended (a late heartbeat must not revive them)
        self.stopped_reason = ""
        # Load the compiled kernels now, not when the first path arrives.
        self.pursuit.compute((0.0, 0.0, 0.0), 0.0, np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]))

    def activate(self) -> None:
        # Also called again when the sim clock restarts: the goal is re-adopted from the planner's heartbeat.
        self.goal: Any = None  # the GoalStatus that made the current goal active
        self.goal_since = math.inf  # its sim time: older paths belong to earlier goals
        self.heartbeat = -math.inf  # sim time of the planner's newest "following" for the goal
        self.progress: tuple[float, float, float] | None = None  # (x, y, sim time) the robot last moved away from
        self.at_goal_xy = False  # latched once within goal_tolerance_m of the goal: only the final turn remains
        self.path_msg: Any = None  # newest nav_msgs/Path received
        self.path_received = -math.inf  # sim time it arrived
        self.path_points: Any = None
        self.path_points_msg: Any = None
        self.speed = 0.0
        self.pursuit.reset()
        self.pose_in.reset()
        self.obstacles: TrackedScan | None = None  # the newest scan, fused
        self.walls: tuple[GridFrame, Any] | None = None  # the map's occupied cells, grown by one cell

    def _update_obstacles(self) -> None:
        """Fuse a new scan: its points in the map frame (at the pose of its stamp) and their velocities."""
        scan = self.scan_sub.take()
        if scan is None:
            return
        stamp = ros.seconds(scan.header.stamp)
        pose = self.pose_in.at(stamp)
        if pose is None:
            return
        self.obstacles = track_scan(
            stamp,
            (pose.x, pose.y, pose.theta),
            float(scan.angle_min),
            float(scan.angle_increment),
            scan.ranges,
            float(scan.range_min),
            float(scan.range_max),
            self.obstacles,
            self.tracking,
            static=self._on_walls,
        )

    def _on_walls(self, points: Any) -> Any:
        """(M,) True for points on (or next to) a cell the map has as occupied: static, whatever two scans say."""
        msg = self.map_sub.take()
        if msg is not None:
            cells, frame = ros.grid_frame(msg)
            self.walls = (frame, maximum_filter(cells >= OCCUPIED, size=3))
        if self.walls is None:
            return np.zeros(len(points), dtype=bool)
        frame, walls = self.walls
        return frame.values_at(walls, points, outside=False)

    def _checked(self, now: float, pose: Pose2D, v: float, w: float) -> tuple[float, float]:
        """(v, ω) after the collision check against the newest scan ((0, 0) without a recent one)."""
        if self.obstacles is None or now - self.obstacles.stamp_s > self.config.scan_timeout_s:
            return 0.0, 0.0  # no recent scan: nothing to check the command against
        points, velocities = self.obstacles.points, self.obstacles.velocities
        local = pose.inverse().transform_points(points)
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        local_vel = velocities @ np.array([[c, -s], [s, c]])  # rotate map-frame velocities into the robot frame
        safe_v, safe_w, ttc = safe_command(v, w, local, local_vel, self.collision)
        if (safe_v, safe_w) != (v, w):
            moving = np.any(velocities != 0.0, axis=1)
            self.log.debug(
                "collision check: (%.2f, %.2f) -> (%.2f, %.2f), ttc %.2f s, %d moving point(s) %s",
                v, w, safe_v, safe_w, ttc, int(moving.sum()), np.round(points[moving][:3], 2).tolist(),
            )  # fmt: skip
        return safe_v, safe_w

    def _stop(self, reason: str) -> None:
        self.cmd_pub.put(ros.twist(0.0, 0.0))
        self.speed = 0.0
        if reason != self.stopped_reason:
            self.log.info("stopped: %s", reason)
            self.stopped_reason = reason

    def _track_goal(self) -> None:
        cls = self.status_cls
        for status in self.status_sub.drain():
            if status.state in (cls.STATE_ACCEPTED, cls.STATE_PLANNING):
                self.finished.discard(status.goal_id)  # ids start again at 1 when the planner restarts
            elif status.state == cls.STATE_FOLLOWING and status.goal_id not in self.finished:
                if self.goal is None or status.goal_id != self.goal.goal_id:
                    self.goal = status
                    self.goal_since = ros.seconds(status.header.stamp)
                    self.progress = None
                    self.at_goal_xy = False
                    self.pursuit.reset()
                self.heartbeat = ros.seconds(status.header.stamp)
            elif status.state in (cls.STATE_FAILED, cls.STATE_CANCELED, cls.STATE_REACHED):
                self.finished.add(status.goal_id)
                if self.goal is not None and status.goal_id == self.goal.goal_id:
                    self.goal = None

    def _current_path(self, now: float) -> Any:
        """The path of the active goal: the newest one stamped since the goal started following, or None."""
        msg = self.path_sub.take()
        if msg is not None:
            self.path_msg, self.path_received = msg, now
        msg = self.path_msg
        if self.goal is None or msg is None or ros.seconds(msg.header.stamp) < self.goal_since:
            return None  # nothing yet, or a path of an earlier goal
        if self.path_points is None or self.path_points_msg is not msg:
            self.path_points, self.path_points_msg = ros.path_points(msg), msg
        return self.path_points

    def step(self, now: float) -> None:
        self.pose_in.update()
        self._update_obstacles()
        self._track_goal()
        path = self._current_path(now)
        if self.goal is None:
            self._stop("no active goal")
            return
        if self._goal_expired(now):
            return
        if path is None or len(path) < 2:
            self._stop("no path")
            return
        if now - self.path_received > self.config.path_timeout_s:
            self._stop(f"path older than {self.config.path_timeout_s} s: is the smoother running?")
            return
        latest = self.pose_in.latest()
        if latest is None or now - latest[0] > self.config.pose_timeout_s:
            self._stop("no recent pose")
            return
        pose = latest[1]
        if self.at_goal_xy:
            self._turn_to_goal(now, pose)
            return
        try:
            v, w = self.pursuit.compute(
                pose,
                self.speed,
                path,
                self._obstacle_distance(pose),
                obstacles_xy=None if self.obstacles is None else self.obstacles.points,
                chord_clearance_m=self.config.robot_radius_m + self.config.chord_margin_m,
            )
        except PathError as exc:
            self.path_msg = None
            self._stop(f"unusable path: {exc}")
            return
        status = self.pursuit.status
        if self.pursuit.goal_reached:
            self.at_goal_xy = True
            self._turn_to_goal(now, pose)
            return
        if abs(status.cross_track_m) > self.config.lost_distance_m:
            self._stop(f"{abs(status.cross_track_m):.2f} m off the path: waiting for a new plan")
            return
        v, w = self._checked(now, pose, v, w)
        self.stopped_reason = ""
        self.speed = v
        self.cmd_pub.put(ros.twist(v, w))

    def _turn_to_goal(self, now: float, pose: Pose2D) -> None:
        """At the goal's position: turn in place towards its yaw, or report reached (yaw-free goals at once)."""
        error = goal_yaw_error(self.goal.goal.pose, pose.theta)
        cfg = self.config
        if error is None or abs(error) <= cfg.yaw_goal_tolerance_rad:
            self._stop("goal reached")
            self._report_reached(now)
            return
        w = math.copysign(
            min(max(cfg.rotate_gain_per_s * abs(error), cfg.rotate_min_radps), cfg.rotate_max_radps), error
        )
        v, w = self._checked(now, pose, 0.0, w)
        self.stopped_reason = ""
        self.speed = v
        self.cmd_pub.put(ros.twist(v, w))

    def _goal_expired(self, now: float) -> bool:
        """Fail the active goal when the planner went silent or the robot stopped making progress."""
        cfg = self.config
        if now - self.heartbeat > cfg.planner_timeout_s:
            self._fail(now, f"no word from the planner for {now - self.heartbeat:.1f} s")
            return True
        latest = self.pose_in.latest()
        if latest is None:
            return False
        pose = latest[1]
        if self.progress is None or math.hypot(pose.x - self.progress[0], pose.y - self.progress[1]) > (
            cfg.progress_radius_m
        ):
            self.progress = (pose.x, pose.y, now)
            return False
        if now - self.progress[2] > cfg.progress_timeout_s:
            self._fail(now, f"no progress: moved less than {cfg.progress_radius_m} m in {cfg.progress_timeout_s} s")
            return True
        return False

    def _fail(self, now: float, text: str) -> None:
        goal = self.goal
        self._stop(text)
        self._end_goal(now, goal, self.status_cls.STATE_FAILED, self.status_cls.ERROR_TIMEOUT, text)
        self.log.warning("goal %d failed: %s", goal.goal_id, text)

    def _end_goal(self, now: float, goal: Any, state: int, error: int, text: str) -> None:
        self.goal = None
        self.finished.add(goal.goal_id)
        self.status_pub.put(
            self.status_cls(
                header=ros.header(now, "map"),
                goal_id=goal.goal_id,
                state=state,
                error_code=error,
                error_text=text,
                goal=goal.goal,
            )
        )

    def _obstacle_distance(self, pose: Pose2D) -> float:
        """d_O of the proximity heuristic: the nearest return of the newest scan in the front sector, metres (from
        the robot's edge; inf without one), leaving out the returns the tracker sees moving away from the robot
        (:func:`mjnav.control.moving_away`): a cart that crosses the robot's way and leaves it is no reason to
        creep behind it, and the collision check, which predicts its motion, still keeps the robot off it."""
        scan = self.scan_sub.latest()
        if scan is None:
            return math.inf
        angles = scan.angle_min + scan.angle_increment * np.arange(len(scan.ranges))
        ignore = None
        tracked = self.obstacles
        if tracked is not None and tracked.stamp_s == ros.seconds(scan.header.stamp):  # the same scan, tracked
            ignore = np.zeros(len(scan.ranges), dtype=bool)
            ignore[tracked.beams[moving_away(tracked.points, tracked.velocities, (pose.x, pose.y))]] = True
        return nearest_obstacle_ahead(
            angles,
            scan.ranges,
            sector_rad=self.config.front_sector_rad,
            range_min_m=float(scan.range_min),
            robot_radius_m=self.config.robot_radius_m,
            ignore=ignore,
        )

    def _report_reached(self, now: float) -> None:
        goal = self.goal
        self._end_goal(now, goal, self.status_cls.STATE_REACHED, self.status_cls.ERROR_NONE, "")
        self.log.info("goal %d reached", goal.goal_id)

"""The controller service: pure pursuit on ``path`` → ``cmd_vel`` at ``rate_hz`` of sim time.

Speed is regulated by curvature and by the nearest obstacle the lidar sees in front (``scan``; returns of an obstacle
moving away from the robot do not count: the collision check below predicts them); the robot slows on
approach and stops within ``goal_tolerance_m`` of the goal; when the goal has an orientation it then turns in place
to the goal's yaw (within ``yaw_goal_tolerance_rad``; an all-zero quaternion means any heading) and reports its
arrival to the planner on ``controller_feedback``. Once within the xy tolerance the goal stays latched there (Nav2's
stateful goal checker): the turn does not restart the approach. Every command then passes a last-line
collision check against the robot's own scan (:func:`mjnav.control.collision.safe_command`): the commanded arc is
rolled forward against the scan's points — moving ones at the velocities two consecutive scans give — and a command
that would collide is replaced by a slower, stopped or (to clear a crossing obstacle) faster one on the same
curvature. It stops (and keeps publishing zero) when there is no path, the goal failed or was canceled, the pose or
the scan is stale, or the robot is further than ``lost_distance_m`` from the path (the planner's next replan gives a
new one).

The planner owns every goal (its ``goal_status``); the controller follows the goal the planner's newest
``following`` names and reports to it on ``controller_feedback``: following, halted (and why), arrived, or no
progress — the robot has not moved ``progress_radius_m`` in ``progress_timeout_s`` (Nav2's progress checker), which
the planner turns into ``ERROR_TIMEOUT``. A controller that (re)starts late gets the planner's newest status and the
smoother's newest path from their latched topics. The robot's footprint radius comes from the robot description
the sim latches (:mod:`mjnav.runtime.robot`).

The path, the goal's status and the map come only when they change: their freshness is their producers' (smoother,
planner, mapper, and SLAM), whose step reports the controller watches (:mod:`mjnav.runtime.upstream`).
One whose due step is more than ``upstream_grace_s`` of sim time late — dead, hung, left out of the lockstep —
stops the robot, saying which, until it reports again.

On SLAM's pose (``pose_source = "slam"``) the controller also follows SLAM's ``localization_health``: while the
localisation is degraded (running on odometry) it drives at most ``degraded_speed_scale`` of its speed, and
while it is lost among returns that do not match the map it stops, saying why in its feedback and log, until SLAM
localises again. In open space — SLAM's newest scan had too few returns to match (``starved`` in the status'
values) — it drives on at its speed on odometry, degraded or lost, and says so: the odometry's error grows with
the distance, not the time, so slower would not localise it sooner, standing still would never bring a return to
localise on, and what returns there are still pass the collision check.
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
from mjnav.msgs.topics import OPERATOR, OWN, PUBLISH_RIGHTS
from mjnav.runtime import Service
from mjnav.runtime.pose import PoseInput
from mjnav.runtime.robot import RobotModel
from mjnav.runtime.upstream import UpstreamWatch

_STATUS = "mjnav_msgs/msg/GoalStatus"
_FEEDBACK = "mjnav_msgs/msg/ControllerFeedback"
#: Feedback while SLAM's scans are bad for want of returns and the robot drives on on odometry (module docstring).
_OPEN_SPACE = "localisation on odometry in open space (too few lidar returns)"
#: Sim seconds without a scan, while a goal is active, after which the status says the controller lacks scans.
STARVED_AFTER_S = 5.0
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
        front_sector_rad: full width of the sector in front whose nearest return slows the robot (returns the
            tracker sees moving away from the robot left out).
        pose_timeout_s: stop when the newest pose is older than this (sim seconds).
        lost_distance_m: stop when the robot is further than this from the path.
        collision_margin_m: clearance the collision check keeps beyond the robot's footprint radius.
        chord_margin_m: the straight line to the lookahead point keeps this beyond the robot's footprint radius
            from every scan point, else the lookahead shrinks (pure pursuit cuts a corner along that line); as the
            smoother keeps its path ``margin_m`` off the inscribed radius.
        collision_static_horizon_s: how far ahead (seconds of the commanded arc) static scan points are checked.
        collision_moving_horizon_s: how far ahead moving scan points are checked.
        moving_speed_mps: scan points moving faster than this between two scans count as moving.
        scan_timeout_s: stop when the newest scan is older than this (sim s): the collision check needs one.
        upstream_grace_s: stop when a service the path, the goal's status, the map or SLAM's pose come from
            (planner, smoother, mapper, slam) has missed its due step by this much (sim s;
            :mod:`mjnav.runtime.upstream`): it died, hung or was left out of the lockstep, and what it sent last may
            no longer hold.
        progress_timeout_s, progress_radius_m: report no progress (the planner fails the goal with
            ``ERROR_TIMEOUT``) when the robot stayed within ``progress_radius_m`` for ``progress_timeout_s`` sim
            seconds while the goal was active.
        degraded_speed_scale: on SLAM's pose, the fraction of ``max_speed_mps`` the robot keeps to while SLAM
            reports its localisation degraded (``localization_health`` WARN); it stops while SLAM reports it lost
            (ERROR).
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
    front_sector_rad: float = 1.6
    pose_timeout_s: float = 0.5
    lost_distance_m: float = 1.0
    collision_margin_m: float = 0.02
    chord_margin_m: float = 0.1
    collision_static_horizon_s: float = 0.3
    collision_moving_horizon_s: float = 4.0
    moving_speed_mps: float = 0.25
    scan_timeout_s: float = 0.5
    upstream_grace_s: float = 0.15
    progress_timeout_s: float = 20.0
    progress_radius_m: float = 0.25
    degraded_speed_scale: float = 0.5

    def __post_init__(self) -> None:
        for name in (
            "max_speed_mps",
            "goal_tolerance_m",
            "pose_timeout_s",
            "lost_distance_m",
            "front_sector_rad",
            "scan_timeout_s",
            "upstream_grace_s",
            "progress_timeout_s",
            "progress_radius_m",
            "yaw_goal_tolerance_rad",
            "rotate_gain_per_s",
            "rotate_min_radps",
        ):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not 0 < self.degraded_speed_scale <= 1:
            raise ValueError(f"degraded_speed_scale must be in (0, 1], got {self.degraded_speed_scale}")
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

    def collision_params(self, robot_radius_m: float) -> CollisionCheckParams:
        """The collision check these settings stand for, for a robot of footprint radius ``robot_radius_m``."""
        return CollisionCheckParams(
            robot_radius_m=robot_radius_m,
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
        self.tracking = TrackingParams(moving_speed_mps=self.config.moving_speed_mps)
        self.robot = RobotModel(self.bus)
        self.path_sub = self.bus.subscribe("path")
        self.pose_in = PoseInput(self.bus, self.config.pose_source)
        self.scan_sub = self.bus.subscribe("scan")
        self.map_sub = self.bus.subscribe("map")
        self.status_sub = self.bus.subscribe("goal_status")
        slam = self.config.pose_source == "slam"
        self.health_sub = self.bus.subscribe("localization_health") if slam else None
        inputs = ("path", "goal_status", "map", *(("localization_health",) if slam else ()))  # and SLAM's tf
        producers = {who for topic in inputs for who in PUBLISH_RIGHTS[topic] if who not in (OPERATOR, OWN)}
        self.upstream = UpstreamWatch(self.bus, producers, self.config.upstream_grace_s)
        self.cmd_pub = self.bus.publisher("cmd_vel")
        self.feedback_pub = self.bus.publisher("controller_feedback")
        self.status_cls = msg_class(_STATUS)
        self.feedback_cls = msg_class(_FEEDBACK)
        self.finished: set[int] = set()  # goal ids that ended (a late status must not revive them)
        self.stopped_reason = ""
        self.slowed = ""  # why the speed is capped for the localisation's sake (logged when it changes)
        # Load the compiled kernels now, not when the first path arrives.
        self.pursuit.compute((0.0, 0.0, 0.0), 0.0, np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]))

    def starting(self) -> str:
        return self.robot.waiting()

    def starved(self) -> str:
        if self.pose_in.latest() is None:
            return f"the robot's pose ({self.pose_in.describe()})"
        if self.goal is not None and (self.obstacles is None or self.now - self.obstacles.stamp_s > STARVED_AFTER_S):
            return f"scans on {self.scan_sub.key} (the collision check needs them)"
        return ""

    def activate(self) -> None:
        # Also called again when the sim clock restarts: the goal is re-adopted from the planner's next status.
        self.goal: Any = None  # the GoalStatus that made the current goal active
        self.goal_since = math.inf  # its sim time: older paths belong to earlier goals
        self.progress: tuple[float, float, float] | None = None  # (x, y, sim time) the robot last moved away from
        self.at_goal_xy = False  # latched once within goal_tolerance_m of the goal: only the final turn remains
        self.path_msg: Any = None  # newest nav_msgs/Path received
        self.path_points: Any = None
        self.path_points_msg: Any = None
        self.speed = 0.0
        self.now = 0.0
        self.reported: tuple[int, int, str] | None = None  # (goal id, state, text) of the newest feedback sent
        self.pursuit.reset()
        self.pose_in.reset()
        self.obstacles: TrackedScan | None = None  # the newest scan, fused
        self.walls: tuple[GridFrame, Any] | None = None  # the map's occupied cells, grown by one cell
        self.robot_version = 0
        self.collision: CollisionCheckParams | None = None
        self.radius_m = math.nan

    def _robot_facts(self) -> None:
        """The collision check and the chord clearance for the robot the description names (rebuilt when it
        changes)."""
        if self.robot.version == self.robot_version:
            return
        robot = self.robot.current
        assert robot is not None  # starting() waited for it
        self.robot_version = self.robot.version
        self.radius_m = robot.radius_m
        self.collision = self.config.collision_params(robot.radius_m)

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
        assert self.collision is not None
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

    def _stop(self, reason: str, detail: str = "") -> None:
        """Command zero; while a goal is active, tell the planner why (``reason``: no numbers, so that the
        feedback goes out when the reason changes, not at every step; ``detail`` only goes to the log)."""
        self.cmd_pub.put(ros.twist(0.0, 0.0))
        self.speed = 0.0
        if reason != self.stopped_reason:
            self.log.info("stopped: %s%s", reason, f" ({detail})" if detail else "")
            self.stopped_reason = reason
        if self.goal is not None:
            self._report(self.feedback_cls.STATE_HALTED, reason)

    def _report(self, state: int, text: str = "", goal: Any = None) -> None:
        """Send the controller's feedback on the active goal (or ``goal``) when its state or text changed."""
        goal = goal if goal is not None else self.goal
        key = (int(goal.goal_id), state, text)
        if key == self.reported:
            return
        self.reported = key
        remaining = self.pursuit.status.remaining_m if self.pursuit.status.mode != "idle" else -1.0
        self.feedback_pub.put(
            self.feedback_cls(
                header=ros.header(self.now, "map"),
                goal_id=goal.goal_id,
                state=state,
                distance_remaining_m=float(remaining),
                text=text,
            )
        )

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
            elif status.state in (cls.STATE_FAILED, cls.STATE_CANCELED, cls.STATE_REACHED):
                self.finished.add(status.goal_id)
                if self.goal is not None and status.goal_id == self.goal.goal_id:
                    self.goal = None

    def _current_path(self) -> Any:
        """The path of the active goal: the newest one stamped since the goal started following, or None."""
        msg = self.path_sub.take()
        if msg is not None:
            self.path_msg = msg
        msg = self.path_msg
        if self.goal is None or msg is None or ros.seconds(msg.header.stamp) < self.goal_since:
            return None  # nothing yet, or a path of an earlier goal
        if self.path_points is None or self.path_points_msg is not msg:
            self.path_points, self.path_points_msg = ros.path_points(msg), msg
        return self.path_points

    def step(self, now: float) -> None:
        self.now = now
        self._robot_facts()
        self.pose_in.update()
        self._update_obstacles()
        self._track_goal()
        path = self._current_path()
        if self.goal is None:
            self._stop("no active goal")
            return
        stale = self.upstream.stale(now)
        if stale:
            self.progress = None  # standing for want of an input is no lack of progress
            names = ", ".join(name for name, _ in stale)
            due = ", ".join(f"{name}'s step due at {t:.2f} s" for name, t in stale)
            self._stop(f"waiting for {names} (not stepping)", f"{due}, now {now:.2f} s")
            return
        if self._no_progress(now):
            return
        if path is None or len(path) < 2:
            self._stop("no path yet")
            return
        latest = self.pose_in.latest()
        if latest is None or now - latest[0] > self.config.pose_timeout_s:
            self._stop("no recent pose")
            return
        pose = latest[1]
        health = None if self.health_sub is None else self.health_sub.latest()
        starved = health is not None and ros.diagnostic_values(health).get("starved") == "1"
        if health is not None and health.level >= health.ERROR and not starved:
            self._stop("localisation lost: waiting for SLAM to localise again", health.message)
            return
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
                chord_clearance_m=self.radius_m + self.config.chord_margin_m,
            )
        except PathError as exc:
            self.path_msg = None
            self._stop("unusable path", str(exc))
            return
        status = self.pursuit.status
        if self.pursuit.goal_reached:
            self.at_goal_xy = True
            self._turn_to_goal(now, pose)
            return
        if abs(status.cross_track_m) > self.config.lost_distance_m:
            self._stop("off the path: waiting for a new plan", f"{abs(status.cross_track_m):.2f} m off")
            return
        note = ""
        if health is not None and health.level >= health.WARN:  # degraded, or lost in open space
            cap = self.config.max_speed_mps
            if starved:  # nothing in range to match: slower would not localise it sooner
                note = _OPEN_SPACE
            else:
                cap *= self.config.degraded_speed_scale
                note = "slowed: localisation degraded"
                if abs(v) > cap:  # slower on the same arc
                    v, w = math.copysign(cap, v), w * cap / abs(v)
            if self.slowed != note:
                self.slowed = note
                self.log.info("%s: %.2f m/s at most (%s)", note, cap, health.message)
        else:
            self.slowed = ""
        self._drive(*self._checked(now, pose, v, w), note)

    def _drive(self, v: float, w: float, note: str = "") -> None:
        self.stopped_reason = ""
        self.speed = v
        self.cmd_pub.put(ros.twist(v, w))
        self._report(self.feedback_cls.STATE_FOLLOWING, note)

    def _turn_to_goal(self, now: float, pose: Pose2D) -> None:
        """At the goal's position: turn in place towards its yaw, or report the arrival (yaw-free goals at once)."""
        error = goal_yaw_error(self.goal.goal.pose, pose.theta)
        cfg = self.config
        if error is None or abs(error) <= cfg.yaw_goal_tolerance_rad:
            goal = self.goal
            self._end_goal(self.feedback_cls.STATE_ARRIVED, "")
            self._stop("goal reached")
            self.log.info("goal %d: arrived", goal.goal_id)
            return
        w = math.copysign(
            min(max(cfg.rotate_gain_per_s * abs(error), cfg.rotate_min_radps), cfg.rotate_max_radps), error
        )
        self._drive(*self._checked(now, pose, 0.0, w))

    def _no_progress(self, now: float) -> bool:
        """Report no progress (the planner fails the goal) when the robot has not moved for too long."""
        cfg = self.config
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
            text = f"no progress: moved less than {cfg.progress_radius_m} m in {cfg.progress_timeout_s} s"
            goal = self.goal
            self._end_goal(self.feedback_cls.STATE_NO_PROGRESS, text)
            self._stop(text)
            self.log.warning("goal %d: %s", goal.goal_id, text)
            return True
        return False

    def _end_goal(self, state: int, text: str) -> None:
        """The controller is done with the active goal: report why; the planner ends it."""
        goal = self.goal
        self._report(state, text, goal)
        self.goal = None
        self.finished.add(goal.goal_id)

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
            robot_radius_m=self.radius_m,
            ignore=ignore,
        )

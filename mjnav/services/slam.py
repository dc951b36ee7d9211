"""The slam service: wheel odometry + lidar → the robot's pose in ``map``, the map, and ``map → odom``.

Mapping mode (default) runs :class:`mjnav.estimation.slam.GraphSlam` online: each new ``scan`` is matched against
the local map (correlative search + PL-ICP), keyframes go into a pose graph whose loop closures (branch-and-bound
matching against older submaps) re-optimise it, and the map is re-rendered from the optimised keyframes.
Localization mode (``mode = "localization"``) tracks the pose on a saved ROS map (``map_file``) with
:class:`mjnav.estimation.slam.Localizer` by scan-to-map matching from ``initialpose``.

Both modes start from ``initialpose`` (``geometry_msgs/PoseWithCovarianceStamped`` in ``map``, what RViz's 2D Pose
Estimate sends; the sim announces the robot's spawn pose there when sim time starts) or from ``initial_pose`` when
configured; until then nothing is published, the robot does not move, and the status says what SLAM waits for.
Every step publishes ``pose`` — the newest ``map → odom`` composed with the newest odometry, so the estimate
follows the wheels between scans — and ``map → odom`` on ``tf``; ``map`` goes out at ``map_rate_hz`` (latched).
Where the lidar sits on the robot comes from the robot description the sim latches (:mod:`mjnav.runtime.robot`):
each scan is placed at the frame its header names.

Each scan used updates the localisation's health (:mod:`mjnav.estimation.health`: enough returns, matched, match
quality), published on ``localization_health`` (``diagnostic_msgs/DiagnosticStatus``:
OK, WARN = degraded, on odometry, ERROR = lost) and logged when it changes; while lost, the status says so. The
controller slows on a degraded localisation and stops on a lost one.

In mapping mode the SLAM state is checkpointed in the run's state directory every ``checkpoint_period_s``, so a
restarted slam service resumes the same map and pose graph. The checkpoint grows by what is new
(:class:`SlamCheckpoint`): each keyframe's scan and each finished submap is written once.
"""

from __future__ import annotations

import bisect
import json
import logging
import math
import pickle
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, TypeVar

import numpy as np

from mjnav.estimation.health import Health, HealthMonitor
from mjnav.estimation.slam import GraphSlam, Localizer, LocalizerConfig, SlamConfig, SlamError, compose, invert
from mjnav.geometry import Pose2D, PoseHistory
from mjnav.mapping import OccupancyGrid, read_ros_map
from mjnav.motion.gyrodometry import GyroOdometry
from mjnav.msgs import msg_class, ros
from mjnav.robot import DescriptionError
from mjnav.runtime import Service
from mjnav.runtime.checkpoint import Checkpoint, CheckpointError, CorruptCheckpoint, LogScan, RecordLog, set_aside
from mjnav.runtime.robot import RobotModel

#: Sim seconds without a scan used after which the status says SLAM lacks scans.
STARVED_AFTER_S = 5.0


@dataclass(frozen=True)
class SlamServiceConfig:
    """SLAM service settings (``services/slam.toml``).

    Attributes:
        rate_hz: loop rate (sim time); each new scan is processed at the next step, ``pose`` goes out every step.
        mode: ``mapping`` (online graph SLAM) or ``localization`` (on ``map_file``).
        map_file: ROS map YAML for localization mode.
        initial_pose: (x, y, yaw) to start from without waiting for ``initialpose``; empty = wait for it.
        initial_sigma: (σ_xy m, σ_yaw rad) assumed with ``initial_pose``.
        max_range_m: beams at or beyond this are "no return" for mapping, metres.
        resolution_m: map cell size, metres.
        map_rate_hz: ``map`` publications per sim second (rendering it costs more than a scan).
        loop_closure: search for loop closures (mapping mode).
        loop_window_m, loop_window_rad: largest loop-closure search half-widths (the library's default, 2 m / 30°,
            suits logs with metres of drift). Here the front end keeps the drift to centimetres, and in the maze a
            2 m window reached the next corridor: on a there-and-back mission (seed 2) a false closure put the
            map 0.4 m off (ATE 0.37 m, map accuracy 0.39); at 0.5 m / 10° 122 closures brought ATE from 1.7 cm
            (no closures) to 0.9 cm. A closure missed for a larger drift costs less than a false one.
        use_gyro: take the heading increments from the IMU's gyro instead of the wheels (distance stays the
            wheels'): :class:`mjnav.motion.gyrodometry.GyroOdometry`, its bias learnt at standstill.
        checkpoint_period_s: checkpoint interval (sim s) of the mapping state in the run's state directory
            (0 = never).
    """

    rate_hz: float = 10.0
    mode: Literal["mapping", "localization"] = "mapping"
    map_file: str = ""
    initial_pose: tuple[float, ...] = ()
    initial_sigma: tuple[float, float] = (0.05, 0.05)
    max_range_m: float = 12.0
    resolution_m: float = 0.05
    map_rate_hz: float = 1.0
    loop_closure: bool = True
    loop_window_m: float = 0.5
    loop_window_rad: float = math.radians(10.0)
    use_gyro: bool = True
    checkpoint_period_s: float = 2.0

    def __post_init__(self) -> None:
        if self.mode == "localization" and not self.map_file:
            raise ValueError("mode 'localization' needs map_file (a ROS map .yaml)")
        if self.initial_pose and len(self.initial_pose) != 3:
            raise ValueError(f"initial_pose must be [x, y, yaw] or empty, got {list(self.initial_pose)}")
        for name in ("max_range_m", "resolution_m", "map_rate_hz", "loop_window_m", "loop_window_rad"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not self.checkpoint_period_s >= 0:
            raise ValueError(f"checkpoint_period_s must be >= 0, got {self.checkpoint_period_s}")


class SlamService(Service[SlamServiceConfig]):
    """Online SLAM or localization; the source of ``pose``, ``map`` and ``map → odom``."""

    name = "slam"
    config_class = SlamServiceConfig

    def configure(self) -> None:
        cfg = self.config
        self.pending: deque[tuple[float, Pose2D]] = deque(maxlen=1000)
        self.pending_gyro: deque[tuple[float, float]] = deque(maxlen=2000)
        self.bus.subscribe("odom", callback=self._on_odom)
        if cfg.use_gyro:
            self.bus.subscribe("imu", callback=self._on_imu)
        self.gyro_odom = GyroOdometry()
        self.scan = self.bus.subscribe("scan")
        self.initial = self.bus.subscribe("initialpose")
        self.robot = RobotModel(self.bus)
        self.pose_pub = self.bus.publisher("pose")
        self.tf_pub = self.bus.publisher("tf")
        self.map_pub = self.bus.publisher("map")
        self.health_pub = self.bus.publisher("localization_health")
        self.health = HealthMonitor()
        self.bus.serve("slam_info", self._on_info)
        self.slam: GraphSlam | None = None
        self.localizer: Localizer | None = None
        self.static_map: OccupancyGrid | None = None
        if cfg.mode == "localization":
            self.static_map = OccupancyGrid.from_ros_map(read_ros_map(cfg.map_file))
        # ((description version, frame), the frame's x, y, yaw in base_link or None when the robot lacks it)
        self.laser: tuple[tuple[int, str], tuple[float, float, float] | None] | None = None
        self.scans = 0
        self.last_scan_used = -math.inf  # sim time of the newest scan SLAM used
        self.failures = 0
        self.map_to_odom: np.ndarray | None = None  # (x, y, θ) once the estimate started
        self.start: tuple[np.ndarray, np.ndarray, Pose2D | None] | None = None  # (map pose, cov, odom then)
        self.checkpoint: SlamCheckpoint | None = None
        self._restore()
        if self.start is None and self.map_to_odom is None and cfg.initial_pose:
            sx, syaw = cfg.initial_sigma
            self.start = (np.asarray(cfg.initial_pose, dtype=float), np.diag([sx**2, sx**2, syaw**2]), None)

    def starting(self) -> str:
        return self.robot.waiting()

    def starved(self) -> str:
        if self.slam is None and self.map_to_odom is None and self.start is None:
            return f"initialpose on {self.initial.key} (where the robot is: the sim announces its spawn pose)"
        if self.odom.latest() is None:
            return f"odometry on {self.bus.key('odom')}"
        if self.now - self.last_scan_used > STARVED_AFTER_S:
            return f"scans on {self.scan.key} (none used for {STARVED_AFTER_S:g} s)"
        if self.health.report.level is Health.LOST:  # no numbers: the runner logs each change of this text
            return f"scans it can localise with (lost: the reason is on {self.health_pub.key})"
        return ""

    def _lidar_pose(self, frame: str) -> tuple[float, float, float] | None:
        """(x, y, yaw) in base_link of the scan frame ``frame``, from the robot description (None: a frame the robot
        does not have, logged once per frame and description)."""
        key = (self.robot.version, frame)
        if self.laser is not None and self.laser[0] == key:
            return self.laser[1]
        robot = self.robot.current
        assert robot is not None  # starting() waited for it
        pose: tuple[float, float, float] | None
        try:
            pose = robot.frame(frame).planar
        except DescriptionError as exc:
            self.log.warning("scans in frame %r not used: %s", frame, exc)
            pose = None
        self.laser = (key, pose)
        return pose

    def activate(self) -> None:
        # Called again when the sim clock goes back (the simulator restarted): its odometry starts again from zero
        # at the world's start, which map → odom already places, so mapping goes on from map → odom ∘ odometry.
        # Also after resuming from a checkpoint: the estimator's (gyro-aided) odometry frame starts afresh.
        self.reanchor = self.map_to_odom is not None
        self.odom = PoseHistory(horizon_s=5.0)
        self.fused = PoseHistory(horizon_s=5.0)  # gyro-aided odometry (= odom without use_gyro), same stamps
        self.gyro_odom.reset()
        self.pending.clear()
        self.pending_gyro.clear()
        self.next_map = 0.0
        self.next_checkpoint = 0.0  # the first checkpoint as soon as mapping started
        self.now = 0.0
        self.last_scan_used = -math.inf

    def _on_odom(self, msg: Any) -> None:
        self.pending.append((ros.seconds(msg.header.stamp), ros.pose_of(msg)))

    def _on_imu(self, msg: Any) -> None:
        self.pending_gyro.append((ros.seconds(msg.header.stamp), float(msg.angular_velocity.z)))

    def _take_odometry(self) -> None:
        """Move the new wheel poses into ``odom`` and their gyro-aided counterparts into ``fused``."""
        while self.pending_gyro:
            self.gyro_odom.add_gyro(*self.pending_gyro.popleft())
        while self.pending:
            t, pose = self.pending.popleft()
            self.odom.add(t, pose)
            self.fused.add(t, self.gyro_odom.add_odom(t, pose) if self.config.use_gyro else pose)

    # ------------------------------------------------------------------------------------------------ loop

    def step(self, now: float) -> None:
        self.now = now
        if self.last_scan_used == -math.inf:
            self.last_scan_used = now  # starvation counts from the first step
        self._take_odometry()
        for msg in self.initial.drain():
            self._set_initial(msg)
        scan = self.scan.take()
        if scan is not None:
            self._process(scan)
        if self.map_to_odom is None:
            return
        odom = self.odom.latest()
        if odom is not None:
            pose = Pose2D(*compose(self.map_to_odom, (odom[1].x, odom[1].y, odom[1].theta)))
            self.pose_pub.put(ros.pose_with_covariance_stamped(now, "map", pose, self._covariance()))
            self.tf_pub.put(ros.tf_message(ros.transform_stamped(now, "map", "odom", Pose2D(*self.map_to_odom))))
        if now >= self.next_map:
            self.next_map = now + 1.0 / self.config.map_rate_hz
            self._publish_map(now)
        if self.slam is not None and self.config.checkpoint_period_s > 0 and now >= self.next_checkpoint:
            self.next_checkpoint = now + self.config.checkpoint_period_s
            self._checkpoint()

    def _set_initial(self, msg: Any) -> None:
        if msg.header.frame_id not in ("", "map"):
            self.log.warning("initialpose in frame %r ignored: it must be in 'map'", msg.header.frame_id)
            return
        pose = ros.pose_of(msg)
        cov = ros.planar_covariance(msg)
        # The odometry when the pose was given (its stamp), if still in the history; else the newest.
        then = self.fused.at(ros.seconds(msg.header.stamp))
        latest = self.fused.latest()
        odom_then = then if then is not None else (None if latest is None else latest[1])
        self.start = (np.array([pose.x, pose.y, pose.theta]), cov, odom_then)
        if self.config.mode == "localization":
            self._localizer().set_pose(
                self.start[0],
                _positive(cov),
                None if odom_then is None else (odom_then.x, odom_then.y, odom_then.theta),
            )
        elif self.slam is not None:
            self.log.info("initialpose ignored: mapping already started (restart slam to map afresh)")
            return
        self.log.info("initial pose (%.2f, %.2f, %.1f°)", pose.x, pose.y, math.degrees(pose.theta))

    def _localizer(self) -> Localizer:
        """The localizer (localization mode), made on first use with the lidar's pose on the robot."""
        if self.localizer is None:
            assert self.static_map is not None
            laser = self._lidar_pose(self._lidar_frame())
            config = LocalizerConfig() if laser is None else LocalizerConfig(laser_offset=laser)
            self.localizer = Localizer(self.static_map, config)
            if self.start is not None and self.start[2] is None:  # initial_pose from the config
                self.localizer.set_pose(self.start[0], _positive(self.start[1]))  # odometry: the next update's
        return self.localizer

    def _lidar_frame(self) -> str:
        robot = self.robot.current
        assert robot is not None
        return robot.lidar_frame or ""

    def _process(self, scan: Any) -> None:
        stamp = ros.seconds(scan.header.stamp)
        odom, raw = self.fused.at(stamp), self.odom.at(stamp)
        if odom is None or raw is None or (self.start is None and self.slam is None):
            return  # no odometry at the scan's time yet, or not started (waiting for initialpose)
        laser = self._lidar_pose(scan.header.frame_id)
        if laser is None:
            return
        n = len(scan.ranges)
        angles = scan.angle_min + scan.angle_increment * np.arange(n)
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        kwargs = {"range_min_m": float(scan.range_min), "range_max_m": float(scan.range_max)}
        # The estimator runs on the gyro-aided odometry (odom_xyt); map → odom is published for the wheels' (raw).
        odom_xyt, raw_xyt = (odom.x, odom.y, odom.theta), (raw.x, raw.y, raw.theta)
        try:
            if self.config.mode == "localization":
                localizer = self._localizer()
                if not localizer.initialised:
                    return
                if self.reanchor and self.map_to_odom is not None:
                    pose = compose(self.map_to_odom, raw_xyt)
                    localizer.set_pose(pose, _positive(self._covariance()), odom_xyt)
                self.reanchor = False
                est = localizer.update(odom_xyt, ranges, angles, **kwargs)
            else:
                if self.slam is None:
                    self.slam = self._new_slam(odom, laser)
                elif self.reanchor and self.map_to_odom is not None:
                    self.slam.reanchor(odom_xyt, compose(self.map_to_odom, raw_xyt))
                    self.log.info(
                        "odometry restarted: mapping goes on from map -> odom (%.2f, %.2f)", *self.map_to_odom[:2]
                    )
                self.reanchor = False
                est = self.slam.update(stamp, odom_xyt, ranges, angles, **kwargs)
        except SlamError as exc:
            self.failures += 1
            if self.failures <= 10 or self.failures % 100 == 0:
                self.log.warning("scan at %.3f s not used (%d so far): %s", stamp, self.failures, exc)
            return
        self.scans += 1
        self.last_scan_used = self.now
        usable = (ranges >= scan.range_min) & (ranges < min(float(scan.range_max), self.config.max_range_m))
        self._report_health(stamp, odom_xyt, int(np.count_nonzero(usable)), est)
        self.map_to_odom = np.asarray(compose(compose(est.map_to_odom, odom_xyt), invert(raw_xyt)), dtype=float)
        self.covariance = np.asarray(est.covariance, dtype=float)

    def _report_health(self, stamp: float, odom_xyt: tuple[float, float, float], returns: int, est: Any) -> None:
        """Update the localisation's health with a scan, publish it, log a change of level."""
        before = self.health.report.level
        report = self.health.update(odom_xyt, returns, est.score, est.matched)
        if report.level != before:
            if report.level > before:
                self.log.warning("localisation %s: %s", report.level.name.lower(), report.reason)
            else:
                self.log.info("localisation %s again", report.level.name.lower())
        values = {
            "returns": str(report.returns),
            "match_score": f"{report.score:.3f}",
            "bad_scans": str(report.bad_scans),
            "unmatched_m": f"{report.unmatched_m:.3f}",
            "degenerate": str(int(est.degenerate)),  # a corridor: the odometry carries the pose along it
            "starved": str(int(report.starved)),  # too few returns: lost in open space, nothing near
            "stamp": f"{stamp:.6f}",
        }
        self.health_pub.put(ros.diagnostic_status(int(report.level), "slam", report.reason or "localised", values))

    def _new_slam(self, odom: Pose2D, laser: tuple[float, float, float]) -> GraphSlam:
        assert self.start is not None
        cfg = self.config
        start, _cov, odom_then = self.start
        # The initial pose was given at odometry odom_then; the robot may have moved since.
        initial = start if odom_then is None else compose(start, _between(odom_then, odom))
        slam_cfg = SlamConfig(
            map_resolution_m=cfg.resolution_m,
            max_range_m=cfg.max_range_m,
            laser_offset=laser,
            loop_candidates=SlamConfig().loop_candidates if cfg.loop_closure else 0,
            loop_window_m=cfg.loop_window_m,
            loop_window_rad=cfg.loop_window_rad,
        )
        self.log.info("mapping from (%.2f, %.2f, %.1f°)", initial[0], initial[1], math.degrees(initial[2]))
        return GraphSlam(slam_cfg, initial_pose=initial)

    def _covariance(self) -> Any:
        cov = getattr(self, "covariance", None)
        return np.zeros((3, 3)) if cov is None else cov

    # --------------------------------------------------------------------------------------------- outputs

    def _publish_map(self, now: float) -> None:
        grid = self.slam.occupancy_grid() if self.slam is not None else self.static_map
        if grid is None:
            return
        origin = (grid.origin_m[0], grid.origin_m[1])
        self.map_pub.put(ros.occupancy_grid(now, "map", grid.to_ros(), grid.resolution_m, origin))

    def _on_info(self, _request: Any) -> Any:
        slam = self.slam
        info = {
            "mode": self.config.mode,
            "scans": self.scans,
            "keyframes": 0 if slam is None else slam.num_keyframes,
            "loop_closures": 0 if slam is None else slam.loop_closures,
            "optimizations": 0 if slam is None else slam.optimizations,
        }
        return msg_class("std_msgs/msg/String")(data=json.dumps(info))

    # ------------------------------------------------------------------------------------------ checkpoint

    def _checkpoint(self) -> None:
        """Checkpoint the mapping state (pose graph, keyframes, map → odom) into the state directory."""
        if self.state_dir is None or self.slam is None:
            return
        if self.checkpoint is None:
            self.checkpoint = SlamCheckpoint(self.state_dir, self.log)
        self.checkpoint.save(self.slam, {"map_to_odom": self.map_to_odom, "scans": self.scans})

    def _restore(self) -> None:
        """Resume from this run's checkpoint (written by this service's previous process), if any; a bad one is
        logged and set aside, and the previous one used or none (:meth:`SlamCheckpoint.load`)."""
        if self.state_dir is None or self.config.mode != "mapping":
            return
        checkpoint = SlamCheckpoint(self.state_dir, self.log)
        loaded = checkpoint.load(_resumed_extra)
        if loaded is None:
            return
        self.slam, (self.map_to_odom, self.scans) = loaded
        self.checkpoint = checkpoint
        self.log.info("resumed SLAM from checkpoint in %s (%d keyframes)", self.state_dir, self.slam.num_keyframes)


def _resumed_extra(extra: dict[str, Any]) -> tuple[np.ndarray, int]:
    """(map → odom (3,), scans used) from what :meth:`SlamService._checkpoint` saved beside the SLAM.

    Raises:
        KeyError, ValueError, TypeError: not what it saves.
    """
    map_to_odom = np.asarray(extra["map_to_odom"], dtype=float)
    if map_to_odom.shape != (3,) or not np.isfinite(map_to_odom).all():
        raise ValueError(f"map_to_odom {map_to_odom!r}")
    return map_to_odom, int(extra["scans"])


T = TypeVar("T")


class SlamCheckpoint:
    """A :class:`GraphSlam` checkpointed in a directory by what is new since the last save.

    ``slam.log`` (a :class:`~mjnav.runtime.checkpoint.RecordLog`) gets each item of the SLAM's append-only lists
    (keyframe scans, finished submaps: :attr:`GraphSlam.APPEND_ONLY`) once, as a checksummed record of the pickled
    ``(list, index, item)``; ``slam.pickle`` (a :class:`~mjnav.runtime.checkpoint.Checkpoint`, the previous one
    kept as ``.prev``) holds the rest (pose graph, occupancy grid, trajectory, the caller's ``extra``), the log's id
    and the length of the log it relies on, and is replaced after the log was synced. A crash in between leaves
    records past that length: the next load ignores them and the next save overwrites them. A save costs the new
    keyframes plus the rest (after 288 keyframes on the test ring: 0.2 instead of 5.7 MB).

    A damaged record fails its checksum. The state saved last needs every record, so it is refused and the previous
    state tried, which needs the log only up to where it was saved: the newest full checkpoint whose records all
    verify is resumed (the good prefix alone is not a state: the pose graph refers to every keyframe), else none
    and SLAM starts afresh. Refused states are set aside; the log goes with them (a copy while the resumed state
    uses it, since the next save drops its records past that state), so nothing is lost.
    """

    #: Version of what the state's and the records' pickles hold.
    SCHEMA = 1

    def __init__(self, directory: Path, log: logging.Logger) -> None:
        self.records = RecordLog(directory / "slam.log", self.SCHEMA)
        self.state = Checkpoint(directory / "slam.pickle", self.SCHEMA, log)
        self.log = log
        self._slam: GraphSlam | None = None  # the SLAM the log belongs to
        self._counts: dict[str, int] = {}  # its items of each list in the log
        self._log_id = 0
        self._log_bytes = 0

    @property
    def log_path(self) -> Path:
        return self.records.path

    @property
    def state_path(self) -> Path:
        return self.state.path

    def save(self, slam: GraphSlam, extra: dict[str, Any]) -> None:
        """Append ``slam``'s new list items to the log, then replace the state file (``extra`` goes with it)."""
        state, lists = slam.split_state()
        counts = {name: len(items) for name, items in lists.items()}
        if slam is not self._slam:  # another mapping: the log starts afresh
            self._log_id = self.records.start()
            self._slam, self._counts, self._log_bytes = slam, dict.fromkeys(counts, 0), RecordLog.HEADER_BYTES
        new = (
            pickle.dumps((name, i, items[i]), protocol=pickle.HIGHEST_PROTOCOL)
            for name, items in lists.items()
            for i in range(self._counts[name], len(items))
        )
        log_bytes = self.records.append(new, self._log_bytes)
        top = {"state": state, "counts": counts, "log_id": self._log_id, "log_bytes": log_bytes, "extra": extra}
        self.state.save(pickle.dumps(top, protocol=pickle.HIGHEST_PROTOCOL))
        self._counts, self._log_bytes = counts, log_bytes

    def load(self, extra: Callable[[dict[str, Any]], T]) -> tuple[GraphSlam, T] | None:
        """The saved SLAM and ``extra(saved extra)``, or None (no checkpoint, or none left that verifies); the next
        :meth:`save` appends to it. Never raises for bad files: they are logged by name and set aside.

        Args:
            extra: what the caller makes of the ``extra`` it saved; any exception refuses the state.
        """
        try:
            scan: LogScan | CheckpointError = self.records.scan()
        except CheckpointError as exc:
            scan = exc
        loaded = self.state.load(lambda payload: self._decoded(payload, scan, extra))
        if self.state.refused and self.log_path.exists():
            try:
                moved = set_aside(self.log_path, copy=loaded is not None)
            except OSError as exc:
                self.log.error("%s not set aside with the refused SLAM state: %s", self.log_path, exc)
            else:
                self.log.warning("%s set aside as %s with the refused SLAM state", self.log_path, moved.name)
        if loaded is None:
            return None
        slam, resumed, counts, log_id, log_bytes = loaded
        self._slam, self._counts, self._log_id, self._log_bytes = slam, counts, log_id, log_bytes
        return slam, resumed

    def _decoded(
        self, payload: bytes, scan: LogScan | CheckpointError, extra: Callable[[dict[str, Any]], T]
    ) -> tuple[GraphSlam, T, dict[str, int], int, int]:
        """A state file's payload and the log's records made a SLAM: (SLAM, extra, counts, log id, log bytes).

        Raises:
            CheckpointError: the log does not hold what the state relies on (and anything a damaged payload makes
                unpickling raise).
        """
        if isinstance(scan, CheckpointError):
            raise scan
        top = pickle.loads(payload)
        counts = {str(name): int(n) for name, n in dict(top["counts"]).items()}
        log_id, log_bytes = int(top["log_id"]), int(top["log_bytes"])
        if log_id != scan.log_id:
            raise CorruptCheckpoint(self.log_path, f"another mapping's log (id {scan.log_id:#x}, needed {log_id:#x})")
        if log_bytes > scan.good_end:
            end = scan.error or f"the file ends at byte {scan.good_end}"
            raise CorruptCheckpoint(self.log_path, f"{end}; the state needs it up to byte {log_bytes}")
        used = bisect.bisect_right(scan.ends, log_bytes)
        if (scan.ends[used - 1] if used else RecordLog.HEADER_BYTES) != log_bytes:
            raise CorruptCheckpoint(self.log_path, f"no record ends at byte {log_bytes}, where the state needs one")
        lists: dict[str, list[Any]] = {name: [] for name in GraphSlam.APPEND_ONLY}
        for record in scan.payloads[:used]:
            name, i, item = pickle.loads(record)
            if name not in lists or i != len(lists[name]):
                raise CorruptCheckpoint(self.log_path, f"record {name}[{i}] out of order")
            lists[name].append(item)
        found = {name: len(items) for name, items in lists.items()}
        if found != counts:
            raise CorruptCheckpoint(self.log_path, f"holds {found} items, the state needs {counts}")
        slam = GraphSlam.from_split_state(top["state"], lists)
        return slam, extra(dict(top["extra"])), counts, log_id, log_bytes


def _between(a: Pose2D, b: Pose2D) -> Any:
    """Relative pose a⁻¹·b of two planar poses, (x, y, θ)."""
    return compose(invert((a.x, a.y, a.theta)), (b.x, b.y, b.theta))


def _positive(cov: Any) -> Any:
    """A covariance usable by the localizer: RViz sends zeros for what it does not set; floor the diagonal."""
    c = np.array(cov, dtype=float)
    floor = np.array([0.01, 0.01, 0.003])
    c[np.diag_indices(3)] = np.maximum(np.diag(c), floor)
    return c

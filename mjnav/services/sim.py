"""The sim service: the MuJoCo robot on the bus.

Publishes ``clock``, ``scan``, ``odom`` (wheel odometry, drifting), ``imu``, ``joint_states``, ``tf``
(``odom → base_link``), ``ground_truth`` (``map → base_link``), ``sim_status`` (collisions, real-time factor) and,
in worlds with moving bodies, ``obstacles`` (their true poses), all stamped in sim time, and drives the wheels
from the newest ``cmd_vel``. The simulator's own watchdog zeroes the wheels when that command is older than
``watchdog_timeout_s`` of sim time.

Actuation: the wheels take the newest command ``actuation_delay_s`` after each clock tick (10 ms by default), and
only then: what the controller computed on clock t drives the wheels from t + ``actuation_delay_s`` on, whatever
the sensors' rates (a motor driver reading its command once per control period).

The robot's facts come from its model, and the sim is their one source on the bus: before sim time starts it
latches the robot's MJCF on ``robot_description`` (flattened, :mod:`mjnav.sim.description`) and ``base_link`` →
each sensor frame on ``tf_static``, as ROS's robot_state_publisher does. Placing the robot at the world's start is
part of the simulated world: when sim time starts the sim announces that spawn pose on ``initialpose``
(``announce_spawn``), what an operator would tell SLAM, so every deployment starts the same way.

Velocity mux (ROS's twist_mux with two inputs): a command on ``cmd_vel_teleop`` (``mjnav teleop``, a joystick)
overrides navigation's ``cmd_vel`` while the newest teleop command is at most ``teleop_timeout_s`` of sim time old;
navigation's commands are dropped meanwhile, and the next one drives the wheels once teleop has been silent that
long. Without teleop traffic nothing changes, so lockstep runs stay repeatable.

Time: the service steps on wall time (it *is* the clock). In **lockstep** (the default) sim time advances one clock
tick at a time, and only when every participant — each service on sim time, and mission clients — has finished
the step that is due (:class:`~mjnav.runtime.simtime.LockstepBarrier`); time starts once the participants named in
``lockstep_participants`` are present. ``rtf`` caps the pace (at most rtf × wall time; ``0`` = as fast as the
participants allow), so a run gives the same result on a busy machine as on an idle one. **Free-running**
(``lockstep = false``) advances to ``rtf × wall time since activation`` whatever the others do, like hardware.
Both are paced by :class:`~mjnav.runtime.simtime.Pacer`; every periodic publication is a
:class:`~mjnav.runtime.simtime.Schedule`.
"""

from __future__ import annotations

import enum
import logging
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from mjnav.bus import Bus, Publisher
from mjnav.control import CollisionMonitor, CollisionMonitorParams, default_zones
from mjnav.control.collision import TrackedScan, TrackingParams, track_scan
from mjnav.geometry import Pose2D
from mjnav.msgs import msg_class, ros
from mjnav.msgs.topics import PUBLISH_RIGHTS
from mjnav.robot import LIDAR_SITE, RobotDescription
from mjnav.runtime import Service
from mjnav.runtime.simtime import LockstepBarrier, Pacer, Schedule

if TYPE_CHECKING:
    from mjnav.sim import SimRunner

log = logging.getLogger("mjnav.sim")

#: ``sim_status`` messages per sim second.
SIM_STATUS_RATE_HZ = 10.0
#: Scan points moving slower than this between two scans count as static for the collision monitor, m/s (the
#: controller's default: lidar noise and the aperture problem stay below it).
MOVING_SPEED_MPS = 0.25


@dataclass(frozen=True)
class SimConfig:
    """Sim service settings (``services/sim.toml``).

    Attributes:
        world: bundled world name (empty, rooms, maze, warehouse) or an MJCF path.
        seed: seed of every noise source.
        rtf: real-time factor: at most rtf × wall time in lockstep, rtf × wall time free-running; 0 = as fast as
            possible.
        rate_hz: wall-time loop rate of the service.
        clock_rate_hz: ``clock`` messages per sim second: the ticks services step on (a multiple of every
            service's ``rate_hz``) and, in lockstep, the rounds of the barrier.
        odom_rate_hz: ``odom``, ``tf``, ``joint_states``, ``truth`` and ``ground_truth`` per sim second; each
            carries the wheel odometry's newest update (the encoders are integrated at 50 Hz). The default is the
            control rate: no service steps faster, and 50 Hz cost the stack about 15 % of its speed in messages that
            nobody read.
        imu_rate_hz: ``imu`` per sim second.
        obstacles_rate_hz: ``obstacles`` (true poses of the world's moving bodies) per sim second; worlds without
            moving bodies publish none.
        actuation_delay_s: sim seconds from a clock tick to the moment the wheels take the newest command (a whole
            number of physics steps, > 0 and at most one clock period): the command a controller computed on clock
            t drives the wheels from t + actuation_delay_s until the next tick's. Commands are taken at that one
            moment per clock period, whatever the publishing rates.
        watchdog_timeout_s: zero the wheels when the newest command is this old (sim seconds).
        teleop_timeout_s: ``cmd_vel_teleop`` overrides ``cmd_vel`` until it has been silent this long (sim seconds).
        collision_monitor: check every command the mux lets through, and again on every scan, against the collision
            monitor's zones (:class:`mjnav.control.CollisionMonitor`, grown from the robot's footprint: stop at
            0.01 m, approach at 0.02 m plus 0.03 m ahead in the direction of travel) on the newest scan, its
            moving returns predicted at the velocities two scans give, moved to the command's time by the wheel
            odometry; its state goes out on ``collision_monitor``.
        monitor_time_before_collision_s: the approach zone's T: a command that would reach an obstacle within T
            is scaled by t/T (Nav2's ``time_before_collision``), seconds.
        monitor_slowdown_ratio: the slowdown zone's scale (a box 0.5 m ahead in the direction of travel); 1 = no
            slowdown zone (the default: navigation already slows near obstacles ahead).
        monitor_min_points: scan points a zone needs before it acts.
        record_path: write an MP4 of the run here ("" = no recording).
        record_fps: video frame rate (frames per sim second).
        record_camera: ``follow`` (a chase camera behind the robot, the default) or ``top`` (the whole world).
            Either way the video shows the map, plan, path, goal and driven trail over the world
            (:class:`mjnav.sim.recording.Overlay`).
        lockstep: advance only when every participant finished its due step (False: free-running on wall time).
        lockstep_participants: participants that must be present before sim time starts (``mjnav up`` fills in the
            stack's sim-time services, ``mjnav demo`` adds its mission client).
        lockstep_timeout_s: wall seconds a participant may hold sim time before it is named and left out.
        publish_ground_truth: publish the true pose on ``ground_truth`` (for tools and comparisons; the navigation
            services run on SLAM's ``map → odom`` and the odometry). The evaluation channel ``truth`` is always
            published. Both go out at ``odom_rate_hz``: an evaluator's clearance is sampled every 50 ms by default
            (2.5 cm of driving at 0.5 m/s); the sim's collision count checks contacts at every physics step.
        odom_noise_scale: multiplies every wheel-odometry error (radius, wheel base, slip): 1 = the default model
            (0.3 % radius, 1 % wheel base, 1 % slip), 0 = perfect odometry, 3 = three times as bad.
        announce_spawn: publish the robot's start pose on ``initialpose`` when sim time starts (the operator's
            act of placing the robot; SLAM starts from it).
        spawn_sigma: (σ_xy m, σ_yaw rad) of that announcement's covariance.
    """

    world: str = "rooms"
    seed: int = 0
    rtf: float = 1.0
    rate_hz: float = 100.0
    clock_rate_hz: float = 20.0
    odom_rate_hz: float = 20.0
    imu_rate_hz: float = 100.0
    obstacles_rate_hz: float = 10.0
    actuation_delay_s: float = 0.01
    watchdog_timeout_s: float = 0.25
    teleop_timeout_s: float = 0.5
    collision_monitor: bool = True
    monitor_time_before_collision_s: float = 1.0
    monitor_slowdown_ratio: float = 1.0
    monitor_min_points: int = 3
    record_path: str = ""
    record_fps: float = 30.0
    record_camera: str = "follow"
    lockstep: bool = True
    lockstep_participants: tuple[str, ...] = ()
    lockstep_timeout_s: float = 10.0
    publish_ground_truth: bool = True
    odom_noise_scale: float = 1.0
    announce_spawn: bool = True
    spawn_sigma: tuple[float, float] = (0.05, 0.05)

    def __post_init__(self) -> None:
        if not all(v >= 0.0 for v in self.spawn_sigma):
            raise ValueError(f"spawn_sigma must be >= 0 (m, rad), got {list(self.spawn_sigma)}")
        self.monitor_params()  # its own checks
        if not self.rtf >= 0.0:
            raise ValueError(f"rtf must be >= 0 (0 = as fast as possible), got {self.rtf}")
        if not 0.0 <= self.odom_noise_scale <= 20.0:
            raise ValueError(f"odom_noise_scale must be in [0, 20], got {self.odom_noise_scale}")
        for name in (
            "clock_rate_hz",
            "odom_rate_hz",
            "imu_rate_hz",
            "obstacles_rate_hz",
            "actuation_delay_s",
            "watchdog_timeout_s",
            "teleop_timeout_s",
            "record_fps",
            "lockstep_timeout_s",
        ):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        # Messages go out on a grid of the fastest schedule's period; the clock must fall on that grid, or a clock
        # tick is published late and the lockstep rounds stall (imu_rate_hz = 50 with a 20 Hz clock did).
        fastest = max(self.odom_rate_hz, self.imu_rate_hz, self.clock_rate_hz, self.obstacles_rate_hz)
        ratio = fastest / self.clock_rate_hz
        if abs(ratio - round(ratio)) > 1e-9:
            raise ValueError(
                f"the fastest publishing rate ({fastest:g} Hz, of odom_rate_hz, imu_rate_hz and obstacles_rate_hz) "
                f"must be a whole multiple of clock_rate_hz ({self.clock_rate_hz:g} Hz)"
            )
        if self.actuation_delay_s > 1.0 / self.clock_rate_hz + 1e-9:
            raise ValueError(
                f"actuation_delay_s ({self.actuation_delay_s:g} s) must be at most one clock period "
                f"({1.0 / self.clock_rate_hz:g} s): the wheels take one command per clock tick"
            )
        if self.record_camera not in ("top", "follow"):
            raise ValueError(f"record_camera must be 'top' or 'follow', got {self.record_camera!r}")
        from mjnav.sim.errors import UnknownWorldError
        from mjnav.sim.worlds import resolve_world

        try:
            resolve_world(self.world)  # a wrong world fails here, before anything starts
        except UnknownWorldError as exc:
            raise ValueError(str(exc)) from exc

    def monitor_params(self) -> CollisionMonitorParams:
        """The collision monitor's settings (the library's defaults but for these fields).

        Raises:
            ValueError: a setting out of its range.
        """
        return CollisionMonitorParams(
            time_before_collision_s=self.monitor_time_before_collision_s,
            slowdown_ratio=self.monitor_slowdown_ratio,
            min_points=self.monitor_min_points,
        )


class _MonitoredCommand:
    """The collision monitor in the sim's command path: every command the mux passes, and the held one again on
    every scan, is checked against the newest scan (its returns and their velocities from two scans,
    :func:`mjnav.control.collision.track_scan`, in the wheel odometry's frame and moved to the command's time by it:
    what a robot's own monitor has; moving returns moved on by their velocity for the scan's age); the state goes
    out on ``collision_monitor`` when it changes."""

    def __init__(self, sim: Any, bus: Bus, params: CollisionMonitorParams, tracking: TrackingParams) -> None:
        footprint = sim.description.footprint_m
        zones = [z for z in default_zones(footprint, params) if z.action != "slowdown" or params.slowdown_ratio < 1]
        self.monitor = CollisionMonitor(zones, params)
        self.sim = sim
        self.lidar = sim.description.frame(LIDAR_SITE).planar
        self.tracking = tracking
        self.tracked: TrackedScan | None = None  # the newest scan, odometry frame, with velocities
        self.requested: tuple[float, float] | None = None  # the mux's newest command, before the monitor
        self._pub = bus.publisher("collision_monitor")
        self._state: tuple[str, str | None, int] = ("", None, -1)
        self.source = ""

    def command(self, t: float, v: float, w: float, source: str) -> None:
        """A new command from the mux: check it and drive the wheels with the result (re-arms the watchdog)."""
        self.requested, self.source = (v, w), source
        self.sim.set_command(*self._checked(t, v, w))

    def scan(self, t: float, scan: Any) -> None:
        """A new scan: track it, check the held command again (the watchdog is not re-armed)."""
        odom = self.sim.odometry().pose
        x, y, yaw = self.lidar
        c, s = math.cos(odom.theta), math.sin(odom.theta)
        sensor = (odom.x + c * x - s * y, odom.y + s * x + c * y, odom.theta + yaw)
        cfg = scan.config
        self.tracked = track_scan(
            scan.stamp_s, sensor, cfg.angle_min_rad, cfg.angle_increment_rad, scan.ranges_m, cfg.range_min_m,
            cfg.range_max_m, self.tracked, self.tracking,
        )  # fmt: skip
        if self.requested is not None and not self.sim.watchdog_tripped:
            self.sim.limit_command(*self._checked(t, *self.requested))

    def _checked(self, t: float, v: float, w: float) -> tuple[float, float]:
        if self.tracked is None:
            return v, w
        pose = self.sim.odometry().pose
        age = max(t - self.tracked.stamp_s, 0.0)  # moving returns go on moving while the scan ages
        points = pose.inverse().transform_points(self.tracked.points + age * self.tracked.velocities)
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        velocities = self.tracked.velocities @ np.array([[c, -s], [s, c]])  # odometry frame -> base frame axes
        result = self.monitor.check(v, w, points, velocities)
        self._publish(t, result)
        return result.v_mps, result.omega_radps

    def _publish(self, t: float, result: Any) -> None:
        action = str(result.action)
        level = 0 if action == "none" else (2 if result.scale == 0.0 else 1)  # ERROR: the command stopped
        state = (action, result.zone, level)
        if state == self._state:
            return
        was, self._state = self._state[2], state
        if action == "none":
            text = "clear"
        else:
            text = f"{'stopped' if level == 2 else 'slowed'} by zone {result.zone} ({action}, scale {result.scale:.2f})"
        if (level > 0) != (was > 0):  # an intervention starts or ends (not each change within one)
            log.info("collision monitor: %s (%s's command)", text, self.source)
        values = {
            "action": action,
            "zone": result.zone or "",
            "scale": f"{result.scale:.3f}",
            "time_to_collision_s": f"{result.time_to_collision_s:.3f}",
            "source": self.source,
            "stamp": f"{t:.6f}",
        }
        self._pub.put(ros.diagnostic_status(level, "collision_monitor", text, values))


class _Round(enum.Enum):
    """Where the lockstep loop is within a round (see :meth:`SimService._step_lockstep`)."""

    IDLE = 0  # clock t is out; the physics has not stepped past t
    ACTUATING = 1  # stepped to the moment the robot takes the command of step t
    HELD = 2  # stepped to t + tick, its clock held until every participant finished step t


class ClockOut:
    """A sim's ``clock`` publication, which a pipelined lockstep round holds back until every participant has
    reported (see :meth:`SimService._step_lockstep`)."""

    def __init__(self, bus: Bus) -> None:
        self._bus = bus
        self._pub = bus.publisher("clock")
        #: Keep a clock that falls due for :meth:`release` instead of publishing it.
        self.hold = False
        self._held: float | None = None

    def due(self, t: float) -> None:
        """Clock ``t`` falls due: publish it, or keep it while :attr:`hold`."""
        if self.hold:
            self._held = t
        else:
            self.publish(t)

    def release(self) -> None:
        """Publish the clock kept back, if any."""
        t, self._held = self._held, None
        if t is not None:
            self.publish(t)

    def publish(self, t: float) -> None:
        self._pub.put(ros.clock(t))
        self._bus.sim_time = t  # what follows belongs to a later step (mjnav.runtime.simtime.SimTimeGate)


class SimStepping(Protocol):
    """What :class:`SimService`'s stepping loop drives: the extension point for another simulator on the same loop
    (lockstep barrier, pacing, free-running), such as :class:`~mjnav.services.uav_sim.UavBridge`."""

    #: Wall time (``time.monotonic``) from which the published real-time factor counts; the loop resets it when
    #: lockstep time starts.
    wall0: float
    #: The sim's lockstep barrier (None: free-running), whose waiting time ``sim_status`` reports.
    barrier: LockstepBarrier | None

    @property
    def time_s(self) -> float:
        """Sim time now, s."""
        ...

    @property
    def clock_period_s(self) -> float:
        """Sim seconds between two ``clock`` messages (one lockstep round)."""
        ...

    #: Topics whose commands drive the simulated robot: their publishers (``PUBLISH_RIGHTS``) are the participants
    #: the physics waits for, within a lockstep round, before it takes a new command.
    command_topics: tuple[str, ...]

    def free_until_s(self, clock_s: float) -> float:
        """How far the physics may step after clock ``clock_s`` before the first new command is taken (no later
        than ``clock_s`` when a command is taken at the clock itself)."""
        ...

    def advance(self, target_s: float, deadline: float | None = None, *, hold_clock: bool = False) -> None:
        """Step to sim time ``target_s``, publishing what falls due (the clock last); stop early at the
        ``time.perf_counter`` ``deadline``. ``hold_clock``: keep the clock due at ``target_s`` for
        :meth:`release_clock`."""
        ...

    def release_clock(self) -> None:
        """Publish the clock the last :meth:`advance` held (nothing when it held none)."""
        ...


class SimBridge:
    """Moves a :class:`~mjnav.sim.Simulator` forward and connects it to the bus (used by the service and
    by ``mjnav sim`` with the bus)."""

    def __init__(self, sim: Any, bus: Bus, config: SimConfig) -> None:
        self.sim = sim
        self.config = config
        self._bus = bus
        self._cmd = bus.subscribe("cmd_vel")
        self._teleop = bus.subscribe("cmd_vel_teleop")
        self._teleop_t = -math.inf  # sim time of the newest teleop command
        #: True while teleop overrides navigation.
        self.teleop_active = False
        self._pub = {
            name: bus.publisher(name) for name in ("scan", "odom", "imu", "joint_states", "tf", "truth", "sim_status")
        }
        self._ground_truth = bus.publisher("ground_truth") if config.publish_ground_truth else None
        self._spawn = bus.publisher("initialpose") if config.announce_spawn else None
        # Only worlds with moving bodies (the warehouse's carts) declare the topic.
        self._obstacles = bus.publisher("obstacles") if sim.moving_body_names else None
        self._obstacles_due = Schedule.every(config.obstacles_rate_hz)
        self._clock = Schedule.every(config.clock_rate_hz)
        self._odom = Schedule.every(config.odom_rate_hz)
        self._imu = Schedule.every(config.imu_rate_hz)
        self._status = Schedule.every(SIM_STATUS_RATE_HZ)
        self._sim_status = msg_class("mjnav_msgs/msg/SimStatus")
        self.wall0 = time.monotonic()
        #: The sim's lockstep barrier (None: free-running), whose waiting time ``sim_status`` reports.
        self.barrier: LockstepBarrier | None = None
        lidar = sim.lidar_config
        self._scan_time_s = 1.0 / lidar.rate_hz if lidar is not None else math.inf
        self.commands_applied = 0
        self.command_topics: tuple[str, ...] = ("cmd_vel",)
        self.monitor = (
            _MonitoredCommand(sim, bus, config.monitor_params(), TrackingParams(moving_speed_mps=MOVING_SPEED_MPS))
            if config.collision_monitor
            else None
        )
        self._clock_out = ClockOut(bus)

    @property
    def tick_s(self) -> float:
        """Sim-time period at which :meth:`publish_due` must be called: the shortest publishing period (messages
        of slower schedules go out at the first call at or after their due time)."""
        schedules = [self._clock, self._odom, self._imu] + ([self._obstacles_due] if self._obstacles else [])
        return min(e.period_s for e in schedules)

    def attach(self, runner: SimRunner) -> None:
        """Make :meth:`apply_command` a hook of ``runner`` (``actuation_delay_s`` after every clock tick) and
        :meth:`publish_due` another (every :attr:`tick_s`); :meth:`advance` then steps them.

        Raises:
            ValueError: the clock period or the actuation delay is not a whole number of physics steps, or the
                clock period not one of hook ticks: a clock would go out late or never (40 Hz on 2 ms steps is
                12.5 steps), a command would drive the wheels later than said. The runner rounds each tick to a
                step, so a tick need not be whole steps itself: the clock's ticks fall on whole steps.
        """
        dt = self.sim.timestep_s
        tick_steps = max(1.0, self.tick_s / dt)  # faster schedules run at every step
        clock_steps = self.clock_period_s / dt

        def whole(x: float) -> bool:
            return abs(x - round(x)) < 1e-6

        if not (whole(clock_steps) and whole(clock_steps / tick_steps)):
            raise ValueError(
                f"the clock's period ({1e3 * self.clock_period_s:g} ms) must be a whole number of {dt * 1e3:g} ms "
                f"physics steps and of the fastest publishing rate's ticks ({1.0 / self.tick_s:g} Hz)"
            )
        delay = self.config.actuation_delay_s
        if not whole(delay / dt):
            raise ValueError(
                f"actuation_delay_s ({1e3 * delay:g} ms) must be a whole number of {dt * 1e3:g} ms physics steps"
            )
        runner.add_hook(lambda sim: self.publish_due(sim.time_s), self.tick_s)
        runner.add_hook(lambda sim: self.apply_command(sim.time_s), self.clock_period_s, offset_s=delay)
        self._runner = runner

    @property
    def time_s(self) -> float:
        """Sim time now, s."""
        return float(self.sim.time_s)

    def free_until_s(self, clock_s: float) -> float:
        """The physics step before the wheels take the command of clock ``clock_s`` (``actuation_delay_s`` later)."""
        return clock_s + self.config.actuation_delay_s - self.sim.timestep_s

    def advance(self, target_s: float, deadline: float | None = None, *, hold_clock: bool = False) -> None:
        """Step the attached runner to ``target_s`` (see :meth:`mjnav.sim.SimRunner.advance`); ``hold_clock``:
        keep a clock due there for :meth:`release_clock`."""
        self._clock_out.hold = hold_clock
        try:
            self._runner.advance(target_s, deadline)
        finally:
            self._clock_out.hold = False

    def release_clock(self) -> None:
        """Publish the clock the last :meth:`advance` held."""
        self._clock_out.release()

    @property
    def clock_period_s(self) -> float:
        """Sim seconds between two ``clock`` messages."""
        return self._clock.period_s

    def apply_command(self, t: float) -> None:
        """Drive the wheels with the newest command that arrived since the last call (at sim time ``t``, a clock tick
        plus ``actuation_delay_s``): teleop's while it is fresh, else navigation's (the mux, see the module
        docstring)."""
        teleop = self._teleop.take()
        nav = self._cmd.take()
        if teleop is not None:
            if not self.teleop_active:
                log.info("teleop overrides navigation (cmd_vel_teleop)")
            self.teleop_active = True
            self._teleop_t = t
            cmd = teleop
        elif self.teleop_active and t - self._teleop_t <= self.config.teleop_timeout_s:
            return  # teleop holds: navigation's commands are dropped
        else:
            if self.teleop_active:
                log.info("teleop silent for %.2f s: navigation resumes", t - self._teleop_t)
            self.teleop_active = False
            cmd = nav
        if cmd is not None:
            if self.monitor is not None:
                self.monitor.command(t, cmd.linear.x, cmd.angular.z, "teleop" if self.teleop_active else "navigation")
            else:
                self.sim.set_command(cmd.linear.x, cmd.angular.z)
            self.commands_applied += 1

    def publish_due(self, t: float) -> None:
        """Publish every message due at sim time ``t`` (call every :attr:`tick_s`), ``clock`` last."""
        sim = self.sim
        clock_due = self._clock.due(t)
        if self._spawn is not None:  # the first call: sim time starts with the robot at its spawn pose
            sxy, syaw = self.config.spawn_sigma
            cov = np.diag([sxy**2, sxy**2, syaw**2])
            self._spawn.put(ros.pose_with_covariance_stamped(t, "map", sim.start_pose, cov))
            self._spawn = None
        if self._odom.due(t):
            est = sim.odometry()
            stamp = est.stamp_s
            self._pub["odom"].put(ros.odometry(stamp, est.pose, est.v_mps, est.omega_radps))
            self._pub["tf"].put(ros.tf_message(ros.transform_stamped(stamp, "odom", "base_link", est.pose)))
            wheels = sim.wheel_states()
            self._pub["joint_states"].put(ros.joint_state(t, wheels.names, wheels.position_rad, wheels.velocity_radps))
            truth = ros.pose_stamped(t, "map", sim.ground_truth_pose())
            self._pub["truth"].put(truth)
            if self._ground_truth is not None:
                self._ground_truth.put(truth)
        # Scans after the poses of the same tick, so a mapper always finds the pose of a scan's stamp.
        scan = sim.pop_scan()
        if scan is not None:
            if self.monitor is not None:
                self.monitor.scan(t, scan)
            cfg = scan.config
            self._pub["scan"].put(
                ros.laser_scan(
                    scan.stamp_s,
                    "laser",
                    angle_min_rad=cfg.angle_min_rad,
                    angle_increment_rad=cfg.angle_increment_rad,
                    scan_time_s=self._scan_time_s,
                    range_min_m=cfg.range_min_m,
                    range_max_m=cfg.range_max_m,
                    ranges_m=scan.ranges_m,
                )
            )
        if self._status.due(t):
            wall = time.monotonic() - self.wall0
            self._pub["sim_status"].put(
                self._sim_status(
                    header=ros.header(t, "map"),
                    world=sim.world.name,
                    collisions=sim.collisions,
                    real_time_factor=t / wall if wall > 0 else 0.0,
                    watchdog_tripped=sim.watchdog_tripped,
                    lockstep_wait_s=self.barrier.waited_s if self.barrier is not None else 0.0,
                )
            )
        if self._obstacles is not None and self._obstacles_due.due(t):
            self._obstacles.put(
                ros.tf_message(
                    *(
                        ros.transform_stamped_3d(t, "map", body.name, body.position_m, body.orientation_xyzw)
                        for body in sim.moving_body_poses()
                    )
                )
            )
        if self._imu.due(t):
            reading = sim.imu()
            self._pub["imu"].put(
                ros.imu(
                    t, "imu", reading.orientation_xyzw, reading.angular_velocity_radps, reading.linear_acceleration_mps2
                )
            )
        # The clock goes last: a service that sees clock t has received every message stamped up to t. What the
        # sim publishes after it is marked as sent at t (Bus.sim_time): it belongs to a later step.
        if clock_due:
            self._clock_out.due(t)


def publish_robot_facts(bus: Bus, description: RobotDescription) -> tuple[Publisher, Publisher]:
    """Latch the robot's description and ``base_link`` → each of its sensor frames on ``tf_static``.

    Returns:
        The two publishers: keep them as long as the sim runs (they answer late joiners).
    """
    text = msg_class("std_msgs/msg/String")(data=description.mjcf)
    frames = [
        ros.transform_stamped_3d(0.0, description.base_frame, f.name, f.xyz_m, f.quat_xyzw) for f in description.frames
    ]
    pubs = bus.publisher("robot_description"), bus.publisher("tf_static")
    pubs[0].put(text)
    pubs[1].put(ros.tf_message(*frames))
    return pubs


class SimService(Service[SimConfig]):
    """Runs the simulator at ``rtf`` × wall time and bridges it to the bus.

    The stepping loop (lockstep or free-running, paced at ``rtf``) drives :attr:`bridge`, a :class:`SimStepping`.
    Another simulator reuses it by subclassing and overriding :meth:`configure` (set ``config`` fields ``rtf``,
    ``rate_hz``, ``lockstep*``; set :attr:`bridge`, :attr:`barrier` — a
    :class:`~mjnav.runtime.simtime.LockstepBarrier` or ``None`` — and :attr:`sim`, whose ``time_s`` and
    ``collisions`` the periodic log reads) and :meth:`deactivate`, as :mod:`mjnav.services.uav_sim` does.
    """

    bridge: SimStepping
    barrier: LockstepBarrier | None

    name = "sim"
    config_class = SimConfig
    uses_sim_time = False

    def _record_frame(self, sim: Any) -> None:
        """Runner hook: refresh the video's overlay from the newest navigation messages, then capture a frame."""
        ov = self.recorder.overlay
        subs = self._overlay_subs
        grid = subs["map"].take()
        if grid is not None:
            cells, frame = ros.grid_frame(grid)
            ov.set_map(cells, frame.origin_m, frame.resolution_m)
        for name in ("plan", "path"):
            msg = subs[name].take()
            if msg is not None:
                pts = [(p.pose.position.x, p.pose.position.y) for p in msg.poses]
                setattr(ov, name, np.asarray(pts, dtype=np.float64).reshape(-1, 2))
        for status in subs["goal_status"].drain():
            position = status.goal.pose.position
            ov.goal = (float(position.x), float(position.y))
        self.recorder.capture()

    def configure(self) -> None:
        from mjnav.sim import Recorder, SimRunner, Simulator
        from mjnav.sim.odometry import OdometryConfig

        cfg = self.config
        base = OdometryConfig()
        k = cfg.odom_noise_scale
        odometry = replace(
            base,
            wheel_radius_error_std=k * base.wheel_radius_error_std,
            wheel_separation_error_std=k * base.wheel_separation_error_std,
            slip_noise_std=k * base.slip_noise_std,
        )
        self.sim = Simulator(cfg.world, seed=cfg.seed, odometry=odometry, watchdog_timeout_s=cfg.watchdog_timeout_s)
        self.robot_facts = publish_robot_facts(self.bus, self.sim.description)
        self.bridge = bridge = SimBridge(self.sim, self.bus, cfg)
        self.runner = SimRunner(self.sim, rtf=None)  # paced by step() below
        bridge.attach(self.runner)
        self.barrier = bridge.barrier = (
            LockstepBarrier(self.bus, cfg.lockstep_participants, cfg.lockstep_timeout_s, self.log)
            if cfg.lockstep
            else None
        )
        self.recorder: Any = None
        if cfg.record_path:
            self.recorder = Recorder(
                self.sim.model,
                self.sim.data,
                Path(cfg.record_path),
                fps=cfg.record_fps,
                camera=cfg.record_camera,
                track_body=self.sim.robot.root_body,
            )
            # What navigation knows goes into the video: the map, the plan, the path, the goal (and the trail).
            self._overlay_subs = {name: self.bus.subscribe(name) for name in ("map", "plan", "path", "goal_status")}
            self.recorder.overlay.track_trail = True
            self.runner.add_hook(self._record_frame, 1.0 / cfg.record_fps)
        start: Pose2D = self.sim.start_pose
        self.log.info(
            "world %s, start (%.2f, %.2f, %.2f), rtf %s, %s",
            cfg.world,
            start.x,
            start.y,
            start.theta,
            cfg.rtf or "max",
            f"lockstep with {', '.join(cfg.lockstep_participants) or 'whoever joins'}"
            if cfg.lockstep
            else "free-running",
        )

    def activate(self) -> None:
        self._wall0 = time.monotonic()
        self._last_report = self._wall0
        # Lockstep: never sprint after a stall, and the next tick allowed at once; free-running: sim time follows
        # rtf × wall time since activation, catching up like hardware.
        lockstep = self.barrier is not None
        lead_s = self.bridge.clock_period_s if lockstep else 0.0
        self._pacer = Pacer(self.config.rtf, catch_up=not lockstep, lead_s=lead_s)
        self._pacer.reset(self.bridge.time_s)
        self._time_started = False
        self._missing: list[str] = []
        self._clock_s = 0.0  # the newest clock published
        self._round = _Round.IDLE
        self._actuators = frozenset(n for topic in self.bridge.command_topics for n in PUBLISH_RIGHTS[topic])
        # A video's frames draw the navigation's newest messages: recording, the physics waits for everybody, so
        # each frame shows the same plan and map on any machine.
        self._pipelined = self.recorder is None

    def step(self, now: float) -> None:
        if self.barrier is not None:
            self._step_lockstep()
        else:
            self._step_free()
        wall = time.monotonic()
        if wall - self._last_report >= 10.0:
            self._last_report = wall
            self.log.info(
                "sim time %.1f s, real-time factor %.2f, collisions %d",
                self.sim.time_s,
                self.sim.time_s / max(wall - self._wall0, 1e-9),
                self.sim.collisions,
            )

    def _step_lockstep(self) -> None:
        """Advance clock tick by clock tick while every participant is ready, within one loop period of wall time
        and at most ``rtf`` × wall time.

        A round from clock t to t + tick is pipelined: the physics steps on while the participants still work on
        their steps at t, and waits only where it must. Up to the moment the robot takes a new command
        (:meth:`SimStepping.free_until_s`) it needs nobody; from there to t + tick it needs the participants that
        command it (``command_topics``' publishers: the controller) to have finished their step at t; the clock of
        t + tick goes out only once every participant has. What the sim publishes meanwhile is sent at t (the
        clock's tag), so every participant receives it at clock t + tick, exactly as if the sim had waited for
        everybody first: the same messages in every step, on any machine, whatever the packing.
        """
        barrier = self.barrier
        assert barrier is not None
        tick = self.bridge.clock_period_s
        if not self._time_started:
            if not barrier.started():
                return
            self.log.info("lockstep: sim time starts with %s", ", ".join(barrier.participants()) or "no participant")
            self._time_started = True
            self._wall0 = self.bridge.wall0 = time.monotonic()  # the real-time factor counts from here
            self._pacer.reset(0.0)
            barrier.published(0.0, tick)  # before the clock goes out: reports may come back at once
            self.bridge.advance(0.0)  # publishes everything due at t = 0, the clock last
        rtf = self.config.rtf
        missing = barrier.missing()
        if missing:
            rtf = min(rtf, 1.0) if rtf > 0 else 1.0  # degraded: real time until they are back (see lockstep.py)
        if missing != self._missing:
            if missing:
                self.log.warning("lockstep: %s missing: sim time at most real time until back", ", ".join(missing))
            else:
                self.log.info("lockstep: every participant is back: real-time factor %s", self.config.rtf or "max")
            self._missing = missing
            self._pacer = Pacer(rtf, lead_s=tick)
        deadline = time.monotonic() + 1.0 / self.config.rate_hz
        bridge = self.bridge
        while True:
            t = self._clock_s
            if self._round is _Round.IDLE:
                if t + tick > self._pacer.allowed(t):
                    return
                free = bridge.free_until_s(t)
                if free > t and self._pipelined:
                    bridge.advance(free)  # no command is taken on the way: nobody to wait for
                self._round = _Round.ACTUATING
            if self._round is _Round.ACTUATING:
                among = self._actuators if self._pipelined else None
                if not barrier.wait(t, max(0.0, deadline - time.monotonic()), among=among):
                    return
                bridge.advance(t + tick, hold_clock=True)
                self._round = _Round.HELD
            if not barrier.wait(t, max(0.0, deadline - time.monotonic())):
                return
            barrier.published(t + tick, tick)  # before the clock goes out: reports may come back at once
            bridge.release_clock()
            self._clock_s = t + tick
            self._round = _Round.IDLE
            if time.monotonic() >= deadline:
                return

    def _step_free(self) -> None:
        cfg = self.config
        bounded = self._pacer.rtf is not None
        deadline = time.perf_counter() + (2.0 if bounded else 0.9) / cfg.rate_hz  # never block the loop for long
        self.bridge.advance(self._pacer.allowed(self.bridge.time_s), deadline)

    def starved(self) -> str:
        barrier = self.barrier
        missing = [] if barrier is None else barrier.missing()
        if not missing:
            return ""
        if not self._time_started:
            return f"lockstep participants {', '.join(missing)} (sim time starts when they are present)"
        return f"lockstep participants {', '.join(missing)} (sim time at most real time until they are back)"

    def deactivate(self) -> None:
        self.sim.set_command(0.0, 0.0)
        if self.recorder is not None:
            self.recorder.close()
            self.log.info("wrote %d frames to %s", self.recorder.frames, self.config.record_path)
        self.log.info("stopped at sim time %.2f s with %d collision(s)", self.sim.time_s, self.sim.collisions)

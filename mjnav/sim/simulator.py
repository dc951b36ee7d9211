"""The simulation core: a diff-drive robot in a MuJoCo world, stepped at 2 ms, with its sensors.

:class:`Simulator` owns one ``MjModel``/``MjData`` pair. Everything periodic runs on a schedule of whole
physics steps, so a run is a pure function of (world, seed, command sequence) and never of wall time:

* lidar scans every ``1/LidarConfig.rate_hz`` s (default 10 Hz), the first at t = 0 — fetch with
  :meth:`Simulator.pop_scan` (``None`` when no new scan is due since the last call);
* wheel odometry every ``1/OdometryConfig.rate_hz`` s (default 50 Hz);
* the command watchdog: when the newest :meth:`Simulator.set_command` is ``watchdog_timeout_s`` old
  (default 0.5 s), the wheel servos are set to zero speed until the next command.

Between those events :meth:`Simulator.step_until` runs a tight loop of ``mj_step`` calls that only compares
two sensor values per step (the collision counter, see :attr:`Simulator.collisions`).

Noise and drift come from generators spawned from one seed (lidar, odometry, IMU, encoder velocity each get
their own stream, so reading one sensor more often does not change another's noise).
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Final, Literal

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjnav.geometry import Pose2D
from mjnav.motion import DiffDriveKinematics
from mjnav.robot import RobotDescription
from mjnav.sim.errors import InvalidCommandError, SimError
from mjnav.sim.lidar import Lidar, LidarConfig, LidarScan
from mjnav.sim.model import RobotBinding, body_name, load_world, moving_bodies, root_pose
from mjnav.sim.odometry import OdometryConfig, OdometryEstimate, WheelOdometry
from mjnav.sim.worlds import WorldInfo

#: Lidar of a robot model without ``lidar_*`` numerics: 360 beams, 10 Hz, 0.12–12 m, σ = 1 cm.
DEFAULT_LIDAR = LidarConfig()
#: ``Simulator(lidar=MODEL_LIDAR)`` (the default): the lidar the robot model declares (its ``lidar_*`` numerics).
MODEL_LIDAR: Final = "model"
#: Default odometry error model (50 Hz, 4096 ticks/rev, 0.3 % radius, 1 % wheel-base, 1 % slip noise).
DEFAULT_ODOMETRY = OdometryConfig()

_NEVER = sys.maxsize


@dataclass(frozen=True, slots=True)
class WheelStates:
    """Wheel encoder readings (``sensor_msgs/JointState`` content).

    Attributes:
        stamp_s: sim time, seconds.
        names: joint names (left, right), without the attach prefix.
        position_rad: (2,) unwrapped wheel angles (left, right), radians.
        velocity_radps: (2,) wheel rates (left, right) with encoder noise, rad/s.
    """

    stamp_s: float
    names: tuple[str, str]
    position_rad: NDArray[np.float64]
    velocity_radps: NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class BodyPose:
    """Pose of a named body in the map frame.

    Attributes:
        name: MJCF body name.
        position_m: (3,) position, metres.
        orientation_xyzw: (4,) orientation quaternion (x, y, z, w).
    """

    name: str
    position_m: NDArray[np.float64]
    orientation_xyzw: NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class ImuReading:
    """IMU sample in the ``imu`` site frame, aligned with base_link (``sensor_msgs/Imu`` content).

    Attributes:
        stamp_s: sim time, seconds.
        angular_velocity_radps: (3,) gyro with noise, rad/s.
        linear_acceleration_mps2: (3,) accelerometer with noise (reads +9.81 on z at rest), m/s².
        orientation_xyzw: (4,) true orientation quaternion (x, y, z, w) of base_link in the map frame.
    """

    stamp_s: float
    angular_velocity_radps: NDArray[np.float64]
    linear_acceleration_mps2: NDArray[np.float64]
    orientation_xyzw: NDArray[np.float64]


def _steps(period_s: float, dt: float) -> float:
    return period_s / dt


class Simulator:
    """A diff-drive robot in a MuJoCo world (see the module docstring for the schedule and noise)."""

    def __init__(
        self,
        world: str | Path,
        *,
        seed: int = 0,
        rng: np.random.Generator | None = None,
        lidar: LidarConfig | Literal["model"] | None = MODEL_LIDAR,
        odometry: OdometryConfig = DEFAULT_ODOMETRY,
        watchdog_timeout_s: float | None = 0.5,
        start: Pose2D | None = None,
        timestep_s: float = 0.002,
        collision_debounce_s: float = 0.25,
    ) -> None:
        """Load the world and put the robot at its start pose (t = 0).

        Args:
            world: bundled world name (``empty``, ``rooms``, ``maze``, ``warehouse``) or an MJCF path.
            seed: seed of every noise source; ignored when ``rng`` is given.
            rng: generator to spawn the noise streams from (overrides ``seed``).
            lidar: lidar layout, rate and noise; ``"model"`` (default): the robot model's (its ``lidar_*`` numerics,
                as its description says: :attr:`description`); ``None`` disables the lidar.
            odometry: wheel-odometry rate and error model.
            watchdog_timeout_s: zero the wheels when the newest command is this old, seconds; ``None``: never.
            start: start pose in the map frame; ``None`` = the world's own start (its ``start`` frame).
            timestep_s: physics step, seconds.
            collision_debounce_s: a contact starts a new collision only after this long without one, seconds.

        Raises:
            UnknownWorldError, ModelLoadError, RobotNotFoundError: see :func:`mjnav.sim.model.load_world`.
            InvalidCommandError: a non-positive timeout, debounce or timestep.
        """
        if not (math.isfinite(timestep_s) and timestep_s > 0.0):
            raise InvalidCommandError(f"timestep_s must be a positive number of seconds, got {timestep_s}")
        if not (math.isfinite(collision_debounce_s) and collision_debounce_s >= 0.0):
            raise InvalidCommandError(f"collision_debounce_s must be >= 0 seconds, got {collision_debounce_s}")
        if watchdog_timeout_s is not None and not (math.isfinite(watchdog_timeout_s) and watchdog_timeout_s > 0):
            raise InvalidCommandError(f"watchdog_timeout_s must be positive or None, got {watchdog_timeout_s}")
        loaded = load_world(world, timestep_s=timestep_s)
        self._model = loaded.model
        self._data = mujoco.MjData(self._model)
        self._robot: RobotBinding = loaded.robot
        self._kinematics = DiffDriveKinematics(loaded.robot.wheel_diameter_m, loaded.robot.wheel_separation_m)
        self._info: WorldInfo = loaded.info
        self._moving = moving_bodies(self._model, self._robot)
        self._moving_names = tuple(body_name(self._model, b) for b in self._moving)
        self._dt = float(self._model.opt.timestep)
        parent = rng if rng is not None else np.random.default_rng(seed)
        self._rng_lidar, self._rng_odom, self._rng_imu, self._rng_enc = parent.spawn(4)
        if isinstance(lidar, str):
            if lidar != MODEL_LIDAR:
                raise InvalidCommandError(f"lidar must be a LidarConfig, {MODEL_LIDAR!r} or None, got {lidar!r}")
            lidar = loaded.description.lidar
        self._lidar_config: LidarConfig | None = lidar
        self._description = loaded.description
        self._odom_config = odometry
        self._watchdog_steps = (
            _NEVER if watchdog_timeout_s is None else max(1, math.ceil(watchdog_timeout_s / self._dt - 1e-9))
        )
        self._watchdog_timeout_s = watchdog_timeout_s
        self._debounce_steps = round(collision_debounce_s / self._dt)
        self._sensordata = self._data.sensordata
        self._ctrl = self._data.ctrl
        self.reset(start)

    # ------------------------------------------------------------------ setup
    def reset(self, start: Pose2D | None = None) -> None:
        """Restart at t = 0: robot at ``start`` (default: the world's start), zero command, fresh counters.

        The noise generators continue their streams (a reset does not replay the same noise).
        """
        m, d, r = self._model, self._data, self._robot
        mujoco.mj_resetData(m, d)
        pose = start if start is not None else self._info.start
        a = r.root_qpos
        d.qpos[a] = pose.x
        d.qpos[a + 1] = pose.y
        d.qpos[a + 3 : a + 7] = (math.cos(0.5 * pose.theta), 0.0, 0.0, math.sin(0.5 * pose.theta))
        mujoco.mj_forward(m, d)
        self._start = pose
        self._k = 0
        self._cmd = (0.0, 0.0)
        self._cmd_k = 0
        self._watchdog_k = _NEVER
        self._watchdog_tripped = False
        self._collisions = 0
        self._last_contact_k = -_NEVER
        self._odom = WheelOdometry(r.wheel_diameter_m, r.wheel_separation_m, self._odom_config, self._rng_odom)
        self._odom.reset(0.0, float(d.qpos[r.wheel_qpos[0]]), float(d.qpos[r.wheel_qpos[1]]))
        self._odom_period = _steps(1.0 / self._odom_config.rate_hz, self._dt)
        self._odom_j = 1
        self._next_odom_k = max(1, round(self._odom_period))
        self._lidar: Lidar | None = None
        self._new_scan: LidarScan | None = None
        self._latest_scan: LidarScan | None = None
        self._next_scan_k = _NEVER
        if self._lidar_config is not None:
            self._lidar = Lidar(m, d, r.lidar_site, r.root_body, self._lidar_config, self._rng_lidar)
            self._scan_period = _steps(1.0 / self._lidar_config.rate_hz, self._dt)
            self._scan_j = 1
            self._next_scan_k = max(1, round(self._scan_period))
            self._cast_scan()

    # ------------------------------------------------------------- properties
    @property
    def model(self) -> mujoco.MjModel:
        """The compiled MuJoCo model (read it; changing it changes the physics)."""
        return self._model

    @property
    def moving_body_names(self) -> tuple[str, ...]:
        """Names of the world's moving bodies outside the robot (see :meth:`moving_body_poses`)."""
        return self._moving_names

    @property
    def data(self) -> mujoco.MjData:
        """The MuJoCo data (for renderers and the service; do not step it behind the simulator's back)."""
        return self._data

    @property
    def robot(self) -> RobotBinding:
        """Ids and addresses of the robot's elements."""
        return self._robot

    @property
    def world(self) -> WorldInfo:
        """Name, path, default start and goal and bounds of the loaded world."""
        return self._info

    @property
    def time_s(self) -> float:
        """Sim time, seconds (step count × timestep, exact)."""
        return self._k * self._dt

    @property
    def step_count(self) -> int:
        """Physics steps taken since the last reset."""
        return self._k

    @property
    def timestep_s(self) -> float:
        """Physics step, seconds."""
        return self._dt

    @property
    def start_pose(self) -> Pose2D:
        """Start pose of the current run in the map frame (also the ``map → odom`` transform)."""
        return self._start

    @property
    def goal_pose(self) -> Pose2D | None:
        """The world's default goal (map frame), or ``None``."""
        return self._info.goal

    @property
    def robot_radius_m(self) -> float:
        """Radius of the robot's footprint circle about base_link (every colliding geom inside), metres."""
        return self._description.radius_m

    @property
    def description(self) -> RobotDescription:
        """The robot's description: what the sim publishes on ``robot_description`` (:attr:`RobotDescription.mjcf`),
        parsed."""
        return self._description

    @property
    def wheel_diameter_m(self) -> float:
        """Drive wheel diameter W, metres."""
        return self._robot.wheel_diameter_m

    @property
    def wheel_separation_m(self) -> float:
        """Distance between the drive wheels L, metres."""
        return self._robot.wheel_separation_m

    @property
    def max_speed_mps(self) -> float:
        """Top straight-line speed allowed by the wheel servos' ctrlrange, m/s."""
        return 0.5 * self._robot.wheel_diameter_m * self._robot.max_wheel_speed_radps

    @property
    def lidar_config(self) -> LidarConfig | None:
        """The lidar configuration, or ``None`` when the lidar is disabled."""
        return self._lidar_config

    @property
    def lidar_offset_m(self) -> NDArray[np.float64]:
        """(3,) position of the lidar site in base_link, metres (the ``base_link → lidar`` transform)."""
        return np.array(self._model.site_pos[self._robot.lidar_site], dtype=np.float64)

    @property
    def command(self) -> tuple[float, float]:
        """Newest commanded (v m/s, ω rad/s) after saturation."""
        return self._cmd

    @property
    def watchdog_tripped(self) -> bool:
        """True while the wheels are held at zero because the newest command is too old."""
        return self._watchdog_tripped

    @property
    def collisions(self) -> int:
        """Number of collision events since the reset.

        A collision is a contact between any robot geom and any geom that is not a floor plane (walls,
        furniture, moving obstacles). Contacts are checked after every physics step, but an *event* is
        counted only when a contact appears after at least ``collision_debounce_s`` (default 0.25 s) without
        any: a robot pressing against or scraping along a wall for 10 s counts once, bouncing off it twice
        within 0.1 s counts once, hitting it again a second later counts twice.
        """
        return self._collisions

    @property
    def in_collision(self) -> bool:
        """True if the robot touched something other than the floor during the last physics step."""
        return self._last_contact_k == self._k and self._k > 0

    # ---------------------------------------------------------------- command
    def set_command(self, v_mps: float, omega_radps: float) -> tuple[float, float]:
        """Command a body twist; it is held until the next command or until the watchdog trips.

        The twist goes through the inverse diff-drive kinematics to the two wheel velocity servos. If a wheel
        would exceed its speed limit both wheel rates are scaled down by the same factor, so the path's
        curvature is kept and only the speed drops.

        Args:
            v_mps: forward speed, m/s.
            omega_radps: yaw rate, rad/s (counter-clockwise positive).

        Returns:
            The (v, ω) actually applied after saturation.

        Raises:
            InvalidCommandError: a value is not finite.
        """
        if not (math.isfinite(v_mps) and math.isfinite(omega_radps)):
            raise InvalidCommandError(f"command must be finite, got v={v_mps}, omega={omega_radps}")
        r = self._robot
        v, w = self._kinematics.limit_wheel_rates(v_mps, omega_radps, r.max_wheel_speed_radps)
        right, left = self._kinematics.wheel_rates(v, w)
        self._ctrl[r.wheel_actuators[0]] = left
        self._ctrl[r.wheel_actuators[1]] = right
        self._cmd = (v, w)
        self._cmd_k = self._k
        self._watchdog_tripped = False
        self._watchdog_k = _NEVER if self._watchdog_steps == _NEVER else self._k + self._watchdog_steps
        return self._cmd

    def limit_command(self, v_mps: float, omega_radps: float) -> tuple[float, float]:
        """Replace the held command's twist by (v, ω) without re-arming the watchdog: a safety stage that slows or
        stops the command it already passed (:class:`mjnav.control.CollisionMonitor` on a newer scan). A tripped
        watchdog's zero stays.

        Returns:
            The (v, ω) now applied (as :meth:`set_command`).

        Raises:
            InvalidCommandError: a value is not finite.
        """
        if self._watchdog_tripped:
            return 0.0, 0.0
        k, watchdog = self._cmd_k, self._watchdog_k
        applied = self.set_command(v_mps, omega_radps)
        self._cmd_k, self._watchdog_k = k, watchdog
        return applied

    # --------------------------------------------------------------- stepping
    def step(self, n: int = 1) -> None:
        """Advance ``n`` physics steps (``n × timestep_s`` seconds), running every event that falls due."""
        if n < 0:
            raise InvalidCommandError(f"cannot step a negative number of steps ({n})")
        self._run_to(self._k + n)

    def step_until(self, t_s: float) -> None:
        """Advance to the first step at or after sim time ``t_s`` (seconds); a time in the past is a no-op."""
        if not math.isfinite(t_s):
            raise InvalidCommandError(f"step_until needs a finite time, got {t_s}")
        self._run_to(math.ceil(t_s / self._dt - 1e-6))

    def _run_to(self, target: int) -> None:
        while self._k < target:
            nxt = min(target, self._next_scan_k, self._next_odom_k, self._watchdog_k)
            if nxt > self._k:
                self._advance(nxt - self._k)
            self._events()

    def _advance(self, n: int) -> None:
        """n × mj_step with the per-step collision check (the only Python work per step)."""
        m, d, step, sd = self._model, self._data, mujoco.mj_step, self._sensordata
        a = self._robot.contact_all_adr
        floors = self._robot.contact_floor_adrs
        k0, last, deb, count = self._k, self._last_contact_k, self._debounce_steps, self._collisions
        if len(floors) == 1:
            f = floors[0]
            for i in range(1, n + 1):
                step(m, d)
                if sd[a] > sd[f]:
                    if k0 + i - last > deb:
                        count += 1
                    last = k0 + i
        else:
            fl = list(floors)
            for i in range(1, n + 1):
                step(m, d)
                if sd[a] > (sd[fl].sum() if fl else 0.0):
                    if k0 + i - last > deb:
                        count += 1
                    last = k0 + i
        self._k, self._last_contact_k, self._collisions = k0 + n, last, count

    def _events(self) -> None:
        k = self._k
        if k >= self._watchdog_k:
            r = self._robot
            self._ctrl[r.wheel_actuators[0]] = 0.0
            self._ctrl[r.wheel_actuators[1]] = 0.0
            self._watchdog_tripped = True
            self._watchdog_k = _NEVER
        if k >= self._next_odom_k:
            q = self._data.qpos
            r = self._robot
            self._odom.update(self.time_s, float(q[r.wheel_qpos[0]]), float(q[r.wheel_qpos[1]]))
            self._odom_j += 1
            self._next_odom_k = max(k + 1, round(self._odom_j * self._odom_period))
        if k >= self._next_scan_k:
            self._cast_scan()
            self._scan_j += 1
            self._next_scan_k = max(k + 1, round(self._scan_j * self._scan_period))

    def _cast_scan(self) -> None:
        assert self._lidar is not None
        mujoco.mj_kinematics(self._model, self._data)  # rays must start from the current qpos, not the last step's
        scan = self._lidar.cast(self.time_s)
        self._new_scan = scan
        self._latest_scan = scan

    # ---------------------------------------------------------------- sensors
    def pop_scan(self) -> LidarScan | None:
        """The scheduled scan cast since the last call, or ``None`` when none is due yet (or no lidar)."""
        scan, self._new_scan = self._new_scan, None
        return scan

    @property
    def latest_scan(self) -> LidarScan | None:
        """The most recent scheduled scan (whether popped or not), or ``None`` without a lidar."""
        return self._latest_scan

    def lidar_scan(self) -> LidarScan:
        """Cast a scan now, off schedule, from the current state (stamped with the current time).

        Raises:
            SimError: the simulator was built with ``lidar=None``.
        """
        if self._lidar is None:
            raise SimError("the lidar is disabled (Simulator(..., lidar=None))")
        mujoco.mj_kinematics(self._model, self._data)
        return self._lidar.cast(self.time_s)

    def ground_truth_pose(self) -> Pose2D:
        """True planar pose of base_link in the map frame (``map → base_link``), metres and radians."""
        return root_pose(self._model, self._data.qpos, self._robot)

    def moving_body_poses(self) -> list[BodyPose]:
        """True poses in the map frame of the world's moving bodies (e.g. the warehouse's carts), in
        :attr:`moving_body_names` order."""
        d = self._data
        out = []
        for name, b in zip(self._moving_names, self._moving, strict=True):
            w, x, y, z = (float(v) for v in d.xquat[b])
            out.append(BodyPose(name, np.array(d.xpos[b], dtype=np.float64), np.array([x, y, z, w])))
        return out

    def body_velocity(self) -> tuple[float, float]:
        """True body twist (v m/s along base_link x, ω rad/s about z) measured from the physics state."""
        d, r = self._data, self._robot
        qv = d.qvel[r.root_qvel : r.root_qvel + 6]
        theta = self.ground_truth_pose().theta
        v = float(qv[0]) * math.cos(theta) + float(qv[1]) * math.sin(theta)
        return v, float(qv[5])

    def wheel_states(self) -> WheelStates:
        """Wheel angles (true, unwrapped) and wheel rates with encoder noise (σ from the MJCF sensors)."""
        d, r = self._data, self._robot
        pos = np.array([d.qpos[r.wheel_qpos[0]], d.qpos[r.wheel_qpos[1]]], dtype=np.float64)
        vel = np.array([d.qvel[r.wheel_qvel[0]], d.qvel[r.wheel_qvel[1]]], dtype=np.float64)
        if r.wheel_vel_noise_radps > 0.0:
            vel += self._rng_enc.normal(0.0, r.wheel_vel_noise_radps, 2)
        return WheelStates(self.time_s, r.wheel_joint_names, pos, vel)

    def imu(self) -> ImuReading:
        """Gyro and accelerometer with noise (σ from the MJCF sensors), plus the true orientation."""
        sd, r = self._sensordata, self._robot
        gyro = np.array(sd[r.gyro_adr : r.gyro_adr + 3], dtype=np.float64)
        accel = np.array(sd[r.accel_adr : r.accel_adr + 3], dtype=np.float64)
        if r.gyro_noise > 0.0:
            gyro += self._rng_imu.normal(0.0, r.gyro_noise, 3)
        if r.accel_noise > 0.0:
            accel += self._rng_imu.normal(0.0, r.accel_noise, 3)
        w, x, y, z = (float(v) for v in self._data.xquat[r.root_body])
        return ImuReading(self.time_s, gyro, accel, np.array([x, y, z, w], dtype=np.float64))

    def odometry(self) -> OdometryEstimate:
        """Latest wheel-odometry estimate (``odom → base_link``, updated at ``OdometryConfig.rate_hz``)."""
        return self._odom.latest

    def mujoco_warnings(self) -> dict[str, int]:
        """MuJoCo warnings raised since the reset, by name (``mjWARN_*`` → count); empty when clean."""
        out: dict[str, int] = {}
        for i in range(len(self._data.warning)):
            n = int(self._data.warning[i].number)
            if n:
                out[mujoco.mjtWarning(i).name] = n
        return out

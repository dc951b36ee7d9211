"""The UAV sim service: the MuJoCo quadrotor (:class:`~mjnav.sim.uav.UavSimulator`) on the bus.

Publishes, stamped in sim time: ``clock``, ``imu`` (body FLU specific force and rate, the AHRS attitude in ENU),
``gps`` (``sensor_msgs/NavSatFix`` about the configured geodetic origin, stamped when taken and published
``gps_delay_s`` later; the origin itself is latched on ``datum``), ``baro`` (static pressure), ``mocap`` (true pose
and twist in ENU: the motion-capture system; the twist's linear part is expressed in ``map``), ``ground_truth``
(true pose, for evaluation) and ``sim_status`` (collisions with obstacles, real-time factor, motor watchdog). It
drives the rotors with the newest ``rotor_cmd`` (speeds, rad/s), read at every IMU tick; an ESC-style watchdog
stops them when that command is older than ``motor_timeout_s`` of sim time. A command is taken only when it names
four rotors and is stamped neither before the last one taken nor after the sim time (a stale or forged flood does not
displace the flight controller's commands; one stamped like them and arriving later still would: only ``--secure``,
where the router takes ``rotor_cmd`` from the flight controller's identity alone, prevents that).

GPS faults can be injected by sim-time windows, as PX4 SITL's ``failure gps off`` / ``failure gps wrong``:
``gps_dropout_s`` (no fix is published for a fix taken in a window: the receiver lost its fix) and ``gps_glitch_s``
(a fix taken in a window is off by ``gps_glitch_m``, ENU). The noise is drawn for every fix either way, so a flight
with a fault sees the same noise as the flight without it.

Time and lockstep are the ground sim's (:class:`~mjnav.services.sim.SimService`, whose stepping loop this service
reuses): sim time advances one clock tick at a time once every lockstep participant has finished the step that is
due, so a flight is repeatable to the last bit.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mjnav.msgs import msg_class, ros
from mjnav.msgs import uav as uav_msgs
from mjnav.runtime.simtime import LockstepBarrier, Schedule
from mjnav.services.sim import SIM_STATUS_RATE_HZ, ClockOut, SimService

log = logging.getLogger("mjnav.uav_sim")


@dataclass(frozen=True)
class UavSimConfig:
    """UAV sim settings (``services/uav_sim.toml``).

    Attributes:
        world: UAV scene (``field``) or an MJCF path with the quadrotor attached under ``uav/``.
        seed: seed of the wind and every sensor's noise.
        rtf: at most rtf × wall time (0 = as fast as the participants allow).
        rate_hz: wall-time loop rate of the service.
        clock_rate_hz: ``clock`` per sim second: the lockstep rounds and the ticks the UAV services step on.
        imu_rate_hz: ``imu`` per sim second (a multiple of the clock rate, physics steps a multiple of its period).
        gps_rate_hz, gps_delay_s: GPS fixes per sim second and their latency, s.
        baro_rate_hz, mocap_rate_hz, truth_rate_hz: ``baro``, ``mocap`` and ``ground_truth`` per sim second.
        wind_mps, gust_mps: mean wind and peak gust speed, m/s.
        drag_area_m2: airframe C_d·A, m².
        origin_lat_deg, origin_lon_deg, origin_alt_m: WGS84 position of the scene's ENU origin.
        accel_noise_mps2, accel_bias_mps2, gyro_noise_radps, attitude_noise_rad, gps_noise_m, baro_noise_pa: sensor
            noise (see :class:`~mjnav.sim.uav.UavNoise`).
        motor_timeout_s: stop the rotors when the newest ``rotor_cmd`` is this old (sim seconds).
        gps_dropout_s: pairs ``[start, end, start, end, ...]`` of sim-time windows (s, half-open) in which the GPS
            has no fix (fixes taken then are not published).
        gps_glitch_s: windows (as ``gps_dropout_s``) in which the fixes taken are off by ``gps_glitch_m``.
        gps_glitch_m: (3,) ENU offset of a glitching fix, m.
        record_path: write an MP4 of the flight here ("" = no recording); record_fps: its frame rate;
            record_camera: a model camera (``uav/chase``, a chase camera), ``follow`` or ``top``.
        lockstep, lockstep_participants, lockstep_timeout_s: as the ground sim's.
    """

    world: str = "field"
    seed: int = 0
    rtf: float = 1.0
    rate_hz: float = 100.0
    clock_rate_hz: float = 50.0
    imu_rate_hz: float = 100.0
    gps_rate_hz: float = 10.0
    gps_delay_s: float = 0.15
    baro_rate_hz: float = 25.0
    mocap_rate_hz: float = 50.0
    truth_rate_hz: float = 50.0
    wind_mps: float = 0.0
    gust_mps: float = 0.0
    drag_area_m2: float = 0.05
    origin_lat_deg: float = 47.397742
    origin_lon_deg: float = 8.545594
    origin_alt_m: float = 488.0
    accel_noise_mps2: float = 0.02
    accel_bias_mps2: float = 0.05
    gyro_noise_radps: float = 0.002
    attitude_noise_rad: float = 0.002
    gps_noise_m: float = 1.0
    baro_noise_pa: float = 2.0
    motor_timeout_s: float = 0.5
    gps_dropout_s: tuple[float, ...] = ()
    gps_glitch_s: tuple[float, ...] = ()
    gps_glitch_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    record_path: str = ""
    record_fps: float = 30.0
    record_camera: str = "uav/chase"
    lockstep: bool = True
    lockstep_participants: tuple[str, ...] = ()
    lockstep_timeout_s: float = 10.0

    def __post_init__(self) -> None:
        if not self.rtf >= 0.0:
            raise ValueError(f"rtf must be >= 0 (0 = as fast as possible), got {self.rtf}")
        for name in (
            "clock_rate_hz",
            "imu_rate_hz",
            "gps_rate_hz",
            "baro_rate_hz",
            "mocap_rate_hz",
            "truth_rate_hz",
            "motor_timeout_s",
            "record_fps",
            "lockstep_timeout_s",
        ):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        ratio = self.imu_rate_hz / self.clock_rate_hz
        if abs(ratio - round(ratio)) > 1e-9 or ratio < 1:
            raise ValueError(f"imu_rate_hz ({self.imu_rate_hz}) must be a multiple of clock_rate_hz")
        if not (0.0 <= self.gps_delay_s <= 0.4):
            raise ValueError(f"gps_delay_s must be in [0, 0.4] s, got {self.gps_delay_s}")
        if not (-90.0 <= self.origin_lat_deg <= 90.0 and -180.0 <= self.origin_lon_deg <= 180.0):
            raise ValueError("origin_lat_deg / origin_lon_deg out of range")
        for name in ("gps_dropout_s", "gps_glitch_s"):
            w = getattr(self, name)
            if len(w) % 2 or not all(math.isfinite(t) for t in w) or any(a >= b for a, b in _pairs(w)):
                raise ValueError(f"{name} must be pairs [start, end, ...] of finite times with start < end, got {w}")
        if not all(math.isfinite(v) for v in self.gps_glitch_m):
            raise ValueError(f"gps_glitch_m must be finite, got {self.gps_glitch_m}")


def in_windows(t_s: float, windows: tuple[float, ...]) -> bool:
    """Whether sim time ``t_s`` lies in one of the half-open windows ``[start, end, start, end, ...]``."""
    return any(a <= t_s < b for a, b in _pairs(windows))


def _pairs(windows: tuple[float, ...]) -> list[tuple[float, float]]:
    return list(zip(windows[0::2], windows[1::2], strict=False))


class UavBridge:
    """Steps a :class:`~mjnav.sim.uav.UavSimulator` tick by tick and connects it to the bus.

    It is the :class:`~mjnav.services.sim.SimStepping` that :class:`~mjnav.services.sim.SimService`'s stepping loop
    drives.
    """

    def __init__(self, sim: Any, bus: Any, config: UavSimConfig, recorder: Any = None) -> None:
        self.sim = sim
        self.config = config
        self.recorder = recorder
        self._bus = bus
        self._lock = threading.Lock()
        self._command: Any = None  # the newest acceptable rotor_cmd not yet applied
        self._command_stamp_s = -math.inf
        self.commands_refused = 0
        self._pub = {
            name: bus.publisher(name) for name in ("imu", "gps", "baro", "mocap", "ground_truth", "sim_status")
        }
        self._clock = Schedule.every(config.clock_rate_hz)
        self._gps = Schedule.every(config.gps_rate_hz)
        self._baro = Schedule.every(config.baro_rate_hz)
        self._mocap = Schedule.every(config.mocap_rate_hz)
        self._truth = Schedule.every(config.truth_rate_hz)
        self._status = Schedule.every(SIM_STATUS_RATE_HZ)
        self._frame = Schedule.every(config.record_fps)
        self._sim_status = msg_class("mjnav_msgs/msg/SimStatus")
        self._fixes: deque[tuple[float, Any]] = deque()  # (publish at, NavSatFix)
        self._outbox: list[tuple[Any, Any]] = []  # (publisher, message) of the clock period under way
        self.tick_s = 1.0 / config.imu_rate_hz
        self.steps_per_tick = round(self.tick_s / sim.timestep_s)
        if abs(self.steps_per_tick * sim.timestep_s - self.tick_s) > 1e-9 or self.steps_per_tick < 1:
            raise ValueError(
                f"the IMU period {self.tick_s} s must be a multiple of the physics step {sim.timestep_s} s"
            )
        self._ticks = 0
        self.command_topics: tuple[str, ...] = ("rotor_cmd",)
        self._clock_out = ClockOut(bus)
        self._last_cmd_t = -math.inf
        self.watchdog_tripped = False
        self.wall0 = time.monotonic()
        #: The sim's lockstep barrier (None: free-running), whose waiting time ``sim_status`` reports.
        self.barrier: LockstepBarrier | None = None
        self._started = False
        bus.subscribe("rotor_cmd", callback=self._on_command)

    @property
    def time_s(self) -> float:
        """Sim time now, s."""
        return float(self.sim.time_s)

    @property
    def clock_period_s(self) -> float:
        """Sim seconds between two ``clock`` messages."""
        return self._clock.period_s

    def free_until_s(self, clock_s: float) -> float:
        """The rotors take a new command at every IMU tick, the clock's included: no step without it."""
        return clock_s

    def release_clock(self) -> None:
        """Publish the clock the last :meth:`advance` held."""
        self._clock_out.release()

    def advance(self, target_s: float, deadline: float | None = None, *, hold_clock: bool = False) -> None:
        """Step to sim time ``target_s`` (whole IMU ticks), publishing what falls due; stop early at the
        ``time.perf_counter`` ``deadline``; ``hold_clock``: keep a clock due there for :meth:`release_clock`.

        The messages of a clock period go out together, in their order, when its clock is due (and at the end):
        one burst per lockstep round costs Zenoh a fraction of the wake-ups of messages spread over the physics
        steps, and subscribers see nothing of a period before its clock anyway.
        """
        self._clock_out.hold = hold_clock
        try:
            if not self._started:
                self._started = True
                self._publish_due(0.0)
            while (self._ticks + 1) * self.tick_s <= target_s + 1e-9:
                if deadline is not None and time.perf_counter() >= deadline:
                    return
                t = self._ticks * self.tick_s
                self._apply_command(t)
                self.sim.step(self.steps_per_tick)
                self._ticks += 1
                self._publish_due(self._ticks * self.tick_s)
        finally:
            self._clock_out.hold = False
            self._flush()

    def _put(self, name: str, msg: Any) -> None:
        """Queue ``msg`` for topic ``name`` until the next :meth:`_flush`."""
        self._outbox.append((self._pub[name], msg))

    def _flush(self) -> None:
        outbox, self._outbox = self._outbox, []
        for pub, msg in outbox:
            pub.put(msg)

    def _on_command(self, cmd: Any) -> None:
        stamp = ros.seconds(cmd.header.stamp)
        with self._lock:
            if len(cmd.velocity) == 4 and self._command_stamp_s <= stamp <= self._ticks * self.tick_s + 1e-6:
                self._command, self._command_stamp_s = cmd, stamp
                return
            self.commands_refused += 1
            refused = self.commands_refused
        if refused & (refused - 1) == 0:  # 1, 2, 4, 8, …
            log.warning(
                "rotor_cmd refused (%d so far): %d speeds stamped %.3f s, the last taken %.3f s, sim time %.3f s",
                refused,
                len(cmd.velocity),
                stamp,
                self._command_stamp_s,
                self._ticks * self.tick_s,
            )

    def _apply_command(self, t: float) -> None:
        with self._lock:
            cmd, self._command = self._command, None
        if cmd is not None:
            self.sim.set_rotor_speeds(cmd.velocity)
            self._last_cmd_t = t
            self.watchdog_tripped = False
        elif t - self._last_cmd_t > self.config.motor_timeout_s and self.sim.rotor_speed_cmd.any():
            self.sim.set_rotor_speeds([0.0] * 4)
            self.watchdog_tripped = True

    def _publish_due(self, t: float) -> None:
        sim, cfg = self.sim, self.config
        imu = sim.imu()
        self._put(
            "imu",
            ros.imu(
                t,
                "imu",
                imu.orientation_xyzw,
                imu.angular_velocity_radps,
                imu.specific_force_mps2,
                gyro_variance=cfg.gyro_noise_radps**2,
                accel_variance=cfg.accel_noise_mps2**2,
            ),
        )
        truth = None
        if self._mocap.due(t):
            truth = sim.truth()
            self._put(
                "mocap",
                uav_msgs.odometry3d(
                    t,
                    "map",
                    "base_link",
                    truth.position_m,
                    truth.quat_wxyz,
                    truth.velocity_mps,
                    truth.angular_velocity_radps,
                ),
            )
        if self._truth.due(t):
            truth = truth or sim.truth()
            self._put("ground_truth", uav_msgs.pose_stamped3d(t, "map", truth.position_m, truth.quat_wxyz))
        if self._gps.due(t):
            lat, lon, alt = sim.gps_fix()  # drawn even in a dropout: the noise that follows stays the same
            if in_windows(t, cfg.gps_glitch_s):
                from mjnav.aerial import enu_to_geodetic, geodetic_to_enu

                o = sim.origin
                e, n, u = np.add(geodetic_to_enu(lat, lon, alt, o.lat_deg, o.lon_deg, o.alt_m), cfg.gps_glitch_m)
                lat, lon, alt = (float(v) for v in enu_to_geodetic(e, n, u, o.lat_deg, o.lon_deg, o.alt_m))
            if not in_windows(t, cfg.gps_dropout_s):
                self._fixes.append((t + cfg.gps_delay_s, uav_msgs.nav_sat_fix(t, lat, lon, alt, cfg.gps_noise_m)))
        while self._fixes and self._fixes[0][0] <= t + 1e-9:
            self._put("gps", self._fixes.popleft()[1])
        if self._baro.due(t):
            self._put("baro", uav_msgs.fluid_pressure(t, sim.baro_pa(), cfg.baro_noise_pa**2))
        if self._status.due(t):
            wall = time.monotonic() - self.wall0
            self._put(
                "sim_status",
                self._sim_status(
                    header=ros.header(t, "map"),
                    world=sim.path.stem,
                    collisions=sim.collisions,
                    real_time_factor=t / wall if wall > 0 else 0.0,
                    watchdog_tripped=self.watchdog_tripped,
                    lockstep_wait_s=self.barrier.waited_s if self.barrier is not None else 0.0,
                ),
            )
        if self.recorder is not None and self._frame.due(t):
            self.recorder.capture()
        # The clock goes last: a service that sees clock t has received every message stamped up to t.
        if self._clock.due(t):
            self._flush()
            self._clock_out.due(t)


class UavSimService(SimService):
    """The quadrotor at ``rtf`` × wall time, in lockstep with the UAV services: the ground sim's stepping loop
    (:class:`~mjnav.services.sim.SimService`) driving a :class:`UavBridge`."""

    name = "uav_sim"
    config_class = UavSimConfig  # type: ignore[assignment]
    uses_sim_time = False

    def configure(self) -> None:
        from mjnav.sim import Recorder
        from mjnav.sim.uav import GeodeticOrigin, UavNoise, UavSimulator

        cfg: Any = self.config
        noise = UavNoise(
            accel_mps2=cfg.accel_noise_mps2,
            accel_bias_mps2=cfg.accel_bias_mps2,
            gyro_radps=cfg.gyro_noise_radps,
            attitude_rad=cfg.attitude_noise_rad,
            gps_m=cfg.gps_noise_m,
            baro_pa=cfg.baro_noise_pa,
        )
        self.sim: Any = UavSimulator(
            cfg.world,
            seed=cfg.seed,
            wind_mps=cfg.wind_mps,
            gust_mps=cfg.gust_mps,
            drag_area_m2=cfg.drag_area_m2,
            noise=noise,
            origin=GeodeticOrigin(cfg.origin_lat_deg, cfg.origin_lon_deg, cfg.origin_alt_m),
        )
        self.recorder: Any = None
        if cfg.record_path:
            self.recorder = Recorder(
                self.sim.model,
                self.sim.data,
                Path(cfg.record_path),
                fps=cfg.record_fps,
                camera=cfg.record_camera,
                track_body=self.sim.body_id,
            )
        self.bridge = UavBridge(self.sim, self.bus, cfg, self.recorder)
        # Where the world is on Earth: the GPS fixes' reference, latched for the INS (a world fact, on the bus).
        self.datum = self.bus.publisher("datum")
        self.datum.put(uav_msgs.nav_sat_fix(0.0, cfg.origin_lat_deg, cfg.origin_lon_deg, cfg.origin_alt_m, 0.0))
        self.barrier = self.bridge.barrier = (
            LockstepBarrier(self.bus, cfg.lockstep_participants, cfg.lockstep_timeout_s, self.log)
            if cfg.lockstep
            else None
        )
        self.log.info(
            "world %s, wind %.1f m/s, gusts %.1f m/s, rtf %s, %s",
            cfg.world,
            cfg.wind_mps,
            cfg.gust_mps,
            cfg.rtf or "max",
            f"lockstep with {', '.join(cfg.lockstep_participants) or 'whoever joins'}"
            if cfg.lockstep
            else "free-running",
        )
        if cfg.gps_dropout_s or cfg.gps_glitch_s:
            self.log.warning(
                "GPS faults injected: no fix in %s s, fixes off by %s m (ENU) in %s s",
                list(cfg.gps_dropout_s),
                list(cfg.gps_glitch_m),
                list(cfg.gps_glitch_s),
            )

    def deactivate(self) -> None:
        self.sim.set_rotor_speeds([0.0] * 4)
        if self.recorder is not None:
            self.recorder.close()
            self.log.info("wrote %d frames to %s", self.recorder.frames, self.config.record_path)
        self.log.info("stopped at sim time %.2f s with %d collision(s)", self.sim.time_s, self.sim.collisions)

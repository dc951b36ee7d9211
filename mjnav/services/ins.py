"""The INS service: GPS/INS fusion (:class:`~mjnav.aerial.GpsIns`) from ``imu`` and ``gps`` to ``ins_odom``.

Every IMU sample (body FLU specific force, AHRS attitude in ENU) is turned into a kinematic acceleration in NED —
``a = R_nb f_frd + g ẑ``, the REP-103 → NED conversion done here, explicitly — and drives one prediction; every
GPS fix (WGS84, stamped when taken) is converted to NED about the map frame's geodetic origin and fused at its stamp
(the filter replays the IMU samples since). The filter starts at the first fix. What the INS knows of the world and
the vehicle comes from the sim over the bus: the origin from ``datum`` (latched), the IMU's period from the stamps
of its samples (as PX4's EKF2 takes its time steps from the IMU's timestamps). Each step publishes the estimate
stamped with the time of the newest IMU sample: position, velocity (in the odometry frame) and covariance, the
AHRS attitude and the body rates, in ENU / FLU (``frame = "enu"``, frames ``map`` → ``base_link``, REP-103) or in
NED / FRD (``frame = "ned"``, ``map_ned`` → ``base_link_frd``).

The barometer is not fused (the filter's measurement is GPS position only).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from mjnav.msgs import ros
from mjnav.msgs import uav as uav_msgs
from mjnav.runtime import Service


@dataclass(frozen=True)
class InsConfig:
    """INS settings (``services/ins.toml``).

    Attributes:
        rate_hz: publishing rate (steps per sim second; the clock's rate or a divisor of it). The filter predicts at
            every IMU sample whatever the rate; a step handles the samples since the last one. A fix is fused at the
            first step after it arrives: at 10 Hz (the GPS rate, one lockstep round in five) the corrections reach
            the flight controller 40 ms later than at 25 Hz, which costs a flight on the INS about 5 cm RMS and
            20 cm of maximum error (seed 0).
        accel_noise_mps2, accel_bias_walk_mps2_per_sqrt_s, gps_sigma_m: the filter's noise model.
        history_s: how late a GPS fix may arrive, s.
        frame: ``enu`` (REP-103) or ``ned`` for the published odometry.
        gravity_mps2: gravity removed from the specific force, m/s².
    """

    rate_hz: float = 25.0
    accel_noise_mps2: float = 0.02
    accel_bias_walk_mps2_per_sqrt_s: float = 1e-3
    gps_sigma_m: float = 1.0
    history_s: float = 0.5
    frame: str = "enu"
    gravity_mps2: float = 9.80665

    def __post_init__(self) -> None:
        if self.frame not in ("enu", "ned"):
            raise ValueError(f"frame must be 'enu' or 'ned', got {self.frame!r}")
        for name in ("gps_sigma_m", "history_s", "accel_noise_mps2", "gravity_mps2"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")


class InsService(Service[InsConfig]):
    """GPS/INS on the bus."""

    name = "ins"
    config_class = InsConfig

    def configure(self) -> None:
        from mjnav.aerial import GpsIns, GpsInsConfig

        cfg = self.config
        self._filter_config = GpsInsConfig(
            accel_noise_mps2=cfg.accel_noise_mps2,
            accel_bias_walk_mps2_per_sqrt_s=cfg.accel_bias_walk_mps2_per_sqrt_s,
            gps_sigma_m=cfg.gps_sigma_m,
            history_s=cfg.history_s,
            init_pos_sigma_m=cfg.gps_sigma_m,
        )
        self._make_filter = GpsIns
        self._lock = threading.Lock()
        self._imu: list[Any] = []
        self._fixes: list[Any] = []
        self._datum: tuple[float, float, float] | None = None
        self.datum_sub = self.bus.subscribe("datum", callback=self._on_datum, immediate=True)
        self.bus.subscribe("imu", callback=self._on_imu)
        self.bus.subscribe("gps", callback=self._on_gps)
        self.pub = self.bus.publisher("ins_odom")
        # warm the compiled kernels now, not at the first fix
        warm = GpsIns(self._filter_config)
        warm.predict(np.zeros(3))
        warm.update_gps(np.zeros(3))
        from mjnav.aerial import geodetic_to_ned
        from mjnav.aerial.rep103 import kinematic_accel_ned, quat_enu_flu_to_ned_frd

        quat_enu_flu_to_ned_frd([1.0, 0.0, 0.0, 0.0])
        kinematic_accel_ned([[1.0, 0.0, 0.0, 0.0]], [[0.0, 0.0, cfg.gravity_mps2]], cfg.gravity_mps2)
        geodetic_to_ned(47.0, 8.0, 400.0, 47.0, 8.0, 400.0)

    def _on_datum(self, msg: Any) -> None:
        self._datum = (float(msg.latitude), float(msg.longitude), float(msg.altitude))

    def starting(self) -> str:
        return "" if self._datum is not None else f"the map frame's geodetic origin on {self.datum_sub.key}"

    def activate(self) -> None:
        self.ins: Any = None
        self.last_imu: tuple[float, np.ndarray, np.ndarray] | None = None  # (stamp, quat NED/FRD, rates FRD)
        self.imu_period_s = math.nan  # from the stamps of two consecutive samples
        self.fixes_fused = 0
        self.fixes_rejected = 0
        with self._lock:
            self._imu.clear()
            self._fixes.clear()

    def _on_imu(self, msg: Any) -> None:
        with self._lock:
            self._imu.append(msg)

    def _on_gps(self, msg: Any) -> None:
        with self._lock:
            self._fixes.append(msg)

    def step(self, now: float) -> None:
        from mjnav.aerial import StaleMeasurementError, geodetic_to_ned
        from mjnav.aerial.rep103 import flu_to_frd, kinematic_accel_ned, quat_enu_flu_to_ned_frd

        cfg = self.config
        with self._lock:
            samples, self._imu = self._imu, []
            fixes, self._fixes = self._fixes, []
        if samples and math.isnan(self.imu_period_s):
            stamps = [ros.seconds(m.header.stamp) for m in samples]
            if self.last_imu is not None:
                stamps.insert(0, self.last_imu[0])
            if len(stamps) >= 2 and stamps[1] > stamps[0]:
                self.imu_period_s = round(stamps[1] - stamps[0], 9)  # the sim's stamps are whole physics steps
                self.log.info("IMU at %.1f Hz (from its stamps)", 1.0 / self.imu_period_s)
        if samples:
            last = samples[-1]
            o, w = last.orientation, last.angular_velocity
            self.last_imu = (
                ros.seconds(last.header.stamp),
                quat_enu_flu_to_ned_frd([o.w, o.x, o.y, o.z]),
                flu_to_frd([w.x, w.y, w.z]),
            )
        if self.ins is None:
            # the filter starts at the first fix, at the time of the first IMU sample that comes with or after it;
            # the next sample propagates it
            if not fixes or not samples or math.isnan(self.imu_period_s):
                return
            fix, first = fixes[0], samples[0]
            x0 = np.zeros(9)
            x0[0:3] = geodetic_to_ned(fix.latitude, fix.longitude, fix.altitude, *self._origin())
            config = replace(self._filter_config, imu_rate_hz=1.0 / self.imu_period_s)
            self.ins = self._make_filter(config, x0=x0, t0_s=ros.seconds(first.header.stamp))
            fixes, samples = fixes[1:], samples[1:]
        if samples:
            # REP-103 (ENU attitude, FLU force) → NED kinematic acceleration, explicitly, for every sample at once
            quats = [(m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z) for m in samples]
            forces = [(m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z) for m in samples]
            for acc in kinematic_accel_ned(quats, forces, cfg.gravity_mps2):
                self.ins.predict(acc)
        for fix in fixes:
            y = np.array(geodetic_to_ned(fix.latitude, fix.longitude, fix.altitude, *self._origin()), dtype=np.float64)
            try:
                self.ins.update_gps(y, stamp_s=ros.seconds(fix.header.stamp))
                self.fixes_fused += 1
            except StaleMeasurementError as exc:
                self.fixes_rejected += 1
                self.log.warning("GPS fix dropped: %s", exc)
        self._publish()

    def _origin(self) -> tuple[float, float, float]:
        assert self._datum is not None  # starting() waited for it
        return self._datum

    def _publish(self) -> None:
        from mjnav.aerial.rep103 import flu_to_frd, ned_to_enu, quat_ned_frd_to_enu_flu

        assert self.ins is not None and self.last_imu is not None
        stamp, q_ned, rates_frd = self.last_imu
        x, cov = self.ins.x, self.ins.P
        if self.config.frame == "ned":
            msg = uav_msgs.odometry3d(
                stamp,
                "map_ned",
                "base_link_frd",
                x[0:3],
                q_ned,
                x[3:6],
                rates_frd,
                position_variance_m2=cov[0:3, 0:3],
                velocity_variance=cov[3:6, 3:6],
            )
        else:
            swap = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # NED <-> ENU
            msg = uav_msgs.odometry3d(
                stamp,
                "map",
                "base_link",
                ned_to_enu(x[0:3]),
                quat_ned_frd_to_enu_flu(q_ned),
                ned_to_enu(x[3:6]),
                flu_to_frd(rates_frd),
                position_variance_m2=swap @ cov[0:3, 0:3] @ swap.T,
                velocity_variance=swap @ cov[3:6, 3:6] @ swap.T,
            )
        self.pub.put(msg)

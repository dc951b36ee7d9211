"""The INS service: GPS/baro/INS fusion (:class:`~mjnav.aerial.GpsIns`) from ``imu``, ``gps`` and ``baro`` to
``ins_odom`` and ``ins_health``.

Every IMU sample (body FLU specific force, AHRS attitude in ENU) passes the plausibility checks of
:class:`~mjnav.aerial.imu_check.ImuCheck` (finite, within the sensor's range, a unit attitude, stamped on the IMU's
period after the last accepted sample, gravity along the attitude's vertical at rest; the rejections are counted),
is turned into a kinematic acceleration in NED — ``a = R_nb f_frd + g ẑ``, the REP-103 → NED conversion done here,
explicitly — and drives one prediction (one per IMU period across a gap of up to ``imu_max_gap_s``). Every GPS fix
(WGS84, stamped when taken) is converted to NED about the map frame's geodetic origin and every barometer reading to
an altitude above it (ISA), and each is gated and fused at its stamp (the filter replays the IMU samples since): a
measurement that fails its χ² gate is counted and dropped, and after ``reset_timeout_s`` without one passing the
filter resets to the next. The filter starts at the first fix (the baro offset from the newest reading then). What
the INS knows of the world and the vehicle comes from the sim over the bus: the origin from ``datum`` (latched), the
IMU's period from the stamps of its samples (as PX4's EKF2 takes its time steps from the IMU's timestamps). A step
handles what is stamped up to its time (later samples wait for a later step), in stamp order.

Each step publishes the estimate stamped with the time of the newest IMU sample: position, velocity (in the
odometry frame) and covariance, the AHRS attitude and the body rates, in ENU / FLU (``frame = "enu"``, frames
``map`` → ``base_link``, REP-103) or in NED / FRD (``frame = "ned"``, ``map_ned`` → ``base_link_frd``); and its
health on ``ins_health`` (``diagnostic_msgs/DiagnosticArray``, same stamp): ERROR when no fix was fused for
``gps_timeout_s`` (the horizontal position is dead reckoning: the flight controller's position-loss failsafe acts on
it, as PX4's EKF2 flags its position invalid after its no-aiding timeout), WARN when the barometer was not fused for
as long (the altitude is on GPS alone), OK otherwise; the values count what was fused, rejected, reset and dropped.
It goes out ``health_rate_hz`` times per sim second and at once when its level changes.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from mjnav.msgs import msg_class, ros
from mjnav.msgs import uav as uav_msgs
from mjnav.runtime import Service

#: ``ins_health`` levels (diagnostic_msgs/DiagnosticStatus).
OK, WARN, ERROR = 0, 1, 2


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
        baro_sigma_m, baro_offset_walk_m_per_sqrt_s: the barometric altitude's noise and its offset's random walk.
        gps_gate_nis, baro_gate_nis: χ² gates on the normalised innovation squared (see
            :class:`~mjnav.aerial.GpsInsConfig`).
        reset_timeout_s: reset to the next measurement after this long without one of its kind passing the gate, s.
        gps_timeout_s: no fix fused for this long (sim s): the horizontal position is lost (``ins_health`` ERROR).
        health_rate_hz: ``ins_health`` messages per sim second; a change of level goes out at once.
        history_s: how late a GPS fix may arrive, s.
        frame: ``enu`` (REP-103) or ``ned`` for the published odometry.
        gravity_mps2: gravity removed from the specific force, m/s².
        imu_accel_range_mps2, imu_gyro_range_radps: the IMU's range; samples beyond it are rejected.
        imu_max_gap_s: the longest gap between two IMU samples the filter bridges (holding the newer sample), s.
        imu_rest_tilt_tol_rad: at rest, the largest angle between the specific force and the attitude's vertical.
    """

    rate_hz: float = 25.0
    accel_noise_mps2: float = 0.02
    accel_bias_walk_mps2_per_sqrt_s: float = 1e-3
    gps_sigma_m: float = 1.0
    baro_sigma_m: float = 0.2
    baro_offset_walk_m_per_sqrt_s: float = 0.005
    gps_gate_nis: float = 25.0
    baro_gate_nis: float = 25.0
    reset_timeout_s: float = 5.0
    gps_timeout_s: float = 1.0
    health_rate_hz: float = 5.0
    history_s: float = 0.5
    frame: str = "enu"
    gravity_mps2: float = 9.80665
    imu_accel_range_mps2: float = 16.0 * 9.80665
    imu_gyro_range_radps: float = math.radians(2000.0)
    imu_max_gap_s: float = 0.1
    imu_rest_tilt_tol_rad: float = 0.5

    def __post_init__(self) -> None:
        if self.frame not in ("enu", "ned"):
            raise ValueError(f"frame must be 'enu' or 'ned', got {self.frame!r}")
        for name in (
            "gps_sigma_m",
            "baro_sigma_m",
            "history_s",
            "accel_noise_mps2",
            "gravity_mps2",
            "gps_gate_nis",
            "baro_gate_nis",
            "reset_timeout_s",
            "gps_timeout_s",
            "health_rate_hz",
            "imu_accel_range_mps2",
            "imu_gyro_range_radps",
            "imu_max_gap_s",
            "imu_rest_tilt_tol_rad",
        ):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")


def _stamp(msg: Any) -> float:
    return ros.seconds(msg.header.stamp)


def due(queue: list[Any], incoming: list[Any], now: float) -> tuple[list[Any], list[Any]]:
    """(messages stamped up to ``now`` in stamp order — arrival order among equal stamps —, the later ones) of what
    was kept back and what arrived."""
    pending = sorted(queue + incoming, key=_stamp) if queue or incoming else []
    cut = next((i for i, m in enumerate(pending) if _stamp(m) > now + 1e-9), len(pending))
    return pending[:cut], pending[cut:]


class ImuIntake:
    """The IMU samples of a UAV service, checked (:class:`~mjnav.aerial.imu_check.ImuCheck`) in stamp order at each
    step: the INS and the flight controller.

    Args:
        check: the checker (its config: the sensor's limits).
        log: where rejections are logged (the first of each reason, then at 10, 100, … of it).
        key: the topic's key, for the log.
    """

    def __init__(self, check: Any, log: Any, key: str) -> None:
        self.check = check
        self._log = log
        self._key = key
        self._lock = threading.Lock()
        self._incoming: list[Any] = []
        self._later: list[Any] = []  # stamped after the last step's time: for a later step

    def add(self, msg: Any) -> None:
        """A subscription callback: keep ``msg`` for the next :meth:`take`."""
        with self._lock:
            self._incoming.append(msg)

    def reset(self, check: Any) -> None:
        """Forget what is kept and start over with ``check``."""
        with self._lock:
            self._incoming.clear()
        self._later.clear()
        self.check = check

    def take(self, now: float) -> tuple[list[Any], np.ndarray]:
        """The accepted samples stamped up to ``now`` that arrived since the last call (in stamp order) and, for
        each, the IMU periods since the accepted sample before it (1, or more across a gap)."""
        with self._lock:
            incoming, self._incoming = self._incoming, []
        ready, self._later = due(self._later, incoming, now)
        if not ready:
            return [], np.zeros(0, dtype=np.int64)
        rows = np.array([_imu_row(m) for m in ready])  # (N, 11): stamp, attitude (w, x, y, z), rates, force
        before = dict(self.check.rejected)
        periods = self.check.check(rows[:, 0], rows[:, 1:5], rows[:, 5:8], rows[:, 8:11])
        if len(ready) > int(np.count_nonzero(periods)):
            for reason, n in self.check.rejected.items():
                if n > before[reason] and _crossed_power_of_ten(before[reason], n):
                    self._log.warning("IMU sample on %s rejected (%s): %d so far", self._key, reason, n)
        keep = periods > 0
        return [m for m, k in zip(ready, keep, strict=True) if k], periods[keep]


def _imu_row(m: Any) -> tuple[float, ...]:
    """A sensor_msgs/Imu as (stamp s, attitude w, x, y, z, rates x, y, z rad/s, specific force x, y, z m/s²)."""
    st, q, w, a = m.header.stamp, m.orientation, m.angular_velocity, m.linear_acceleration
    return (ros.seconds(st), q.w, q.x, q.y, q.z, w.x, w.y, w.z, a.x, a.y, a.z)


def _crossed_power_of_ten(before: int, after: int) -> bool:
    """Whether a count went from ``before`` to ``after`` through 1, 10, 100, …"""
    return before == 0 or int(math.log10(after)) > int(math.log10(before))


class InsService(Service[InsConfig]):
    """GPS/baro/INS on the bus."""

    name = "ins"
    config_class = InsConfig

    def configure(self) -> None:
        from mjnav.aerial import GpsIns, GpsInsConfig

        cfg = self.config
        self._filter_config = GpsInsConfig(
            accel_noise_mps2=cfg.accel_noise_mps2,
            accel_bias_walk_mps2_per_sqrt_s=cfg.accel_bias_walk_mps2_per_sqrt_s,
            gps_sigma_m=cfg.gps_sigma_m,
            baro_sigma_m=cfg.baro_sigma_m,
            baro_offset_walk_m_per_sqrt_s=cfg.baro_offset_walk_m_per_sqrt_s,
            history_s=cfg.history_s,
            init_pos_sigma_m=cfg.gps_sigma_m,
            gps_gate_nis=cfg.gps_gate_nis,
            baro_gate_nis=cfg.baro_gate_nis,
            reset_timeout_s=cfg.reset_timeout_s,
        )
        self._make_filter = GpsIns
        self._lock = threading.Lock()
        self._fixes: list[Any] = []
        self._baros: list[Any] = []
        self._datum: tuple[float, float, float] | None = None
        self.datum_sub = self.bus.subscribe("datum", callback=self._on_datum, immediate=True)
        self.imu = ImuIntake(self._new_check(), self.log, self.bus.key("imu"))
        self.bus.subscribe("imu", callback=self.imu.add)
        self.bus.subscribe("gps", callback=self._keep("_fixes"))
        self.bus.subscribe("baro", callback=self._keep("_baros"))
        self.pub = self.bus.publisher("ins_odom")
        self.health_pub = self.bus.publisher("ins_health")
        self._diagnostic_array = msg_class("diagnostic_msgs/msg/DiagnosticArray")
        # warm the compiled kernels now, not at the first fix
        warm = GpsIns(self._filter_config)
        warm.predict(np.zeros(3))
        warm.update_gps(np.zeros(3))
        warm.update_baro(0.0)
        self._new_check().check([0.0], [(1.0, 0.0, 0.0, 0.0)], [(0.0, 0.0, 0.0)], [(0.0, 0.0, cfg.gravity_mps2)])
        from mjnav.aerial import geodetic_to_ned
        from mjnav.aerial.rep103 import kinematic_accel_ned, quat_enu_flu_to_ned_frd

        quat_enu_flu_to_ned_frd([1.0, 0.0, 0.0, 0.0])
        kinematic_accel_ned([[1.0, 0.0, 0.0, 0.0]], [[0.0, 0.0, cfg.gravity_mps2]], cfg.gravity_mps2)
        geodetic_to_ned(47.0, 8.0, 400.0, 47.0, 8.0, 400.0)

    def _new_check(self) -> Any:
        from mjnav.aerial.imu_check import ImuCheck, ImuCheckConfig

        cfg = self.config
        return ImuCheck(
            ImuCheckConfig(
                accel_range_mps2=cfg.imu_accel_range_mps2,
                gyro_range_radps=cfg.imu_gyro_range_radps,
                max_gap_s=cfg.imu_max_gap_s,
                rest_tilt_tol_rad=cfg.imu_rest_tilt_tol_rad,
                gravity_mps2=cfg.gravity_mps2,
            )
        )

    def _on_datum(self, msg: Any) -> None:
        self._datum = (float(msg.latitude), float(msg.longitude), float(msg.altitude))

    def _keep(self, attribute: str) -> Any:
        """A callback that appends a message to the list ``self.<attribute>`` (which :meth:`step` swaps out)."""

        def keep(msg: Any) -> None:
            with self._lock:
                getattr(self, attribute).append(msg)

        return keep

    def starting(self) -> str:
        return "" if self._datum is not None else f"the map frame's geodetic origin on {self.datum_sub.key}"

    def activate(self) -> None:
        self.ins: Any = None
        self.imu.reset(self._new_check())
        self.last_imu: tuple[float, np.ndarray, np.ndarray] | None = None  # (stamp, quat NED/FRD, rates FRD)
        self._later_fixes: list[Any] = []
        self._later_baros: list[Any] = []
        self._baro_altitude_m: float | None = None  # the newest reading, for the baro offset at the start
        self.dropped = {"gps": 0, "baro": 0}  # measurements the filter could not take (stale, no fix, bad)
        self._level = OK
        self._health_stamp = -math.inf  # of the last ins_health sent
        with self._lock:
            self._fixes.clear()
            self._baros.clear()

    @property
    def imu_period_s(self) -> float:
        """The IMU's period read from the stamps of its first two samples (NaN before), s."""
        return float(self.imu.check.learnt_period_s)

    def step(self, now: float) -> None:
        from mjnav.aerial.rep103 import flu_to_frd, kinematic_accel_ned, quat_enu_flu_to_ned_frd

        cfg = self.config
        with self._lock:
            incoming_fixes, self._fixes = self._fixes, []
            incoming_baros, self._baros = self._baros, []
        samples, periods = self.imu.take(now)
        fixes, self._later_fixes = due(self._later_fixes, incoming_fixes, now)
        baros, self._later_baros = due(self._later_baros, incoming_baros, now)
        if samples:
            last = samples[-1]
            o, w = last.orientation, last.angular_velocity
            self.last_imu = (_stamp(last), quat_enu_flu_to_ned_frd([o.w, o.x, o.y, o.z]), flu_to_frd([w.x, w.y, w.z]))
        if baros and self.ins is None:
            self._baro_altitude_m = self._baro_altitude(baros[-1])
        if self.ins is None:
            # the filter starts at the first fix, at the time of the first IMU sample that comes with or after it;
            # the next sample propagates it
            fixes = [f for f in fixes if self._has_fix(f)]
            if not fixes or not samples or math.isnan(self.imu_period_s):
                return
            self._start(fixes[0], samples[0])
            fixes, samples, periods = fixes[1:], samples[1:], periods[1:]
        if samples:
            # REP-103 (ENU attitude, FLU force) → NED kinematic acceleration, explicitly, for every sample at once
            quats = [(m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z) for m in samples]
            forces = [(m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z) for m in samples]
            for acc, k in zip(kinematic_accel_ned(quats, forces, cfg.gravity_mps2), periods, strict=True):
                for _ in range(int(k)):  # across a gap the newer sample stands for the missing ones
                    self.ins.predict(acc)
        for fix in fixes:
            if self._has_fix(fix):
                self._fuse("gps", self._ned(fix), _stamp(fix))
        for baro in baros:
            self._fuse("baro", self._baro_altitude(baro), _stamp(baro))
        self._publish()

    @staticmethod
    def _has_fix(fix: Any) -> bool:
        return int(fix.status.status) >= 0  # sensor_msgs/NavSatStatus: STATUS_NO_FIX = -1

    def _start(self, fix: Any, first: Any) -> None:
        from mjnav.aerial.ins import BARO_OFFSET, N_STATE

        c = self._filter_config
        x0 = np.zeros(N_STATE)
        x0[0:3] = self._ned(fix)
        sig = [c.init_pos_sigma_m] * 3 + [c.init_vel_sigma_mps] * 3 + [c.init_bias_sigma_mps2] * 3
        p0 = np.diag(np.square([*sig, c.init_baro_offset_sigma_m]))
        if self._baro_altitude_m is not None:
            # offset = baro altitude - (-p_d): its error is the fix's vertical error plus the reading's noise
            x0[BARO_OFFSET] = self._baro_altitude_m + x0[2]
            p0[2, BARO_OFFSET] = p0[BARO_OFFSET, 2] = p0[2, 2]
            p0[BARO_OFFSET, BARO_OFFSET] = p0[2, 2] + c.baro_sigma_m**2
        config = replace(c, imu_rate_hz=1.0 / self.imu_period_s)
        self.ins = self._make_filter(config, x0=x0, P0=p0, t0_s=_stamp(first))

    def _fuse(self, kind: str, y: Any, stamp: float) -> None:
        from mjnav.aerial import AerialError

        try:
            fusion = self.ins.update_gps(y, stamp_s=stamp) if kind == "gps" else self.ins.update_baro(y, stamp)
        except AerialError as exc:  # stale, or a second one at the same IMU sample
            self.dropped[kind] += 1
            self.log.warning("%s measurement dropped: %s", kind, exc)
            return
        stats = self.ins.gps if kind == "gps" else self.ins.baro
        if fusion.reset:
            self.log.warning(
                "%s: nothing passed the gate for %.1f s: reset to the measurement at %.2f s (NIS %.0f)",
                kind,
                self.config.reset_timeout_s,
                stamp,
                fusion.nis,
            )
        elif not fusion.fused and _crossed_power_of_ten(stats.rejected - 1, stats.rejected):
            self.log.warning(
                "%s measurement at %.2f s rejected (NIS %.1f): %d so far", kind, stamp, fusion.nis, stats.rejected
            )

    def _ned(self, fix: Any) -> np.ndarray:
        from mjnav.aerial import geodetic_to_ned

        return np.array(geodetic_to_ned(fix.latitude, fix.longitude, fix.altitude, *self._origin()), dtype=np.float64)

    def _baro_altitude(self, msg: Any) -> float:
        """Altitude above the datum (m) of a static pressure reading (ISA)."""
        from mjnav.aerial import isa_altitude_m

        return isa_altitude_m(float(msg.fluid_pressure)) - self._origin()[2]

    def _origin(self) -> tuple[float, float, float]:
        assert self._datum is not None  # starting() waited for it
        return self._datum

    def _health(self, stamp: float) -> Any:
        """``ins_health`` at ``stamp`` (level, reason and counters), or None when neither its period is over nor its
        level changed."""
        ins, cfg, check = self.ins, self.config, self.imu.check
        gps_age, baro_age = ins.t_s - ins.gps.last_fused_s, ins.t_s - ins.baro.last_fused_s
        if gps_age >= cfg.gps_timeout_s:
            level, text = ERROR, f"horizontal position lost: no GPS fix fused for {gps_age:.1f} s"
        elif baro_age >= cfg.gps_timeout_s:
            level, text = WARN, f"altitude on GPS alone: no barometer reading fused for {baro_age:.1f} s"
        else:
            level, text = OK, "GPS and barometer fused"
        changed = level != self._level
        if changed:
            (self.log.warning if level > self._level else self.log.info)("health: %s", text)
            self._level = level
        if not changed and stamp - self._health_stamp < 1.0 / cfg.health_rate_hz - 1e-6:  # stamps: whole ns
            return None
        self._health_stamp = stamp
        values = {
            "gps_age_s": f"{gps_age:.3f}",
            "gps_fused": str(ins.gps.fused),
            "gps_rejected": str(ins.gps.rejected),
            "gps_resets": str(ins.gps.resets),
            "gps_dropped": str(self.dropped["gps"]),
            "gps_nis": f"{ins.gps.last_nis:.2f}",
            "baro_age_s": f"{baro_age:.3f}",
            "baro_fused": str(ins.baro.fused),
            "baro_rejected": str(ins.baro.rejected),
            "baro_resets": str(ins.baro.resets),
            "baro_dropped": str(self.dropped["baro"]),
            "baro_nis": f"{ins.baro.last_nis:.2f}",
            "baro_offset_m": f"{ins.baro_offset:.3f}",
            "imu_accepted": str(check.accepted),
            "imu_rejected": str(sum(check.rejected.values())),
            **{f"imu_rejected_{reason}": str(n) for reason, n in check.rejected.items()},
        }
        status = ros.diagnostic_status(level, "ins", text, values)
        return self._diagnostic_array(header=ros.header(stamp, "map"), status=[status])

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
        # the health first: a subscriber holding this estimate has the health of the same step
        health = self._health(stamp)
        if health is not None:
            self.health_pub.put(health)
        self.pub.put(msg)

"""The flight controller: an onboard task scheduler running the quadrotor cascade, with arming and a failsafe.

Each step (one clock tick) runs one base tick of a :class:`~mjnav.aerial.Scheduler` whose table is the seed's
order — ``EST`` (state from ``mocap`` or the INS + IMU), ``CTL`` (the cascade: position → velocity/acceleration →
attitude → rate → mixer, :class:`~mjnav.aerial.CascadeController`), ``SVO`` (``rotor_cmd``), ``NET`` (setpoints,
arming, the failsafe), ``DLG`` (``flight_state``). The tasks' measured run times are the scheduler's statistics.

* **Controllers** (``controller``): ``pid`` (PX4-style position P + velocity PID), ``rpt`` (Chen's robust and
  perfect tracking outer loop, ε = ``rpt_eps``), ``lqr`` and ``hinf`` (outer loops designed by LQR / H∞ on the
  per-axis double integrator with integral action, :mod:`mjnav.aerial.outer`); all share the attitude and rate
  loops, checked for loop separation.
* **State** (``state_source``): ``mocap`` — the motion-capture odometry (true pose and twist); ``ins`` — position
  and velocity from ``ins_odom`` (its frame id says ENU ``map`` or NED ``map_ned``; extrapolated by its velocity to
  the step's time) with attitude and rates from the newest ``imu``. Everything is converted to NED / FRD here.
* **Setpoints**: ``setpoint`` (``geometry_msgs/PoseStamped``, ENU: hold that position and yaw) or ``trajectory``
  (``nav_msgs/Path`` whose poses are stamped with the sim time they are due: a cubic spline gives position,
  velocity and acceleration feed-forward); the newer of the two wins.
* **Arming**: ``arm`` true arms a landed vehicle (``armed``: idle rotors); the first setpoint then starts
  ``offboard``. ``arm`` false lands (``landing``: descend at ``land_speed_mps`` over the current position) and
  disarms on touchdown, or disarms at once on the ground.
* **Failsafes** (PX4's, latched until the vehicle has landed and disarmed):

  - *offboard proof of life*: in ``offboard``, when no setpoint or trajectory message arrived for
    ``setpoint_timeout_s`` of sim time, the vehicle lands (``failsafe_land``) and disarms on touchdown;
  - *position lost* (``state_source = "ins"``): when the INS's ``ins_health`` says ERROR — no GPS fix fused for its
    ``gps_timeout_s`` — the vehicle holds its altitude (the INS's, barometer-aided) and an attitude that keeps its
    velocity at zero (``failsafe_hold``: the position loop is open, the velocity loop damps the INS's dead-reckoned
    velocity, the horizontal integrators — a trim for the lost position — are cleared) for ``position_loss_hold_s``,
    then descends at ``failsafe_descend_speed_mps`` (``failsafe_descend``, PX4's Descend mode) and disarms on
    touchdown; a landing under way goes straight to ``failsafe_descend``. The drift is the dead-reckoned velocity's
    error integrated (about 1 m in 8 s without wind, seed 1); a level attitude alone drifted 3.6 m there. An INS
    that publishes no ``ins_health`` is trusted;
  - *geofence*: a cylinder about the datum (the ``map`` origin) of radius ``geofence_radius_m`` up to
    ``geofence_max_altitude_m``; leaving it in ``offboard`` returns over the arming position at the current altitude
    (``failsafe_return``, PX4's geofence action Return, at ``return_speed_mps``) and lands there (``failsafe_land``),
    or with ``geofence_action = "land"`` lands where it is. Arming is refused outside the fence and while the
    position is lost.
* **IMU** (``state_source = "ins"``): attitude and rates come from the newest sample that passes the plausibility
  checks of :class:`~mjnav.aerial.imu_check.ImuCheck` (the INS's: :class:`~mjnav.services.ins.ImuIntake`), in
  stamp order up to the step's time — not from whatever arrived last.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from mjnav.msgs import ros
from mjnav.msgs import uav as uav_msgs
from mjnav.runtime import Service

#: Flight states published on ``flight_state``.
STATES = (
    "disarmed",
    "armed",
    "offboard",
    "landing",
    "failsafe_land",
    "failsafe_hold",
    "failsafe_descend",
    "failsafe_return",
)
#: States that steer on the estimated horizontal position (the position-lost failsafe leaves them).
_ON_POSITION = ("offboard", "landing", "failsafe_land", "failsafe_return")
#: States that descend over a point to the ground and disarm there.
_DESCENDING = ("landing", "failsafe_land", "failsafe_descend")
_ROTORS = ("rotor0", "rotor1", "rotor2", "rotor3")
#: Peers' messages kept per topic until a step uses them (a peer steps at most once per clock tick).
_KEEP = 8
#: A peer's message stamped within this of a step's time was made at that step (sim seconds; ticks are 20 ms).
_STAMP_EPS_S = 1e-6


@dataclass(frozen=True)
class FlightControllerConfig:
    """Flight controller settings (``services/flight_controller.toml``).

    Attributes:
        rate_hz: control rate = the scheduler's base tick (the UAV sim's clock rate).
        controller: ``pid``, ``lqr``, ``hinf`` or ``rpt``.
        state_source: ``ins`` (GPS/INS + IMU) or ``mocap`` (motion capture).
        rpt_eps: RPT tuning ε (poles at 1/ε).
        accel_limit_mps2: outer-loop acceleration command limit per axis (rpt, lqr, hinf), m/s².
        pid_separation: ``pid``: bandwidth ratio between nested loops — attitude to velocity to position — from
            which the position P and velocity PI gains follow (:func:`~mjnav.aerial.outer.pid_outer_gains`).
        att_p, rate_p, rate_i, rate_d: attitude P and body-rate PID gains (roll, pitch, yaw).
        setpoint_timeout_s: failsafe after this long without a setpoint in offboard, sim seconds.
        land_speed_mps: descent rate when landing, m/s.
        touchdown_height_m: height above the arming height below which a slow vehicle counts as landed, m.
        idle_speed_rad_s: rotor speed while armed on the ground, rad/s.
        status_rate_hz: ``flight_state`` messages per sim second (and at every change).
        position_loss_hold_s: position lost: hold attitude and altitude this long before descending, sim s.
        failsafe_descend_speed_mps: descent rate without a position, m/s.
        geofence_radius_m: horizontal radius of the fence about the datum, m (0: none).
        geofence_max_altitude_m: the fence's ceiling above the datum, m (0: none).
        geofence_action: ``return`` (over the arming position, then land) or ``land`` (where it is).
        return_speed_mps: mean horizontal speed of the return, m/s.
    """

    rate_hz: float = 50.0
    controller: str = "rpt"
    state_source: str = "mocap"
    rpt_eps: float = 0.25
    accel_limit_mps2: float = 8.0
    pid_separation: float = 4.0
    att_p: tuple[float, float, float] = (20.0, 20.0, 3.0)
    rate_p: tuple[float, float, float] = (60.0, 60.0, 10.0)
    rate_i: tuple[float, float, float] = (5.0, 5.0, 2.0)
    rate_d: tuple[float, float, float] = (0.5, 0.5, 0.0)
    setpoint_timeout_s: float = 0.5
    land_speed_mps: float = 0.5
    touchdown_height_m: float = 0.05
    idle_speed_rad_s: float = 200.0
    status_rate_hz: float = 10.0
    position_loss_hold_s: float = 2.0
    failsafe_descend_speed_mps: float = 0.3
    geofence_radius_m: float = 20.0
    geofence_max_altitude_m: float = 10.0
    geofence_action: str = "return"
    return_speed_mps: float = 1.0

    def __post_init__(self) -> None:
        if self.controller not in ("pid", "lqr", "hinf", "rpt"):
            raise ValueError(f"controller must be pid, lqr, hinf or rpt, got {self.controller!r}")
        if self.state_source not in ("ins", "mocap"):
            raise ValueError(f"state_source must be ins or mocap, got {self.state_source!r}")
        if self.geofence_action not in ("return", "land"):
            raise ValueError(f"geofence_action must be return or land, got {self.geofence_action!r}")
        for name in (
            "rpt_eps",
            "accel_limit_mps2",
            "setpoint_timeout_s",
            "land_speed_mps",
            "status_rate_hz",
            "failsafe_descend_speed_mps",
            "return_speed_mps",
        ):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("position_loss_hold_s", "geofence_radius_m", "geofence_max_altitude_m"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0.0):
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not self.pid_separation > 1.0:
            raise ValueError(f"pid_separation must be > 1, got {self.pid_separation}")


class _Reference:
    """The active reference: a held pose, or a stamped trajectory through a cubic spline (NED)."""

    def __init__(self, t: np.ndarray, pos_ned: np.ndarray, yaw_ned: np.ndarray) -> None:
        from scipy.interpolate import CubicSpline

        self.t0, self.t1 = float(t[0]), float(t[-1])
        self.hold = len(t) < 2
        self.pos = pos_ned
        self.yaw = yaw_ned
        self.t = t
        if not self.hold:
            # (4, N - 1, 3) polynomial coefficients per interval, highest power first
            self.coeffs = CubicSpline(t, pos_ned, axis=0, bc_type="clamped").c

    def at(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """(position, velocity, acceleration, yaw) due at ``now`` (held before the first and after the last)."""
        if self.hold or now <= self.t0 or now >= self.t1:
            i = 0 if (self.hold or now <= self.t0) else -1
            return self.pos[i].copy(), np.zeros(3), np.zeros(3), float(self.yaw[i])
        i = int(np.searchsorted(self.t, now, side="right")) - 1
        c3, c2, c1, c0 = self.coeffs[:, i]  # one interval's cubic, evaluated with its derivatives by Horner
        dx = now - self.t[i]
        pos = ((c3 * dx + c2) * dx + c1) * dx + c0
        vel = (3.0 * c3 * dx + 2.0 * c2) * dx + c1
        acc = 6.0 * c3 * dx + 2.0 * c2
        return pos, vel, acc, float(self.yaw[i])


class FlightControllerService(Service[FlightControllerConfig]):
    """Cascade control of the quadrotor from setpoints, on the onboard scheduler."""

    name = "flight_controller"
    config_class = FlightControllerConfig

    def configure(self) -> None:
        from mjnav.aerial import (
            CascadeController,
            CascadeGains,
            QuadrotorParams,
            RptController,
            rpt_gains,
        )
        from mjnav.aerial.outer import hinf_outer_gains, lqr_outer_gains, pid_outer_gains

        cfg = self.config
        self.params = QuadrotorParams()
        gains = CascadeGains(att_p=cfg.att_p, rate_p=cfg.rate_p, rate_i=cfg.rate_i, rate_d=cfg.rate_d)
        if cfg.controller == "pid":  # the P–PI outer loops, spaced from the attitude loop these gains give
            inner = CascadeController(self.params, gains)
            pid = pid_outer_gains(
                min(inner.attitude_bandwidth_rad_s(0), inner.attitude_bandwidth_rad_s(1)), cfg.pid_separation
            )
            gains = replace(gains, pos_p=(pid.pos_p,) * 3, vel_p=(pid.vel_p,) * 3, vel_i=(pid.vel_i,) * 3)
            self.log.info("pid: position P %.2f /s, velocity P %.2f /s, I %.2f /s²", pid.pos_p, pid.vel_p, pid.vel_i)
        outer_gains = {
            "pid": None,
            "rpt": lambda: rpt_gains(cfg.rpt_eps),
            "lqr": lqr_outer_gains,
            "hinf": hinf_outer_gains,
        }[cfg.controller]
        self._make_controller = lambda: CascadeController(
            self.params,
            gains,
            outer=None if outer_gains is None else RptController(outer_gains(), accel_limit=cfg.accel_limit_mps2),
        )
        self.ctl = self._make_controller()  # raises LoopSeparationError for an outer loop too fast
        # warm the compiled kernels (conversions, controller) now rather than at the first step in flight
        from mjnav.aerial import hover_state
        from mjnav.aerial.rep103 import quat_enu_flu_to_ned_frd

        quat_enu_flu_to_ned_frd([1.0, 0.0, 0.0, 0.0])
        self.ctl.update(hover_state(self.params), np.zeros(3), 0.0, 1.0 / cfg.rate_hz)
        # Peers' messages are kept by stamp (see _take_newest): the sim's mocap and IMU samples reach the
        # controller in order with the clock, but a lockstep peer's output of step t (the INS's estimate, the
        # flight client's trajectory) may reach it before or after clock t, as the router happens to schedule the
        # two links; a step at t uses only what the peers made at earlier steps, whatever the arrival order.
        self._lock = threading.Lock()
        self._ins_odom: deque[Any] = deque(maxlen=_KEEP)
        self._ins_health: deque[Any] = deque(maxlen=_KEEP)
        self._trajectories: deque[Any] = deque(maxlen=_KEEP)
        self.imu: Any = None  # mocap carries attitude and rates; with the INS they come from the newest IMU sample
        if cfg.state_source == "mocap":
            self.state_sub: Any = self.bus.subscribe("mocap")
        else:
            from mjnav.services.ins import ImuIntake

            self.state_sub = self.bus.subscribe("ins_odom", callback=self._keep(self._ins_odom))
            self.bus.subscribe("ins_health", callback=self._keep(self._ins_health))
            self.imu = ImuIntake(self._new_imu_check(), self.log, self.bus.key("imu"))
            self.bus.subscribe("imu", callback=self.imu.add)
            self._new_imu_check().check([0.0], [(1.0, 0.0, 0.0, 0.0)], [(0.0, 0.0, 0.0)], [(0.0, 0.0, 9.8)])
        self.setpoint_sub = self.bus.subscribe("setpoint")
        self.trajectory_sub = self.bus.subscribe("trajectory", callback=self._keep(self._trajectories))
        self.arm_sub = self.bus.subscribe("arm")
        self.rotor_pub = self.bus.publisher("rotor_cmd")
        self.state_pub = self.bus.publisher("flight_state")

    def _new_imu_check(self) -> Any:
        from mjnav.aerial.imu_check import ImuCheck, ImuCheckConfig

        return ImuCheck(ImuCheckConfig(gravity_mps2=self.params.gravity_mps2))

    def _keep(self, into: deque[Any]) -> Any:
        def keep(msg: Any) -> None:
            with self._lock:
                into.append(msg)

        return keep

    def _take_newest(self, kept: deque[Any], now: float) -> Any:
        """Take the newest kept message (``None`` if there is none) that was not made at sim time ``now``; the older
        ones are dropped. A message stamped ``now`` is a lockstep peer's output of this very step that arrived
        early: it stays for the next step, where it would have been seen had it arrived after the clock.
        """
        with self._lock:
            found = None
            while kept and abs(ros.seconds(kept[0].header.stamp) - now) > _STAMP_EPS_S:
                found = kept.popleft()
            return found

    @staticmethod
    def _timed(fn: Any) -> Any:
        def run(now: float) -> float:
            t0 = time.perf_counter()
            fn(now)
            return (time.perf_counter() - t0) * 1e6

        return run

    def activate(self) -> None:
        from mjnav.aerial import Scheduler, Task

        base = self.config.rate_hz
        table = [
            Task("EST", base, 200.0, 5),
            Task("CTL", base, 1000.0, 4),
            Task("SVO", base, 100.0, 3),
            Task("NET", base, 500.0, 2),
            Task("DLG", min(self.config.status_rate_hz, base), 500.0, 1),
        ]
        self.scheduler = Scheduler(
            table,
            base_rate_hz=base,
            handlers={
                "EST": self._timed(self._estimate),
                "CTL": self._timed(self._control),
                "SVO": self._timed(self._servo),
                "NET": self._timed(self._network),
                "DLG": self._timed(self._log_state),
            },
        )
        self.state = "disarmed"
        self._published_state = ""
        self.x: np.ndarray | None = None  # (17,) NED state estimate
        self.reference: _Reference | None = None
        self._trajectory_stamp: tuple[float, int] | None = None
        self.last_setpoint_t = -math.inf
        self.home_d = math.nan  # NED down of the arming position
        self.command = np.zeros(4)
        self._land_start: tuple[float, np.ndarray] | None = None
        self._land_yaw = 0.0
        self._still_since: float | None = None  # since when the vehicle sits on the ground while landing
        self._now = 0.0
        self._outbox: list[tuple[Any, Any]] = []  # (publisher, message) made by this step's tasks
        self._ins_state: Any = None  # the INS estimate in use (ins_odom)
        self._health: Any = None  # the INS health of the same step (ins_health; None: the INS publishes none)
        self._imu_msg: Any = None  # the newest accepted IMU sample
        self.home = np.zeros(3)  # NED arming position
        self._hold_start = 0.0  # when the position-lost hold began
        self._return: _Reference | None = None
        with self._lock:
            self._ins_odom.clear()
            self._ins_health.clear()
            self._trajectories.clear()
        if self.imu is not None:
            self.imu.reset(self._new_imu_check())
        self.ctl.reset()

    def step(self, now: float) -> None:
        self._now = now
        try:
            self.scheduler.tick(now)
        finally:
            # the step's messages leave together (one Zenoh wake-up, not one per task), in the order made
            outbox, self._outbox = self._outbox, []
            for pub, msg in outbox:
                pub.put(msg)

    # ------------------------------------------------------------------------------------------------- tasks

    def _estimate(self, now: float) -> None:
        from mjnav.aerial.rep103 import enu_to_ned, flu_to_frd, quat_enu_flu_to_ned_frd

        if self.config.state_source == "mocap":
            msg = self.state_sub.latest()
        else:
            newest = self._take_newest(self._ins_odom, now)
            msg = self._ins_state = newest if newest is not None else self._ins_state
            health = self._take_newest(self._ins_health, now)
            self._health = health if health is not None else self._health
            samples, _ = self.imu.take(now)
            self._imu_msg = samples[-1] if samples else self._imu_msg
        if msg is None:
            return
        stamp, pos, quat, vel, rates = uav_msgs.odometry_state(msg)
        x = np.zeros(17)
        if self.config.state_source == "mocap":
            x[0:3], x[3:6] = enu_to_ned(pos), enu_to_ned(vel)
            x[6:10], x[10:13] = quat_enu_flu_to_ned_frd(quat), flu_to_frd(rates)
        else:
            ned = msg.header.frame_id == "map_ned"
            p, v = (pos, vel) if ned else (enu_to_ned(pos), enu_to_ned(vel))
            x[0:3], x[3:6] = p + v * max(0.0, now - stamp), v
            imu = self._imu_msg
            if imu is None:
                return
            o, w = imu.orientation, imu.angular_velocity
            x[6:10] = quat_enu_flu_to_ned_frd([o.w, o.x, o.y, o.z])
            x[10:13] = flu_to_frd([w.x, w.y, w.z])
        self.x = x

    def _control(self, now: float) -> None:
        x, cfg = self.x, self.config
        if self.state == "disarmed" or x is None:
            self.command = np.zeros(4)
            return
        if self.state == "armed":
            self.command = np.full(4, cfg.idle_speed_rad_s)
            return
        dt = 1.0 / cfg.rate_hz
        if self.state == "offboard" and self.reference is not None:
            pos, vel, acc, yaw = self.reference.at(now)
            if self.home_d - pos[2] < 0.1 and self.home_d - x[2] < cfg.touchdown_height_m:
                # on the ground and asked to stay there: idle, no integrator wind-up against the ground
                self.command = np.full(4, cfg.idle_speed_rad_s)
                self.ctl.reset()
                return
        elif self.state == "failsafe_return":
            assert self._return is not None
            pos, vel, acc, yaw = self._return.at(now)
        else:  # over the point where the failsafe or the landing began: hold its altitude, or descend
            assert self._land_start is not None
            t0, p0 = self._land_start
            pos, vel, acc, yaw = p0.copy(), np.zeros(3), np.zeros(3), self._land_yaw
            if self.state in _DESCENDING:
                speed = cfg.failsafe_descend_speed_mps if self.state == "failsafe_descend" else cfg.land_speed_mps
                pos[2] = min(p0[2] + speed * (now - t0), self.home_d + 0.5)
                vel[2] = speed if pos[2] < self.home_d + 0.5 else 0.0
                if self._landed(now, x, pos, t0):
                    self._set_state("disarmed", now)
                    self.command = np.zeros(4)
                    return
            if self.state in ("failsafe_hold", "failsafe_descend"):
                # no position: the position loop sees no error, the velocity loop damps the dead-reckoned velocity
                x = x.copy()
                x[0:2] = pos[0:2]
        self.command = self.ctl.update(x, pos, yaw, dt, velocity_ff=vel, accel_ff=acc)

    def _landed(self, now: float, x: np.ndarray, pos: np.ndarray, t0: float) -> bool:
        """PX4's land detector in short: near the arming height and still, or — when the estimate drifted — the
        descent setpoint is at the ground and for a second the thrust has stayed below 60 % of hover (the ground
        carries the vehicle) without a fast vertical motion."""
        pressed = pos[2] >= self.home_d and self.ctl.thrust_sp_n < 0.6 * self.params.hover_thrust_n
        on_ground = pressed and abs(x[5]) < 0.5
        self._still_since = (self._still_since if self._still_since is not None else now) if on_ground else None
        near = self.home_d - x[2] < self.config.touchdown_height_m and abs(x[5]) < 0.1 and now - t0 > 0.5
        return near or (self._still_since is not None and now - self._still_since >= 1.0)

    def _servo(self, now: float) -> None:
        self._outbox.append((self.rotor_pub, ros.joint_state(now, _ROTORS, np.zeros(4), self.command)))

    def _network(self, now: float) -> None:
        from mjnav.aerial.rep103 import enu_to_ned

        for msg in self.arm_sub.drain():
            self._on_arm(bool(msg.data), now)
        setpoint = self.setpoint_sub.take()
        trajectory = self._take_newest(self._trajectories, now)
        if trajectory is not None and len(trajectory.poses) > 0:
            self.last_setpoint_t = now
            key = (ros.seconds(trajectory.header.stamp), len(trajectory.poses))
            if key != self._trajectory_stamp or setpoint is not None:
                ts, pts, yaws = uav_msgs.trajectory_arrays(trajectory)
                if np.all(np.diff(ts) > 0):
                    self._trajectory_stamp = key
                    self.reference = _Reference(ts, enu_to_ned(pts), math.pi / 2 - yaws)
                else:
                    self.log.warning("trajectory dropped: its stamps are not increasing")
        elif setpoint is not None:
            self.last_setpoint_t = now
            self._trajectory_stamp = None
            q = setpoint.pose.orientation
            yaw_enu = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
            p = enu_to_ned(uav_msgs.position(setpoint.pose))
            self.reference = _Reference(np.array([now]), p[None, :], np.array([math.pi / 2 - yaw_enu]))
        self._failsafes(now)

    def _failsafes(self, now: float) -> None:
        """Take off on the first setpoint; the failsafes (see the module's docs) and their next phases."""
        cfg = self.config
        lost = self._position_lost()
        fence = self._outside_fence() if self.state == "offboard" else ""
        if self.state == "armed" and self.reference is not None and now - self.last_setpoint_t < 1e-9 and not lost:
            self.ctl.reset()
            self._set_state("offboard", now)
        elif self.state in _ON_POSITION and lost:
            self.log.warning("position lost (%s): failsafe, holding attitude and altitude, then descending", lost)
            self._start_landing("failsafe_descend" if self.state in _DESCENDING else "failsafe_hold", now)
            self.ctl.clear_horizontal_integrators()
        elif self.state == "offboard" and now - self.last_setpoint_t >= cfg.setpoint_timeout_s - 1e-9:
            self.log.warning("no setpoint for %.2f s of sim time: failsafe, landing", now - self.last_setpoint_t)
            self._start_landing("failsafe_land", now)
        elif fence:
            self.log.warning("geofence left (%s): failsafe, %s", fence, cfg.geofence_action)
            if cfg.geofence_action == "land":
                self._start_landing("failsafe_land", now)
            else:
                self._start_return(now)
        elif self.state == "failsafe_hold" and now - self._hold_start >= cfg.position_loss_hold_s - 1e-9:
            self._start_landing("failsafe_descend", now)
        elif self.state == "failsafe_return" and self._return is not None and now >= self._return.t1 + 1.0:
            self._start_landing("failsafe_land", now)

    def _position_lost(self) -> str:
        """Why the INS's newest health says the horizontal position is lost ("" when it does not, or there is
        none)."""
        health = self._health
        if health is None or not health.status or health.status[0].level < health.status[0].ERROR:
            return ""
        return str(health.status[0].message)

    def _outside_fence(self) -> str:
        """How the estimated position is outside the geofence ("" inside it, or without an estimate)."""
        x, cfg = self.x, self.config
        if x is None:
            return ""
        radius, altitude = math.hypot(x[0], x[1]), -x[2]
        if cfg.geofence_radius_m > 0.0 and radius > cfg.geofence_radius_m:
            return f"{radius:.1f} m from the datum, the fence's radius is {cfg.geofence_radius_m:g} m"
        if cfg.geofence_max_altitude_m > 0.0 and altitude > cfg.geofence_max_altitude_m:
            return f"{altitude:.1f} m above the datum, the fence's ceiling is {cfg.geofence_max_altitude_m:g} m"
        return ""

    def _start_return(self, now: float) -> None:
        """Fly over the arming position at the current altitude (below the ceiling) at ``return_speed_mps``."""
        from mjnav.aerial import euler_from_quat

        assert self.x is not None
        cfg = self.config
        p = self.x[0:3].copy()
        target = np.array([self.home[0], self.home[1], p[2]])
        if cfg.geofence_max_altitude_m > 0.0:
            target[2] = max(p[2], -0.9 * cfg.geofence_max_altitude_m)
        duration = max(1.0, float(np.linalg.norm(target - p)) / cfg.return_speed_mps)
        yaw = float(euler_from_quat(self.x[6:10])[2])
        self._return = _Reference(np.array([now, now + duration]), np.stack([p, target]), np.array([yaw, yaw]))
        self._set_state("failsafe_return", now)

    def _on_arm(self, arm: bool, now: float) -> None:
        if arm and self.state == "disarmed":
            if self.x is None:
                self.log.warning("arming refused: no state estimate yet")
                return
            refusal = self._position_lost() or self._outside_fence()
            if refusal:
                self.log.warning("arming refused: %s", refusal)
                return
            self.home = self.x[0:3].copy()
            self.home_d = float(self.x[2])
            self.reference = None
            self._set_state("armed", now)
        elif not arm and self.state == "armed":
            self._set_state("disarmed", now)
        elif not arm and self.state == "offboard":
            self._start_landing("landing", now)

    def _start_landing(self, state: str, now: float) -> None:
        """Enter ``state`` (a landing, or the position-lost hold), over the current position and heading."""
        assert self.x is not None
        self._land_start = (now, self.x[0:3].copy())
        self._hold_start = now
        self._still_since = None
        from mjnav.aerial import euler_from_quat

        self._land_yaw = float(euler_from_quat(self.x[6:10])[2])
        self._set_state(state, now)

    def _set_state(self, state: str, now: float) -> None:
        if state != self.state:
            self.log.info("%s -> %s at %.3f s", self.state, state, now)
        self.state = state
        self._log_state(now)

    def _log_state(self, now: float) -> None:
        self._outbox.append((self.state_pub, uav_msgs.string(self.state)))

    def deactivate(self) -> None:
        self.rotor_pub.put(ros.joint_state(self._now, _ROTORS, np.zeros(4), np.zeros(4)))

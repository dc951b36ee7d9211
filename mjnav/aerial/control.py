"""Quadrotor control: a PX4-style cascade (position → velocity → attitude → rate PID) and loop-design tools.

* `PID`: per-axis PID with derivative on the measurement through a first-order low-pass and anti-windup
  (integrator clamp + conditional integration while the output is saturated).
* `CascadeController`: position P → velocity PID → thrust vector and attitude setpoint → attitude P on the
  quaternion error → body-rate PID → torque → `mix` → rotor speeds. NED / FRD, radians.
* `lqr`, `hinf_state_feedback`: continuous-time state-feedback synthesis (``u = -K x``) through scipy's Riccati
  solver; H∞ by γ bisection on the game Riccati equation (Doyle–Glover–Khargonekar–Francis state feedback).
* `loop_margins`: gain and phase margins of a state-feedback loop broken at one plant input.
* `rpt_gains` / `RptController`: Chen et al.'s robust-and-perfect-tracking outer loop
  ``u = a_r + K_p e + K_d ė + K_i ∫e`` with gains ∝ 1/ε², 1/ε, 1/ε³ and closed-loop poles ∝ 1/ε.
* `closed_loop_bandwidth`, `check_loop_separation`: reject an outer loop too fast for its inner loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg
from numba import njit
from scipy.optimize import brentq

from mjnav.aerial.errors import DesignError, InvalidParameterError, LoopSeparationError
from mjnav.aerial.quadrotor import QuadrotorParams, _mix_kernel, _mixer_inverse

__all__ = [
    "PID",
    "CascadeController",
    "CascadeGains",
    "HinfDesign",
    "LqrDesign",
    "Margins",
    "RptController",
    "RptGains",
    "care",
    "check_loop_separation",
    "closed_loop_bandwidth",
    "hinf_norm",
    "hinf_state_feedback",
    "hover_lqr",
    "loop_margins",
    "lqr",
    "rpt_gains",
    "rpt_poles",
]


def _vec(value: Any, n: int, name: str) -> np.ndarray:
    v = np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)).copy()
    if np.any(np.isnan(v)):
        raise InvalidParameterError(f"{name} must not be NaN")
    return v


class PID:
    """Vector PID with filtered derivative-on-measurement and anti-windup.

    ``out = kp·e + ki·∫e + kd·d(-y)/dt`` (derivative of the negated measurement, low-passed, so a setpoint step
    gives no derivative kick), clipped to ±output_limit. The integrator is clamped to ±integral_limit and frozen on
    an axis while the output is saturated and the error would push it further.

    Args:
        kp, ki, kd: gains, scalars or (dim,) arrays.
        dim: number of axes.
        integral_limit: bound on ``ki·∫e`` (output units), scalar or (dim,).
        output_limit: bound on the output, scalar or (dim,).
        d_cutoff_hz: derivative low-pass cutoff, Hz (None: unfiltered).
    """

    def __init__(
        self,
        kp: Any,
        ki: Any = 0.0,
        kd: Any = 0.0,
        *,
        dim: int = 3,
        integral_limit: Any = math.inf,
        output_limit: Any = math.inf,
        d_cutoff_hz: float | None = None,
    ) -> None:
        self.kp = _vec(kp, dim, "kp")
        self.ki = _vec(ki, dim, "ki")
        self.kd = _vec(kd, dim, "kd")
        self.integral_limit = _vec(integral_limit, dim, "integral_limit")
        self.output_limit = _vec(output_limit, dim, "output_limit")
        if np.any(self.integral_limit < 0) or np.any(self.output_limit < 0):
            raise InvalidParameterError("limits must be >= 0")
        if d_cutoff_hz is not None and not d_cutoff_hz > 0.0:
            raise InvalidParameterError(f"d_cutoff_hz must be > 0, got {d_cutoff_hz}")
        self.d_cutoff_hz = d_cutoff_hz
        self.dim = dim
        self.integral = np.zeros(dim)  # ki·∫e, output units
        self.derivative = np.zeros(dim)  # filtered d(-y)/dt
        self._last_meas: np.ndarray | None = None

    def reset(self) -> None:
        """Zero the integrator and the derivative filter."""
        self.integral[:] = 0.0
        self.derivative[:] = 0.0
        self._last_meas = None

    def update(self, setpoint: Any, measurement: Any, dt: float, measurement_rate: Any = None) -> np.ndarray:
        """One control period.

        Args:
            setpoint, measurement: (dim,) arrays.
            dt: period, s (> 0).
            measurement_rate: (dim,) time derivative of the measurement if known (e.g. a gyro for an angle loop);
                otherwise it is differenced.

        Returns:
            (dim,) output.
        """
        if not dt > 0.0:
            raise InvalidParameterError(f"dt must be > 0, got {dt}")
        sp = np.asarray(setpoint, dtype=np.float64)
        y = np.asarray(measurement, dtype=np.float64)
        if measurement_rate is not None:
            rate, mode = np.asarray(measurement_rate, dtype=np.float64), _D_GIVEN
        else:
            rate, mode = y, _D_NONE if self._last_meas is None else _D_DIFFERENCE
        if self._last_meas is None:
            self._last_meas = np.zeros(self.dim)
        return _pid_step(self._state(dt), sp, y, rate, mode, dt)

    def _state(self, dt: float) -> _PidState:
        """The arrays `_pid_step` reads and updates in place (``_last_meas`` must exist)."""
        alpha = -1.0 if self.d_cutoff_hz is None else dt / (dt + 1.0 / (2.0 * math.pi * self.d_cutoff_hz))
        assert self._last_meas is not None
        return (
            self.kp, self.ki, self.kd, self.integral_limit, self.output_limit, alpha,
            self.integral, self.derivative, self._last_meas,
        )  # fmt: skip


#: How `_pid_step` gets the derivative term: none (first call), by differencing the measurement, or given.
_D_NONE, _D_DIFFERENCE, _D_GIVEN = 0, 1, 2
#: (kp, ki, kd, integral limit, output limit, derivative filter α (< 0: unfiltered), integral, derivative,
#: last measurement): a `PID`'s gains and its state arrays, updated in place by `_pid_step`.
_PidState = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, np.ndarray, np.ndarray, np.ndarray]


@njit(cache=True)
def _pid_step(state: Any, sp: np.ndarray, y: np.ndarray, rate: np.ndarray, mode: int, dt: float) -> np.ndarray:
    """One `PID.update` on (dim,) arrays: returns the output; the integral, derivative and last measurement of
    ``state`` (see `_PidState`) are updated in place. ``rate`` is the measurement's derivative (``mode`` _D_GIVEN)."""
    kp, ki, kd, ilim, olim, alpha, integral, derivative, last = state
    out = np.empty(sp.shape[0])
    for i in range(sp.shape[0]):
        e = sp[i] - y[i]
        if mode == _D_GIVEN:
            raw = -rate[i]
        elif mode == _D_DIFFERENCE:
            raw = -(y[i] - last[i]) / dt
        else:
            raw = 0.0
        last[i] = y[i]
        if alpha < 0.0:
            derivative[i] = raw
        else:
            derivative[i] += alpha * (raw - derivative[i])
        unsat = kp[i] * e + integral[i] + kd[i] * derivative[i]
        out[i] = min(max(unsat, -olim[i]), olim[i])
        # conditional integration: not while saturated in the direction the error pushes
        if not ((unsat > olim[i] and e > 0.0) or (unsat < -olim[i] and e < 0.0)):
            integral[i] = min(max(integral[i] + ki[i] * e * dt, -ilim[i]), ilim[i])
    return out


@dataclass(frozen=True)
class CascadeGains:
    """Gains of the PX4-style cascade (defaults suit the default `QuadrotorParams`).

    Attributes:
        pos_p: position P, 1/s (N, E, D).
        vel_p, vel_i, vel_d: velocity PID, 1/s, 1/s², - (output: acceleration m/s²).
        att_p: attitude P, 1/s (roll, pitch, yaw) on the quaternion error.
        rate_p, rate_i, rate_d: body-rate PID in angular acceleration (rad/s² per rad/s); torque = J · output.
        rate_d_cutoff_hz: rate-derivative low-pass, Hz.
        rate_integral_limit: bound on the rate integrator, rad/s².
        vel_integral_limit: bound on the velocity integrator, m/s².
        max_speed_mps: velocity setpoint limit (horizontal and vertical).
        max_tilt_rad: tilt limit of the thrust vector.
        max_rate_rad_s: body-rate setpoint limit.
    """

    pos_p: tuple[float, float, float] = (1.0, 1.0, 1.5)
    vel_p: tuple[float, float, float] = (2.5, 2.5, 4.0)
    vel_i: tuple[float, float, float] = (0.4, 0.4, 2.0)
    vel_d: tuple[float, float, float] = (0.0, 0.0, 0.0)
    att_p: tuple[float, float, float] = (7.0, 7.0, 3.0)
    rate_p: tuple[float, float, float] = (25.0, 25.0, 10.0)
    rate_i: tuple[float, float, float] = (5.0, 5.0, 2.0)
    rate_d: tuple[float, float, float] = (0.3, 0.3, 0.0)
    rate_d_cutoff_hz: float = 30.0
    rate_integral_limit: float = 30.0
    vel_integral_limit: float = 3.0
    max_speed_mps: float = 5.0
    max_tilt_rad: float = 0.6
    max_rate_rad_s: float = 4.0


@dataclass
class CascadeController:
    """Position → velocity → attitude → rate cascade producing rotor-speed commands for the full model.

    Args:
        params: the vehicle (mass, inertia, mixer).
        gains: loop gains.
        outer: an optional `RptController` replacing the position P + velocity PID loops (its acceleration command
            feeds the attitude loop). It is checked against the attitude loop's bandwidth with
            `check_loop_separation` (factor ``separation_factor``).
        separation_factor: required ratio of the attitude bandwidth to the fastest outer-loop pole.

    Raises:
        LoopSeparationError: the RPT outer loop's poles come within ``separation_factor`` of the attitude loop's
            bandwidth.

    `update` takes the (17,) full state (the caller decides whether it is truth or an estimate) and returns the
    (4,) rotor-speed command in rad/s; the intermediate setpoints of the last call are kept as attributes.
    """

    params: QuadrotorParams = field(default_factory=QuadrotorParams)
    gains: CascadeGains = field(default_factory=CascadeGains)
    outer: RptController | None = None
    separation_factor: float = 1.5

    def __post_init__(self) -> None:
        g = self.gains
        if self.outer is not None:
            check_loop_separation(rpt_poles(self.outer.gains), self.attitude_bandwidth_rad_s(), self.separation_factor)
        self.vel_pid = PID(
            g.vel_p, g.vel_i, g.vel_d, integral_limit=g.vel_integral_limit, d_cutoff_hz=5.0, output_limit=15.0
        )
        self.rate_pid = PID(
            g.rate_p,
            g.rate_i,
            g.rate_d,
            integral_limit=g.rate_integral_limit,
            d_cutoff_hz=g.rate_d_cutoff_hz,
            output_limit=200.0,
        )
        self.velocity_sp = np.zeros(3)
        self.accel_sp = np.zeros(3)
        self.attitude_sp = np.array([1.0, 0.0, 0.0, 0.0])
        self.rate_sp = np.zeros(3)
        self.thrust_sp_n = 0.0
        self.torque_sp_nm = np.zeros(3)

    def reset(self) -> None:
        """Clear integrators and filters."""
        self.vel_pid.reset()
        self.rate_pid.reset()
        if self.outer is not None:
            self.outer.reset()

    def clear_horizontal_integrators(self) -> None:
        """Zero the outer loops' north and east integrators: the trim they hold is for a position that can no longer
        be measured (the flight controller's position-lost failsafe)."""
        self.vel_pid.integral[0:2] = 0.0
        if self.outer is not None:
            self.outer.integral[0:2] = 0.0

    def attitude_bandwidth_rad_s(self, axis: int = 0) -> float:
        """-3 dB bandwidth (rad/s) of the attitude loop (roll: axis 0, pitch: 1) on the linearised axis.

        Model: angle P → rate PI (+ D on the measured rate) → torque through the first-order motor lag on
        ``J ω̇ = τ``; states [angle, rate, torque, rate integral], input the angle setpoint.
        """
        g, p = self.gains, self.params
        j, tm = p.inertia_kgm2[axis], p.motor_time_constant_s
        ka, kp, ki, kd = g.att_p[axis], g.rate_p[axis], g.rate_i[axis], g.rate_d[axis]
        # τ_cmd = J (kp (ka (φ_sp - φ) - ω) + i - kd ω̇),  ω̇ = τ / J,  i̇ = ki (ka (φ_sp - φ) - ω)
        a = np.array(
            [
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, 1.0 / j, 0.0],
                [-j * kp * ka / tm, -j * kp / tm, -(1.0 + kd) / tm, j / tm],
                [-ki * ka, -ki, 0.0, 0.0],
            ]
        )
        b = np.array([[0.0], [0.0], [j * kp * ka / tm], [ki * ka]])
        return closed_loop_bandwidth(a, b, np.array([[1.0, 0.0, 0.0, 0.0]]))

    def update(
        self,
        state: np.ndarray,
        position_sp: Any,
        yaw_sp: float,
        dt: float,
        velocity_ff: Any = None,
        accel_ff: Any = None,
    ) -> np.ndarray:
        """One control period of all loops.

        Args:
            state: (17,) full state (see `mjnav.aerial.quadrotor`).
            position_sp: (3,) NED position setpoint, m.
            yaw_sp: heading setpoint, rad.
            dt: period, s.
            velocity_ff, accel_ff: optional (3,) NED feed-forwards, m/s and m/s².

        Returns:
            (4,) rotor-speed commands, rad/s.
        """
        g = self.gains
        x = np.asarray(state, dtype=np.float64)
        pos, vel, quat, omega = x[0:3], x[3:6], x[6:10], x[10:13]
        if self.outer is not None:
            zero = np.zeros(3)
            v_sp = zero if velocity_ff is None else np.asarray(velocity_ff, dtype=np.float64)
            a_ref = zero if accel_ff is None else np.asarray(accel_ff, dtype=np.float64)
            a_sp = self.outer.update(position_sp, v_sp, a_ref, pos, vel, dt)
        else:
            v_sp = np.asarray(g.pos_p) * (np.asarray(position_sp, dtype=np.float64) - pos)
            if velocity_ff is not None:
                v_sp = v_sp + np.asarray(velocity_ff, dtype=np.float64)
            v_sp = np.clip(v_sp, -g.max_speed_mps, g.max_speed_mps)
            a_sp = self.vel_pid.update(v_sp, vel, dt)
            if accel_ff is not None:
                a_sp = a_sp + np.asarray(accel_ff, dtype=np.float64)
        self.velocity_sp, self.accel_sp = v_sp, a_sp
        if not dt > 0.0:
            raise InvalidParameterError(f"dt must be > 0, got {dt}")
        rate = self.rate_pid
        mode = _D_NONE if rate._last_meas is None else _D_DIFFERENCE
        if rate._last_meas is None:
            rate._last_meas = np.zeros(3)
        q_sp, thrust, rate_sp, torque, speeds = _inner_loops(
            a_sp, float(yaw_sp), quat, omega, dt, mode, rate._state(dt), self._vehicle, self._attitude_gains
        )
        self.attitude_sp, self.thrust_sp_n, self.rate_sp, self.torque_sp_nm = q_sp, thrust, rate_sp, torque
        return speeds

    @property
    def _vehicle(self) -> tuple[float, float, np.ndarray, np.ndarray, float, float]:
        """(mass kg, gravity m/s², inertia (3,) kg m², mixer inverse (4, 4), max rotor thrust N, k_f) for the
        kernels."""
        p = self.params
        return (
            p.mass_kg, p.gravity_mps2, np.asarray(p.inertia_kgm2, dtype=np.float64), _mixer_inverse(p),
            p.max_rotor_thrust_n, p.thrust_coeff,
        )  # fmt: skip

    @property
    def _attitude_gains(self) -> tuple[float, np.ndarray, float]:
        """(tan of the tilt limit, attitude P (3,) 1/s, body-rate limit rad/s) for the kernels."""
        g = self.gains
        return math.tan(g.max_tilt_rad), np.asarray(g.att_p, dtype=np.float64), g.max_rate_rad_s

    def attitude_from_accel(self, accel_sp: np.ndarray, yaw_sp: float, quat: np.ndarray) -> tuple[np.ndarray, float]:
        """Attitude setpoint (4,) quaternion and collective thrust (N) realising an NED acceleration setpoint.

        The thrust vector ``m (a_sp - g ẑ)`` is tilt-limited; body -z is aligned with it and the heading set to
        ``yaw_sp``; the collective thrust is its projection on the current body -z axis.
        """
        p = self.params
        return _attitude_from_accel(
            np.asarray(accel_sp, dtype=np.float64),
            float(yaw_sp),
            np.asarray(quat, dtype=np.float64),
            p.mass_kg,
            p.gravity_mps2,
            math.tan(self.gains.max_tilt_rad),
        )

    def attitude_control(self, quat: np.ndarray, quat_sp: np.ndarray) -> np.ndarray:
        """Body-rate setpoint (3,) rad/s: ``att_p ⊙ 2 sign(q_e,w) q_e,xyz`` with ``q_e = q⁻¹ ⊗ q_sp``, clipped."""
        g = self.gains
        return _attitude_control(
            np.asarray(quat, dtype=np.float64),
            np.asarray(quat_sp, dtype=np.float64),
            np.asarray(g.att_p, dtype=np.float64),
            g.max_rate_rad_s,
        )


# The inner loops compiled (numba): on (3,) and (4,) vectors NumPy's per-call overhead is most of the cost, and the
# flight controller runs them at every clock tick of a lockstep flight.


@njit(cache=True)
def _attitude_from_accel(
    accel_sp: np.ndarray, yaw_sp: float, quat: np.ndarray, mass: float, gravity: float, tan_tilt: float
) -> tuple[np.ndarray, float]:
    """`CascadeController.attitude_from_accel` (tilt limit given as its tangent)."""
    f0, f1 = mass * accel_sp[0], mass * accel_sp[1]
    f2 = min(mass * (accel_sp[2] - gravity), -1e-6)  # never command thrust downwards
    horiz = math.hypot(f0, f1)
    max_h = -f2 * tan_tilt
    if horiz > max_h:
        f0, f1 = f0 * max_h / horiz, f1 * max_h / horiz
    n = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    zb = np.array([-f0 / n, -f1 / n, -f2 / n])
    xc = np.array([math.cos(yaw_sp), math.sin(yaw_sp), 0.0])
    yb = _cross(zb, xc)
    yb /= math.sqrt(yb[0] * yb[0] + yb[1] * yb[1] + yb[2] * yb[2])
    xb = _cross(yb, zb)
    m = np.empty((3, 3))
    m[:, 0], m[:, 1], m[:, 2] = xb, yb, zb
    q_sp = _quat_from_matrix(m)
    w, qx, qy, qz = quat[0], quat[1], quat[2], quat[3]
    body_z0, body_z1, body_z2 = 2 * (qx * qz + w * qy), 2 * (qy * qz - w * qx), 1 - 2 * (qx * qx + qy * qy)
    thrust = max(0.0, -(f0 * body_z0 + f1 * body_z1 + f2 * body_z2))
    return q_sp, thrust


@njit(cache=True)
def _attitude_control(quat: np.ndarray, quat_sp: np.ndarray, att_p: np.ndarray, lim: float) -> np.ndarray:
    """`CascadeController.attitude_control`."""
    qc = np.array([quat[0], -quat[1], -quat[2], -quat[3]])
    qe = _qmul(qc, quat_sp)
    sign = 2.0 * math.copysign(1.0, qe[0])
    out = np.empty(3)
    for i in range(3):
        out[i] = min(max(att_p[i] * (sign * qe[i + 1]), -lim), lim)
    return out


@njit(cache=True)
def _inner_loops(
    a_sp: np.ndarray,
    yaw_sp: float,
    quat: np.ndarray,
    omega: np.ndarray,
    dt: float,
    rate_mode: int,
    rate_state: Any,
    vehicle: Any,
    attitude: Any,
) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, np.ndarray]:
    """Acceleration setpoint → attitude setpoint and thrust → body-rate setpoint → rate PID (state updated in
    place) → torque → mixer → rotor speeds. Returns (q_sp (4,), thrust N, rate_sp (3,), torque (3,) N m,
    rotor speeds (4,) rad/s)."""
    mass, gravity, inertia, mix_inv, tmax, k_f = vehicle
    tan_tilt, att_p, max_rate = attitude
    q_sp, thrust = _attitude_from_accel(a_sp, yaw_sp, quat, mass, gravity, tan_tilt)
    rate_sp = _attitude_control(quat, q_sp, att_p, max_rate)
    ang_acc = _pid_step(rate_state, rate_sp, omega, omega, rate_mode, dt)
    torque = inertia * ang_acc + _cross(omega, inertia * omega)
    thrusts = _mix_kernel(mix_inv, thrust, torque, tmax)
    return q_sp, thrust, rate_sp, torque, np.sqrt(np.maximum(thrusts, 0.0) / k_f)


@njit(cache=True)
def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of two (3,) vectors."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(cache=True)
def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, ax, ay, az = a[0], a[1], a[2], a[3]
    bw, bx, by, bz = b[0], b[1], b[2], b[3]
    return np.array(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


@njit(cache=True)
def _quat_from_matrix(m: np.ndarray) -> np.ndarray:
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = np.array([0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s])
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2
        q = np.array([(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s])
    elif m[1, 1] > m[2, 2]:
        s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2
        q = np.array([(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s])
    else:
        s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2
        q = np.array([(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s])
    return q / math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])


# ---------------------------------------------------------------------------------------------------------------
# state-feedback synthesis


def care(A: np.ndarray, G: np.ndarray, Q: np.ndarray) -> np.ndarray | None:
    """Stabilising solution X of ``AᵀX + XA - X G X + Q = 0`` (G, Q symmetric), or None when there is none.

    Solved by the ordered real Schur form of the Hamiltonian ``[[A, -G], [-Q, -Aᵀ]]`` (Laub's method): with the
    stable invariant subspace spanned by ``[U1; U2]``, ``X = U2 U1⁻¹``, refined by up to three Newton-Kleinman
    steps when its residual is not small. None when the Hamiltonian has eigenvalues on (or numerically at) the
    imaginary axis, U1 is singular, or the result is not a symmetric solution that makes ``A - G X`` Hurwitz.
    """
    n = A.shape[0]
    h = np.block([[A, -G], [-Q, -A.T]])
    if not np.all(np.isfinite(h)):
        return None
    try:
        _, z, sdim = scipy.linalg.schur(h, output="real", sort="lhp")
    except (np.linalg.LinAlgError, ValueError):
        return None
    if sdim != n:
        return None
    u1, u2 = z[:n, :n], z[n:, :n]
    if np.linalg.cond(u1) > 1e14:
        return None
    x = np.linalg.solve(u1.T, u2.T).T
    x = 0.5 * (x + x.T)
    if not np.all(np.isfinite(x)):
        return None
    size = max(1.0, float(np.max(np.abs(x)))) * max(1.0, float(np.max(np.abs(h))))
    res = A.T @ x + x @ A - x @ G @ x + Q
    for _ in range(3):  # Newton-Kleinman refinement when the Schur solution is not accurate enough
        if np.max(np.abs(res)) <= 1e-10 * size:
            break
        acl = A - G @ x
        try:
            dx = scipy.linalg.solve_continuous_lyapunov(acl.T, -res)
        except (np.linalg.LinAlgError, ValueError):
            return None
        x = x + 0.5 * (dx + dx.T)
        res = A.T @ x + x @ A - x @ G @ x + Q
    if not np.all(np.isfinite(x)) or np.max(np.abs(res)) > 1e-6 * size:
        return None
    if not np.all(np.linalg.eigvals(A - G @ x).real < 0):
        return None
    return x


@dataclass(frozen=True)
class LqrDesign:
    """An LQR design ``u = -K x``: gain K (m, n), Riccati solution S (n, n), closed-loop poles (n,) complex."""

    K: np.ndarray
    S: np.ndarray
    poles: np.ndarray


def _as2d(m: Any, name: str) -> np.ndarray:
    a = np.atleast_2d(np.asarray(m, dtype=np.float64))
    if a.ndim != 2 or not np.all(np.isfinite(a)):
        raise InvalidParameterError(f"{name} must be a finite 2-D array")
    return a


def lqr(A: Any, B: Any, Q: Any, R: Any) -> LqrDesign:
    """Continuous-time LQR: minimise ∫ xᵀQx + uᵀRu for ẋ = Ax + Bu.

    The Riccati equation is solved by `care` (Hamiltonian Schur form, ~0.1–0.3 ms for the 12-state hover model);
    when that fails on a badly conditioned problem, by ``scipy.linalg.solve_continuous_are``.

    Args:
        A: (n, n); B: (n, m); Q: (n, n) symmetric PSD; R: (m, m) symmetric PD.

    Returns:
        `LqrDesign` with ``K = R⁻¹ Bᵀ S`` (u = -K x).

    Raises:
        DesignError: no stabilising solution (e.g. (A, B) not stabilisable).
    """
    a, b, q, r = _as2d(A, "A"), _as2d(B, "B"), _as2d(Q, "Q"), _as2d(R, "R")
    if a.shape[0] != a.shape[1] or b.shape[0] != a.shape[0] or q.shape != a.shape or r.shape != (b.shape[1],) * 2:
        raise InvalidParameterError(f"shape mismatch: A {a.shape}, B {b.shape}, Q {q.shape}, R {r.shape}")
    rinv_bt = np.linalg.solve(r, b.T)
    s = care(a, b @ rinv_bt, q)
    if s is None:  # badly conditioned: scipy's balanced generalised-pencil solver is slower but more robust
        try:
            s = scipy.linalg.solve_continuous_are(a, b, q, r)
        except (np.linalg.LinAlgError, ValueError) as exc:
            raise DesignError(f"LQR Riccati equation has no stabilising solution: {exc}") from exc
        if not np.all(np.linalg.eigvals(a - b @ (rinv_bt @ s)).real < 0):
            raise DesignError("LQR Riccati solution does not stabilise the closed loop")
    k = rinv_bt @ s
    return LqrDesign(k, s, np.linalg.eigvals(a - b @ k))


def hover_lqr(params: QuadrotorParams, Q: Any, R: Any) -> LqrDesign:
    """LQR for the 12-state hover linearisation (`hover_linearization`); u = -K δx is [δT, τx, τy, τz]."""
    from mjnav.aerial.quadrotor import hover_linearization

    a, b = hover_linearization(params)
    return lqr(a, b, Q, R)


@dataclass(frozen=True)
class HinfDesign:
    """An H∞ state-feedback design ``u = -K x``.

    Attributes:
        K: (m, n) gain.
        X: (n, n) solution of the game Riccati equation at ``gamma``.
        gamma: the bound used: ‖T_zw‖∞ < gamma for the closed loop.
        gamma_opt: the smallest feasible γ found by bisection (within the tolerance).
        poles: (n,) closed-loop poles.
    """

    K: np.ndarray
    X: np.ndarray
    gamma: float
    gamma_opt: float
    poles: np.ndarray


def _game_riccati(
    a: np.ndarray, b2: np.ndarray, b1: np.ndarray, q: np.ndarray, r: np.ndarray, gamma: float
) -> np.ndarray | None:
    """Stabilising X >= 0 of AᵀX + XA - X(B2R⁻¹B2ᵀ - γ⁻²B1B1ᵀ)X + Q = 0, or None."""
    x = care(a, b2 @ np.linalg.solve(r, b2.T) - b1 @ b1.T / gamma**2, q)
    if x is None or np.min(np.linalg.eigvalsh(x)) < -1e-9 * max(1.0, float(np.max(np.abs(x)))):
        return None
    return x


def hinf_state_feedback(
    A: Any,
    B2: Any,
    B1: Any,
    Q: Any,
    R: Any,
    gamma: float | None = None,
    *,
    suboptimality: float = 1.2,
    rtol: float = 1e-3,
) -> HinfDesign:
    """H∞ state feedback for ẋ = Ax + B1 w + B2 u with performance z = [Q^½ x; R^½ u].

    Finds ``u = -K x``, ``K = R⁻¹B2ᵀX``, with X the stabilising solution of the game Riccati equation
    ``AᵀX + XA - X(B2R⁻¹B2ᵀ - γ⁻²B1B1ᵀ)X + Q = 0``, which guarantees ‖T_zw‖∞ < γ. Without ``gamma`` the optimum
    γ_opt is bracketed by doubling and bisected to ``rtol``; the design then uses ``suboptimality · γ_opt``
    (a central, better-conditioned controller than the optimum).

    Args:
        A: (n, n); B2: (n, m) control input; B1: (n, k) disturbance input; Q: (n, n) PSD; R: (m, m) PD.
        gamma: a fixed bound (skips the bisection; still checked feasible).
        suboptimality: factor > 1 on γ_opt.
        rtol: relative bisection tolerance.

    Raises:
        DesignError: no γ up to 1e8 is feasible, or the requested ``gamma`` is infeasible.
    """
    a, b2, b1, q, r = _as2d(A, "A"), _as2d(B2, "B2"), _as2d(B1, "B1"), _as2d(Q, "Q"), _as2d(R, "R")
    if gamma is not None:
        x = _game_riccati(a, b2, b1, q, r, gamma)
        if x is None:
            raise DesignError(f"gamma = {gamma} is infeasible (no stabilising game Riccati solution)")
        gamma_opt = math.nan
    else:
        if not suboptimality > 1.0:
            raise InvalidParameterError(f"suboptimality must be > 1, got {suboptimality}")

        def feasible(g: float) -> bool:
            return _game_riccati(a, b2, b1, q, r, g) is not None

        hi = lo = 1.0
        if feasible(hi):
            while feasible(lo) and lo > 1e-8:
                hi, lo = lo, lo / 4.0
        else:
            while not feasible(hi):
                lo, hi = hi, hi * 4.0
                if hi > 1e8:
                    raise DesignError("no feasible gamma below 1e8 (is (A, B2) stabilisable?)")
        while hi - lo > rtol * hi:
            mid = 0.5 * (lo + hi)
            if _game_riccati(a, b2, b1, q, r, mid) is None:
                lo = mid
            else:
                hi = mid
        gamma_opt = hi
        gamma = suboptimality * hi
        x = _game_riccati(a, b2, b1, q, r, gamma)
        if x is None:  # pragma: no cover - feasibility is monotone in γ
            raise DesignError("H∞ design failed at the suboptimal gamma")
    k = np.linalg.solve(r, b2.T @ x)
    poles = np.linalg.eigvals(a - b2 @ k)
    return HinfDesign(k, x, float(gamma), float(gamma_opt), poles)


def hinf_norm(A: Any, B: Any, C: Any, D: Any = None, *, w_min: float = 1e-3, w_max: float = 1e4) -> float:
    """H∞ norm (peak largest singular value over frequency) of a stable system, by a log grid + golden refine."""
    a, b, c = _as2d(A, "A"), _as2d(B, "B"), _as2d(C, "C")
    d = np.zeros((c.shape[0], b.shape[1])) if D is None else _as2d(D, "D")
    n = a.shape[0]

    def sv(w: float) -> float:
        g = c @ np.linalg.solve(1j * w * np.eye(n) - a, b) + d
        return float(np.linalg.svd(g, compute_uv=False)[0])

    ws = np.logspace(math.log10(w_min), math.log10(w_max), 600)
    vals = np.array([sv(w) for w in ws])
    i = int(np.argmax(vals))
    lo, hi = ws[max(i - 1, 0)], ws[min(i + 1, ws.size - 1)]
    for _ in range(60):
        m1, m2 = lo + 0.382 * (hi - lo), lo + 0.618 * (hi - lo)
        if sv(m1) > sv(m2):
            hi = m2
        else:
            lo = m1
    return max(float(vals.max()), sv(0.5 * (lo + hi)), sv(0.0) if np.all(np.linalg.eigvals(a).real < 0) else 0.0)


# ---------------------------------------------------------------------------------------------------------------
# margins


@dataclass(frozen=True)
class Margins:
    """Classical margins of a loop broken at one plant input.

    Attributes:
        gain_margin_db: how much the loop gain may rise before instability, dB (inf: never).
        gain_reduction_margin_db: how much it may fall, dB, as a negative number (-inf: never).
        phase_margin_deg: phase margin at the gain crossover, degrees (inf: no crossover).
        crossover_rad_s: gain-crossover frequency, rad/s (nan: none).
    """

    gain_margin_db: float
    gain_reduction_margin_db: float
    phase_margin_deg: float
    crossover_rad_s: float

    def meets(self, gain_db: float = 6.0, phase_deg: float = 45.0) -> bool:
        """True when both gain margins are at least ``gain_db`` and the phase margin at least ``phase_deg``."""
        return (
            self.gain_margin_db >= gain_db
            and -self.gain_reduction_margin_db >= gain_db
            and self.phase_margin_deg >= phase_deg
        )


def loop_margins(
    A: Any,
    B: Any,
    K: Any,
    channel: int = 0,
    *,
    actuator_lag_s: float = 0.0,
    w_min: float = 1e-3,
    w_max: float = 1e4,
    points: int = 3000,
) -> Margins:
    """Gain and phase margins of ``u = -K x`` on ẋ = Ax + Bu, broken at input ``channel``.

    The other inputs stay closed. The loop transfer is ``L(s) = K_i (sI - A + B_o K_o)⁻¹ B_i / (1 + s·lag)``
    (an optional first-order actuator lag the design did not model). Crossings are located on a log frequency
    grid and refined with Brent's method.
    """
    a, b, k = _as2d(A, "A"), _as2d(B, "B"), _as2d(K, "K")
    n = a.shape[0]
    others = [j for j in range(b.shape[1]) if j != channel]
    a_o = a - b[:, others] @ k[others, :] if others else a
    bi, ki = b[:, channel], k[channel, :]
    eye = np.eye(n)

    def loop(w: float) -> complex:
        val = ki @ np.linalg.solve(1j * w * eye - a_o, bi)
        return complex(val / (1.0 + 1j * w * actuator_lag_s))

    ws = np.logspace(math.log10(w_min), math.log10(w_max), points)
    big = np.linalg.solve(1j * ws[:, None, None] * eye - a_o, np.broadcast_to(bi, (points, n))[..., None])[..., 0]
    ls = (big @ ki) / (1.0 + 1j * ws * actuator_lag_s)
    mag = np.abs(ls)
    # phase crossovers: Im L = 0 with Re L < 0
    gm_up, gm_down = math.inf, -math.inf
    im = ls.imag
    for i in np.flatnonzero(np.sign(im[:-1]) * np.sign(im[1:]) < 0):
        w = brentq(lambda x: loop(x).imag, ws[i], ws[i + 1])
        lv = loop(w)
        if lv.real < 0:
            g = -20.0 * math.log10(abs(lv))
            if g > 0:
                gm_up = min(gm_up, g)
            else:
                gm_down = max(gm_down, g)
    pm, wc = math.inf, math.nan
    for i in np.flatnonzero(np.sign(mag[:-1] - 1.0) * np.sign(mag[1:] - 1.0) < 0):
        w = brentq(lambda x: abs(loop(x)) - 1.0, ws[i], ws[i + 1])
        ph = math.degrees(math.atan2(loop(w).imag, loop(w).real))  # in (-180, 180]
        margin = 180.0 + ph if ph <= 0 else 180.0 - ph
        if margin < pm:
            pm, wc = margin, w
    return Margins(gm_up, gm_down, pm, wc)


# ---------------------------------------------------------------------------------------------------------------
# RPT outer loop and loop separation


@dataclass(frozen=True)
class RptGains:
    """RPT gains for ``u = a_r + kp e + kd ė + ki ∫e`` (per axis, double-integrator plant), at tuning ε."""

    kp: float
    kd: float
    ki: float
    eps: float


def rpt_gains(eps: float, omega_n: float = 1.0, zeta: float = 0.9, p: float = 1.0) -> RptGains:
    """Chen et al.'s RPT gains: the closed-loop polynomial is ``(s² + 2ζωₙ s/ε + ωₙ²/ε²)(s + p/ε)``.

    ``kd = (2ζωₙ + p)/ε``, ``kp = (ωₙ² + 2ζωₙp)/ε²``, ``ki = ωₙ²p/ε³``, so the poles are the ε = 1 poles
    times 1/ε: a smaller ε tracks faster and more tightly.

    Raises:
        InvalidParameterError: non-positive ε, ωₙ, ζ or p.
    """
    for name, v in {"eps": eps, "omega_n": omega_n, "zeta": zeta, "p": p}.items():
        if not v > 0.0:
            raise InvalidParameterError(f"{name} must be > 0, got {v}")
    return RptGains(
        kp=(omega_n**2 + 2.0 * zeta * omega_n * p) / eps**2,
        kd=(2.0 * zeta * omega_n + p) / eps,
        ki=omega_n**2 * p / eps**3,
        eps=eps,
    )


def rpt_poles(gains: RptGains) -> np.ndarray:
    """(3,) closed-loop poles of the RPT loop on a double integrator: roots of s³ + kd s² + kp s + ki."""
    return np.roots([1.0, gains.kd, gains.kp, gains.ki])


class RptController:
    """RPT outer loop on NED axes: ``a_cmd = a_r + kp e + kd ė + ki ∫e``, e = reference - measured position.

    Args:
        gains: from `rpt_gains`.
        accel_limit: optional bound on each command axis, m/s²; the integrator is frozen while saturated.
    """

    def __init__(self, gains: RptGains, accel_limit: float = math.inf) -> None:
        self.gains = gains
        self.accel_limit = accel_limit
        self.integral = np.zeros(3)

    def reset(self) -> None:
        """Zero the integral of the position error."""
        self.integral[:] = 0.0

    def update(self, pos_ref: Any, vel_ref: Any, acc_ref: Any, pos: Any, vel: Any, dt: float) -> np.ndarray:
        """(3,) acceleration command, m/s², from references and measurements (NED, m, m/s, m/s²)."""
        g = self.gains
        return _rpt_step(
            (g.kp, g.kd, g.ki, self.accel_limit, dt),
            self.integral,
            np.asarray(pos_ref, dtype=np.float64),
            np.asarray(vel_ref, dtype=np.float64),
            np.asarray(acc_ref, dtype=np.float64),
            np.asarray(pos, dtype=np.float64),
            np.asarray(vel, dtype=np.float64),
        )


@njit(cache=True)
def _rpt_step(
    k: tuple[float, float, float, float, float],
    integral: np.ndarray,
    pos_ref: np.ndarray,
    vel_ref: np.ndarray,
    acc_ref: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
) -> np.ndarray:
    """`RptController.update` with ``k = (kp, kd, ki, accel limit, dt)``; ``integral`` (3,) is updated in place
    (not while an axis is saturated)."""
    kp, kd, ki, limit, dt = k
    u = np.empty(3)
    for i in range(3):
        e = pos_ref[i] - pos[i]
        grown = integral[i] + e * dt
        ui = acc_ref[i] + kp * e + kd * (vel_ref[i] - vel[i]) + ki * grown
        if abs(ui) > limit:
            u[i] = min(max(ui, -limit), limit)
        else:
            u[i] = ui
            integral[i] = grown
    return u


def closed_loop_bandwidth(A: Any, B: Any, C: Any, D: Any = None, *, w_max: float = 1e5) -> float:
    """-3 dB bandwidth (rad/s) of a stable SISO closed loop (A, B, C, D) relative to its DC gain."""
    a, b, c = _as2d(A, "A"), _as2d(B, "B"), _as2d(C, "C")
    d = 0.0 if D is None else float(np.asarray(D).reshape(-1)[0])
    n = a.shape[0]

    def mag(w: float) -> float:
        return float(abs((c @ np.linalg.solve(1j * w * np.eye(n) - a, b)).reshape(-1)[0] + d))

    dc = mag(0.0)
    target = dc / math.sqrt(2.0)
    ws = np.logspace(-4, math.log10(w_max), 800)
    vals = np.array([mag(w) for w in ws])
    below = np.flatnonzero(vals < target)
    if below.size == 0:
        return math.inf
    i = int(below[0])
    if i == 0:
        return float(ws[0])
    return float(brentq(lambda w: mag(w) - target, ws[i - 1], ws[i]))


def check_loop_separation(outer_poles: Any, inner_bandwidth_rad_s: float, factor: float = 1.5) -> float:
    """Reject an outer loop whose poles come within ``factor`` of the inner loop's bandwidth.

    Args:
        outer_poles: outer-loop closed-loop poles (complex or real), rad/s.
        inner_bandwidth_rad_s: the inner loop's bandwidth, rad/s.
        factor: required ratio inner bandwidth / fastest outer pole magnitude.

    Returns:
        The separation ratio ``inner_bandwidth / max|pole|``.

    Raises:
        LoopSeparationError: the ratio is below ``factor``.
    """
    poles = np.atleast_1d(np.asarray(outer_poles, dtype=np.complex128))
    fastest = float(np.max(np.abs(poles)))
    ratio = math.inf if fastest == 0.0 else inner_bandwidth_rad_s / fastest
    if ratio < factor:
        raise LoopSeparationError(
            f"outer-loop pole at {fastest:.3g} rad/s is within {factor}x of the inner bandwidth "
            f"{inner_bandwidth_rad_s:.3g} rad/s (ratio {ratio:.2f})"
        )
    return ratio

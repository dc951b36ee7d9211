"""Quadrotor rigid-body model: X-configuration mixer, first-order motor lag, RK4 step, hover linearisation.

Frames: NED world, FRD body, quaternion (w, x, y, z) body → NED. Rotors in the PX4 "quad X" numbering:

    rotor  position (FRD)      spin (seen from above)   yaw reaction on the body
    0      front-right (+d,+d)  counter-clockwise         +  (nose right)
    1      rear-left  (-d,-d)   counter-clockwise         +
    2      front-left (+d,-d)   clockwise                 -
    3      rear-right (-d,+d)   clockwise                 -

with ``d = arm_length_m / √2``. Rotor i at speed ω_i (rad/s) makes thrust ``T_i = k_f ω_i²`` along body -z and a
reaction torque ``± k_m ω_i²`` about body z; the body wrench is ``[T, τx, τy, τz] = M @ [T_0 … T_3]`` with
``τx = -y_i T_i``, ``τy = x_i T_i``, ``τz = s_i (k_m / k_f) T_i``. Rotor speeds follow their commands with a
first-order lag (time constant ``motor_time_constant_s``), commands clipped to [0, max_rotor_speed_rad_s].

Full state (17,): ``[p_ned (3) m, v_ned (3) m/s, q (4), ω_body (3) rad/s, rotor speeds (4) rad/s]``.
Linearised state (12,): ``[p_ned (3), v_ned (3), roll, pitch, yaw, p, q, r]`` with input
``[collective thrust deviation (N, along -z body), τx, τy, τz (N m)]``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from mjnav.aerial.errors import InvalidParameterError
from mjnav.aerial.frames import euler_from_quat, quat_from_euler

__all__ = [
    "STATE_SIZE",
    "QuadrotorParams",
    "derivative",
    "hover_linearization",
    "hover_state",
    "mix",
    "mixer_matrix",
    "reduced_state",
    "rotor_speeds_for_thrusts",
    "step",
    "wrench_from_rotor_speeds",
]

STATE_SIZE = 17
_SPIN = np.array([1.0, 1.0, -1.0, -1.0])
_SIGNS_XY = np.array([[1.0, 1.0], [-1.0, -1.0], [1.0, -1.0], [-1.0, 1.0]])


@dataclass(frozen=True)
class QuadrotorParams:
    """Physical parameters of an X-configuration quadrotor (defaults: a ~1 kg, 450 mm-class quad).

    Attributes:
        mass_kg: total mass, kg.
        arm_length_m: centre-to-rotor distance, m.
        inertia_kgm2: principal moments (Jxx, Jyy, Jzz), kg m², body FRD axes.
        thrust_coeff: k_f, N per (rad/s)².
        torque_coeff: k_m, N m per (rad/s)² (rotor drag torque).
        motor_time_constant_s: first-order rotor-speed lag, s.
        max_rotor_speed_rad_s: command limit, rad/s.
        gravity_mps2: gravity, m/s² (NED +z).
        drag_coeff_ns_per_m: linear translational drag, N per m/s.
    """

    mass_kg: float = 1.0
    arm_length_m: float = 0.17
    inertia_kgm2: tuple[float, float, float] = (0.0082, 0.0082, 0.0149)
    thrust_coeff: float = 8.5e-6
    torque_coeff: float = 1.36e-7
    motor_time_constant_s: float = 0.02
    max_rotor_speed_rad_s: float = 1100.0
    gravity_mps2: float = 9.80665
    drag_coeff_ns_per_m: float = 0.0
    _packed: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        positive = {
            "mass_kg": self.mass_kg,
            "arm_length_m": self.arm_length_m,
            "thrust_coeff": self.thrust_coeff,
            "torque_coeff": self.torque_coeff,
            "motor_time_constant_s": self.motor_time_constant_s,
            "max_rotor_speed_rad_s": self.max_rotor_speed_rad_s,
        }
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0.0):
                raise InvalidParameterError(f"{name} must be finite and > 0, got {value}")
        if len(self.inertia_kgm2) != 3 or not all(math.isfinite(j) and j > 0.0 for j in self.inertia_kgm2):
            raise InvalidParameterError(f"inertia_kgm2 must be three positive moments, got {self.inertia_kgm2}")
        if self.drag_coeff_ns_per_m < 0.0 or self.gravity_mps2 < 0.0:
            raise InvalidParameterError("drag_coeff_ns_per_m and gravity_mps2 must be >= 0")
        if self.hover_thrust_n > 4.0 * self.max_rotor_thrust_n:
            raise InvalidParameterError("the rotors cannot lift this mass (hover thrust above the maximum)")
        packed = np.array(
            [
                self.mass_kg,
                *self.inertia_kgm2,
                self.thrust_coeff,
                self.torque_coeff,
                self.motor_time_constant_s,
                self.max_rotor_speed_rad_s,
                self.gravity_mps2,
                self.drag_coeff_ns_per_m,
                self.arm_length_m / math.sqrt(2.0),
            ]
        )
        packed.setflags(write=False)
        object.__setattr__(self, "_packed", packed)

    @property
    def inertia(self) -> np.ndarray:
        """(3, 3) diagonal inertia matrix, kg m²."""
        return np.diag(self.inertia_kgm2)

    @property
    def hover_thrust_n(self) -> float:
        """Total thrust that balances gravity, N."""
        return self.mass_kg * self.gravity_mps2

    @property
    def max_rotor_thrust_n(self) -> float:
        """Thrust of one rotor at full speed, N."""
        return self.thrust_coeff * self.max_rotor_speed_rad_s**2

    @property
    def hover_rotor_speed_rad_s(self) -> float:
        """Rotor speed at hover, rad/s."""
        return math.sqrt(self.hover_thrust_n / (4.0 * self.thrust_coeff))

    @property
    def rotor_positions_m(self) -> np.ndarray:
        """(4, 2) rotor (x, y) positions in the body FRD frame, m."""
        return _SIGNS_XY * (self.arm_length_m / math.sqrt(2.0))

    @property
    def rotor_spin(self) -> np.ndarray:
        """(4,) +1 for counter-clockwise rotors (positive yaw reaction), -1 for clockwise."""
        return _SPIN.copy()

    @property
    def packed(self) -> np.ndarray:
        """Read-only parameter vector for the compiled kernels."""
        return self._packed


def mixer_matrix(params: QuadrotorParams) -> np.ndarray:
    """(4, 4) allocation matrix M with ``[T, τx, τy, τz] = M @ rotor_thrusts`` (N, N m)."""
    pos = params.rotor_positions_m
    return np.vstack([np.ones(4), -pos[:, 1], pos[:, 0], _SPIN * (params.torque_coeff / params.thrust_coeff)])


@functools.lru_cache(maxsize=16)
def _mixer_inverse(params: QuadrotorParams) -> np.ndarray:
    """Inverse of `mixer_matrix` (cached per parameter set; read-only)."""
    inv = np.linalg.inv(mixer_matrix(params))
    inv.setflags(write=False)
    return inv


def mix(params: QuadrotorParams, thrust_n: float, torque_nm: np.ndarray) -> np.ndarray:
    """Rotor thrusts (4,) N for a collective thrust (N) and body torque (3,) N m, yaw given up first.

    The roll/pitch/thrust part is allocated first; the yaw part is then scaled down (never up) until every rotor
    is within [0, max thrust]; whatever still does not fit is clipped.
    """
    tau = np.asarray(torque_nm, dtype=np.float64)
    if tau.shape != (3,):
        raise InvalidParameterError(f"torque_nm must have shape (3,), got {tau.shape}")
    return _mix_kernel(_mixer_inverse(params), float(thrust_n), tau, params.max_rotor_thrust_n)


@njit(cache=True)
def _mix_kernel(inv: np.ndarray, thrust_n: float, tau: np.ndarray, tmax: float) -> np.ndarray:
    """`mix` with the mixer inverse (4, 4) and the maximum rotor thrust (N) given."""
    base = np.empty(4)
    yaw = np.empty(4)
    for i in range(4):
        base[i] = inv[i, 0] * thrust_n + inv[i, 1] * tau[0] + inv[i, 2] * tau[1]
        yaw[i] = inv[i, 3] * tau[2]
    scale = 1.0
    for i in range(4):
        b, y = base[i], yaw[i]
        if y > 0.0 and b + y > tmax:
            scale = min(scale, max(0.0, (tmax - b) / y))
        elif y < 0.0 and b + y < 0.0:
            scale = min(scale, max(0.0, -b / y))
    out = np.empty(4)
    for i in range(4):
        out[i] = min(max(base[i] + scale * yaw[i], 0.0), tmax)
    return out


def rotor_speeds_for_thrusts(params: QuadrotorParams, thrusts_n: np.ndarray) -> np.ndarray:
    """Rotor speeds (rad/s) that make the given rotor thrusts (N), ``sqrt(T / k_f)``."""
    return np.sqrt(np.maximum(np.asarray(thrusts_n, dtype=np.float64), 0.0) / params.thrust_coeff)


def wrench_from_rotor_speeds(params: QuadrotorParams, speeds_rad_s: np.ndarray) -> tuple[float, np.ndarray]:
    """(collective thrust N, body torque (3,) N m) of the rotor speeds (4,) rad/s."""
    w = mixer_matrix(params) @ (params.thrust_coeff * np.asarray(speeds_rad_s, dtype=np.float64) ** 2)
    return float(w[0]), w[1:]


def hover_state(params: QuadrotorParams, position_ned: np.ndarray | None = None, yaw: float = 0.0) -> np.ndarray:
    """(17,) state hovering at rest at ``position_ned`` (m) with heading ``yaw`` (rad), rotors at hover speed."""
    x = np.zeros(STATE_SIZE)
    if position_ned is not None:
        x[0:3] = position_ned
    x[6:10] = quat_from_euler(0.0, 0.0, yaw)
    x[13:17] = params.hover_rotor_speed_rad_s
    return x


def reduced_state(state: np.ndarray) -> np.ndarray:
    """(12,) linearisation state ``[p, v, roll, pitch, yaw, ω]`` of a (17,) full state."""
    s = np.asarray(state, dtype=np.float64)
    return np.concatenate([s[0:6], euler_from_quat(s[6:10]), s[10:13]])


@njit(cache=True)
def _deriv(x: np.ndarray, cmd: np.ndarray, pk: np.ndarray, out: np.ndarray) -> None:
    m, jx, jy, jz, kf, km, tm, wmax, g, drag, d = (
        pk[0],
        pk[1],
        pk[2],
        pk[3],
        pk[4],
        pk[5],
        pk[6],
        pk[7],
        pk[8],
        pk[9],
        pk[10],
    )
    qw, qx, qy, qz = x[6], x[7], x[8], x[9]
    p, q, r = x[10], x[11], x[12]
    t0 = kf * x[13] * x[13]
    t1 = kf * x[14] * x[14]
    t2 = kf * x[15] * x[15]
    t3 = kf * x[16] * x[16]
    thrust = t0 + t1 + t2 + t3
    tx = d * (-t0 + t1 + t2 - t3)
    ty = d * (t0 - t1 + t2 - t3)
    tz = km / kf * (t0 + t1 - t2 - t3)
    # third column of R(q): body z in NED
    bx = 2.0 * (qx * qz + qw * qy)
    by = 2.0 * (qy * qz - qw * qx)
    bz = 1.0 - 2.0 * (qx * qx + qy * qy)
    out[0] = x[3]
    out[1] = x[4]
    out[2] = x[5]
    out[3] = (-thrust * bx - drag * x[3]) / m
    out[4] = (-thrust * by - drag * x[4]) / m
    out[5] = (-thrust * bz - drag * x[5]) / m + g
    out[6] = 0.5 * (-qx * p - qy * q - qz * r)
    out[7] = 0.5 * (qw * p + qy * r - qz * q)
    out[8] = 0.5 * (qw * q - qx * r + qz * p)
    out[9] = 0.5 * (qw * r + qx * q - qy * p)
    out[10] = (tx - (jz - jy) * q * r) / jx
    out[11] = (ty - (jx - jz) * r * p) / jy
    out[12] = (tz - (jy - jx) * p * q) / jz
    for i in range(4):
        c = min(max(cmd[i], 0.0), wmax)
        out[13 + i] = (c - x[13 + i]) / tm


@njit(cache=True)
def _rk4(x: np.ndarray, cmd: np.ndarray, dt: float, pk: np.ndarray) -> np.ndarray:
    n = x.size
    k1 = np.empty(n)
    k2 = np.empty(n)
    k3 = np.empty(n)
    k4 = np.empty(n)
    _deriv(x, cmd, pk, k1)
    _deriv(x + 0.5 * dt * k1, cmd, pk, k2)
    _deriv(x + 0.5 * dt * k2, cmd, pk, k3)
    _deriv(x + dt * k3, cmd, pk, k4)
    y = x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    nq = math.sqrt(y[6] * y[6] + y[7] * y[7] + y[8] * y[8] + y[9] * y[9])
    for i in range(6, 10):
        y[i] /= nq
    return y


def _check(state: np.ndarray, cmd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x = np.ascontiguousarray(state, dtype=np.float64)
    c = np.ascontiguousarray(cmd, dtype=np.float64)
    if x.shape != (STATE_SIZE,) or c.shape != (4,):
        raise InvalidParameterError(f"state must be (17,) and rotor command (4,), got {x.shape} and {c.shape}")
    return x, c


def derivative(state: np.ndarray, rotor_cmd_rad_s: np.ndarray, params: QuadrotorParams) -> np.ndarray:
    """Time derivative (17,) of the full state under rotor-speed commands (4,) rad/s."""
    x, c = _check(state, rotor_cmd_rad_s)
    out = np.empty(STATE_SIZE)
    _deriv(x, c, params.packed, out)
    return out


def step(state: np.ndarray, rotor_cmd_rad_s: np.ndarray, dt: float, params: QuadrotorParams) -> np.ndarray:
    """One RK4 step of ``dt`` seconds (commands held), quaternion renormalised; returns the new (17,) state."""
    x, c = _check(state, rotor_cmd_rad_s)
    if not dt > 0.0:
        raise InvalidParameterError(f"dt must be > 0, got {dt}")
    return _rk4(x, c, float(dt), params.packed)


def hover_linearization(params: QuadrotorParams) -> tuple[np.ndarray, np.ndarray]:
    """(A (12, 12), B (12, 4)) of the rigid body about hover at yaw 0 (motor lag neglected).

    State ``[pN, pE, pD, vN, vE, vD, roll, pitch, yaw, p, q, r]``, input ``[δT N, τx, τy, τz N m]`` where δT is
    the collective thrust above hover (along body -z): ``v̇N = -g·pitch``, ``v̇E = g·roll``, ``v̇D = -δT/m``,
    Euler rates = body rates, ``ω̇ = J⁻¹ τ``.
    """
    g = params.gravity_mps2
    c = params.drag_coeff_ns_per_m / params.mass_kg
    a = np.zeros((12, 12))
    a[0:3, 3:6] = np.eye(3)
    a[3:6, 3:6] = -c * np.eye(3)
    a[3, 7] = -g
    a[4, 6] = g
    a[6:9, 9:12] = np.eye(3)
    b = np.zeros((12, 4))
    b[5, 0] = -1.0 / params.mass_kg
    b[9:12, 1:4] = np.diag(1.0 / np.asarray(params.inertia_kgm2))
    return a, b

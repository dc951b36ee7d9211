"""Loosely coupled GPS/INS Kalman filter in NED with delayed-GPS fusion.

State (9,): ``[p_ned (3) m, v_ned (3) m/s, b_acc (3) m/s²]`` — position, velocity and the accelerometer bias
(expressed in NED: attitude comes from the AHRS and is not estimated here). One IMU sample of kinematic
acceleration ``a_m = R_nb f_b + g ẑ`` (m/s², NED; see `accel_ned_from_specific_force`) drives the prediction
over ``dt = 1/imu_rate_hz``:

    p⁺ = p + v dt + ½ (a_m - b) dt²,   v⁺ = v + (a_m - b) dt,   b⁺ = b

i.e. ``x⁺ = F x + G a_m`` with process noise ``Q = G σ_a² Gᵀ + diag(0, 0, σ_b² dt)`` (σ_a: accelerometer white
noise per sample, σ_b: bias random walk). A GPS fix ``y = p + v_gps``, ``R = σ_gps² I``, corrects it with the
Joseph-form update.

Delayed GPS (fixes stamped 100–200 ms before they arrive, as PX4's EKF2 handles them): the filter keeps a ring
buffer of the last ``history_s`` of states, covariances, IMU inputs and fused fixes. A fix stamped ``t`` is
fused into the buffered state nearest ``t`` and the filter replays the buffered IMU inputs (and any fixes fused
after ``t``) up to now — for this linear filter exactly what fusing it on time would have given.

The Kalman equations are the two compiled kernels `_kf_predict_into` / `_kf_update` over (F, G, Q, H, R),
allocation-free on the IMU path; they are kept minimal so a generic ``KalmanFilter(F, H, Q, R, G)`` can replace
them without touching the model or the buffering.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from mjnav.aerial.errors import InvalidParameterError, StaleMeasurementError
from mjnav.aerial.frames import body_to_ned

__all__ = [
    "GpsIns",
    "GpsInsConfig",
    "SyntheticFlight",
    "accel_ned_from_specific_force",
    "gps_ins_model",
    "run_filter",
    "synthetic_flight",
]

N_STATE = 9


@dataclass(frozen=True)
class GpsInsConfig:
    """Noise model and timing of `GpsIns`.

    Attributes:
        imu_rate_hz: IMU (prediction) rate, Hz.
        accel_noise_mps2: accelerometer white noise, standard deviation per sample, m/s².
        accel_bias_walk_mps2_per_sqrt_s: bias random walk, m/s² per √s.
        gps_sigma_m: GPS position noise, standard deviation per axis, m.
        history_s: how far back a delayed fix may be stamped, s.
        init_pos_sigma_m, init_vel_sigma_mps, init_bias_sigma_mps2: default initial standard deviations.
    """

    imu_rate_hz: float = 200.0
    accel_noise_mps2: float = 0.02
    accel_bias_walk_mps2_per_sqrt_s: float = 1e-3
    gps_sigma_m: float = 1.5
    history_s: float = 0.5
    init_pos_sigma_m: float = 3.0
    init_vel_sigma_mps: float = 0.5
    init_bias_sigma_mps2: float = 0.1

    def __post_init__(self) -> None:
        for name in (
            "imu_rate_hz",
            "accel_noise_mps2",
            "gps_sigma_m",
            "history_s",
            "init_pos_sigma_m",
            "init_vel_sigma_mps",
            "init_bias_sigma_mps2",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise InvalidParameterError(f"{name} must be finite and > 0, got {v}")
        if not self.accel_bias_walk_mps2_per_sqrt_s >= 0.0:
            raise InvalidParameterError("accel_bias_walk_mps2_per_sqrt_s must be >= 0")

    @property
    def dt_s(self) -> float:
        """IMU period, s."""
        return 1.0 / self.imu_rate_hz


def gps_ins_model(config: GpsInsConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(F (9, 9), G (9, 3), Q (9, 9), H (3, 9), R (3, 3)) of the filter at the configured IMU period."""
    dt = config.dt_s
    i3 = np.eye(3)
    f = np.eye(N_STATE)
    f[0:3, 3:6] = dt * i3
    f[0:3, 6:9] = -0.5 * dt * dt * i3
    f[3:6, 6:9] = -dt * i3
    g = np.zeros((N_STATE, 3))
    g[0:3] = 0.5 * dt * dt * i3
    g[3:6] = dt * i3
    q = config.accel_noise_mps2**2 * (g @ g.T)
    q[6:9, 6:9] += config.accel_bias_walk_mps2_per_sqrt_s**2 * dt * i3
    h = np.zeros((3, N_STATE))
    h[:, 0:3] = i3
    r = config.gps_sigma_m**2 * i3
    return f, g, q, h, r


def accel_ned_from_specific_force(
    f_body: Any, roll: float, pitch: float, yaw: float, gravity_mps2: float = 9.80665
) -> np.ndarray:
    """Kinematic acceleration (3,) NED m/s² from an accelerometer's specific force (3,) body FRD m/s².

    ``a = R_nb(roll, pitch, yaw) f_b + [0, 0, g]`` (a level vehicle at rest reads ``f_b = [0, 0, -g]``).
    """
    a = body_to_ned(np.asarray(f_body, dtype=np.float64), roll, pitch, yaw)
    a[..., 2] += gravity_mps2
    return a


@njit(cache=True)
def _kf_predict_into(
    x: np.ndarray,
    P: np.ndarray,
    u: np.ndarray,
    F: np.ndarray,
    G: np.ndarray,
    Q: np.ndarray,
    x_out: np.ndarray,
    P_out: np.ndarray,
    tmp: np.ndarray,
) -> None:
    """x_out = F x + G u;  P_out = F P Fᵀ + Q (no allocation)."""
    n = x.size
    for i in range(n):
        acc = 0.0
        for k in range(n):
            acc += F[i, k] * x[k]
        for k in range(u.size):
            acc += G[i, k] * u[k]
        x_out[i] = acc
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += F[i, k] * P[k, j]
            tmp[i, j] = acc
    for i in range(n):
        for j in range(i, n):
            acc = Q[i, j]
            for k in range(n):
                acc += tmp[i, k] * F[j, k]
            P_out[i, j] = acc
            P_out[j, i] = acc


@njit(cache=True)
def _kf_update(x: np.ndarray, P: np.ndarray, y: np.ndarray, H: np.ndarray, R: np.ndarray) -> float:
    """In-place Kalman update (Joseph form); returns the innovation's normalised squared norm (NIS)."""
    pht = P @ H.T
    s = H @ pht + R
    s_inv = np.linalg.inv(s)
    innov = y - H @ x
    k = pht @ s_inv
    x += k @ innov
    ikh = np.eye(x.size) - k @ H
    P[:, :] = ikh @ P @ ikh.T + k @ R @ k.T
    return float(innov @ s_inv @ innov)


@njit(cache=True)
def _step(
    buf_x: np.ndarray,
    buf_P: np.ndarray,
    buf_u: np.ndarray,
    buf_has: np.ndarray,
    head: int,
    u: np.ndarray,
    F: np.ndarray,
    G: np.ndarray,
    Q: np.ndarray,
    tmp: np.ndarray,
) -> int:
    nxt = (head + 1) % buf_x.shape[0]
    for i in range(u.size):
        buf_u[nxt, i] = u[i]
    buf_has[nxt] = False
    _kf_predict_into(buf_x[head], buf_P[head], u, F, G, Q, buf_x[nxt], buf_P[nxt], tmp)
    return nxt


@njit(cache=True)
def _fuse_delayed(
    buf_x: np.ndarray,
    buf_P: np.ndarray,
    buf_u: np.ndarray,
    buf_has: np.ndarray,
    buf_y: np.ndarray,
    head: int,
    age: int,
    y: np.ndarray,
    F: np.ndarray,
    G: np.ndarray,
    Q: np.ndarray,
    H: np.ndarray,
    R: np.ndarray,
    tmp: np.ndarray,
) -> float:
    n = buf_x.shape[0]
    j = (head - age) % n
    nis = _kf_update(buf_x[j], buf_P[j], y, H, R)
    buf_y[j, :] = y
    buf_has[j] = True
    for a in range(age - 1, -1, -1):
        i = (head - a) % n
        prev = (i - 1) % n
        _kf_predict_into(buf_x[prev], buf_P[prev], buf_u[i], F, G, Q, buf_x[i], buf_P[i], tmp)
        if buf_has[i]:
            _kf_update(buf_x[i], buf_P[i], buf_y[i], H, R)
    return nis


class GpsIns:
    """GPS/INS filter: 100–200 Hz IMU prediction, 5–10 Hz GPS correction, delayed fixes fused by replay.

    Args:
        config: noise model and rates.
        x0: (9,) initial state ``[p, v, b]`` (default zeros).
        P0: (9, 9) initial covariance (default from the config's initial sigmas).
        t0_s: time of the initial state, s.
    """

    def __init__(self, config: GpsInsConfig | None = None, x0: Any = None, P0: Any = None, t0_s: float = 0.0) -> None:
        self.config = config or GpsInsConfig()
        c = self.config
        self.F, self.G, self.Q, self.H, self.R = gps_ins_model(c)
        size = max(2, math.ceil(c.history_s * c.imu_rate_hz) + 2)
        self._buf_x = np.zeros((size, N_STATE))
        self._buf_P = np.zeros((size, N_STATE, N_STATE))
        self._buf_u = np.zeros((size, 3))
        self._buf_y = np.zeros((size, 3))
        self._buf_has = np.zeros(size, dtype=np.bool_)
        self._tmp = np.zeros((N_STATE, N_STATE))
        self._head = 0
        self._count = 1
        self._steps = 0
        self.t0_s = float(t0_s)
        if x0 is not None:
            x = np.asarray(x0, dtype=np.float64)
            if x.shape != (N_STATE,):
                raise InvalidParameterError(f"x0 must have shape (9,), got {x.shape}")
            self._buf_x[0] = x
        if P0 is not None:
            p = np.asarray(P0, dtype=np.float64)
            if p.shape != (N_STATE, N_STATE):
                raise InvalidParameterError(f"P0 must have shape (9, 9), got {p.shape}")
            self._buf_P[0] = p
        else:
            sig = [c.init_pos_sigma_m] * 3 + [c.init_vel_sigma_mps] * 3 + [c.init_bias_sigma_mps2] * 3
            self._buf_P[0] = np.diag(np.square(sig))
        self.last_nis = math.nan

    @property
    def t_s(self) -> float:
        """Time of the current estimate, s."""
        return self.t0_s + self._steps / self.config.imu_rate_hz

    @property
    def x(self) -> np.ndarray:
        """(9,) current state estimate (a copy)."""
        return self._buf_x[self._head].copy()

    @property
    def P(self) -> np.ndarray:  # noqa: N802 - the usual name of a covariance
        """(9, 9) current covariance (a copy)."""
        return self._buf_P[self._head].copy()

    @property
    def position(self) -> np.ndarray:
        """(3,) NED position estimate, m."""
        return self._buf_x[self._head, 0:3].copy()

    @property
    def velocity(self) -> np.ndarray:
        """(3,) NED velocity estimate, m/s."""
        return self._buf_x[self._head, 3:6].copy()

    @property
    def accel_bias(self) -> np.ndarray:
        """(3,) accelerometer bias estimate (NED), m/s²."""
        return self._buf_x[self._head, 6:9].copy()

    def predict(self, accel_ned: np.ndarray) -> None:
        """Propagate one IMU period with a kinematic acceleration sample (3,) NED m/s² (gravity removed)."""
        u = accel_ned if type(accel_ned) is np.ndarray else np.asarray(accel_ned, dtype=np.float64)
        if u.shape != (3,) or u.dtype != np.float64:
            u = np.asarray(u, dtype=np.float64).reshape(3)
        self._head = _step(
            self._buf_x, self._buf_P, self._buf_u, self._buf_has, self._head, u, self.F, self.G, self.Q, self._tmp
        )
        if self._count < self._buf_x.shape[0]:
            self._count += 1
        self._steps += 1

    def update_gps(self, position_ned: Any, stamp_s: float | None = None) -> float:
        """Fuse a GPS position fix (3,) NED m taken at ``stamp_s`` (default: now).

        The fix is fused at the buffered IMU sample nearest its stamp and the later samples are replayed.

        Returns:
            The fix's normalised innovation squared (χ²₃ when the filter is consistent).

        Raises:
            StaleMeasurementError: the stamp is older than the history or later than the current time.
        """
        y = np.asarray(position_ned, dtype=np.float64).reshape(3)
        age = 0 if stamp_s is None else round((self.t_s - stamp_s) * self.config.imu_rate_hz)
        if age < 0:
            raise StaleMeasurementError(f"fix stamped {stamp_s} s is after the filter time {self.t_s} s")
        if age > self._count - 1:
            raise StaleMeasurementError(
                f"fix stamped {stamp_s} s is older than the {self.config.history_s} s history (now {self.t_s} s)"
            )
        self.last_nis = _fuse_delayed(
            self._buf_x,
            self._buf_P,
            self._buf_u,
            self._buf_has,
            self._buf_y,
            self._head,
            age,
            y,
            self.F,
            self.G,
            self.Q,
            self.H,
            self.R,
            self._tmp,
        )
        return self.last_nis


@dataclass(frozen=True)
class SyntheticFlight:
    """A seeded synthetic flight consistent with the filter's model.

    Attributes:
        t_s: (K,) IMU sample times (time after each sample's prediction), s.
        position, velocity, bias: (K, 3) true NED position m, velocity m/s, accelerometer bias m/s².
        accel_meas: (K, 3) IMU kinematic-acceleration samples (true acceleration + bias + white noise), m/s².
        gps_index: (M,) IMU index at which each fix was taken.
        gps_arrival_index: (M,) IMU index after which each fix arrives (taken + delay).
        gps_position: (M, 3) fixes (true position + N(0, σ_gps²)), m.
        x0: (9,) true initial state (drawn around zero with the config's initial sigmas).
    """

    t_s: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    bias: np.ndarray
    accel_meas: np.ndarray
    gps_index: np.ndarray
    gps_arrival_index: np.ndarray
    gps_position: np.ndarray
    x0: np.ndarray


def synthetic_flight(
    rng: np.random.Generator,
    config: GpsInsConfig | None = None,
    duration_s: float = 60.0,
    gps_rate_hz: float = 5.0,
    gps_delay_s: float = 0.15,
) -> SyntheticFlight:
    """A figure-eight climb sampled at the IMU rate, with noisy IMU and delayed noisy GPS (seeded).

    The truth is propagated with the filter's own discrete model (so NEES is χ²₉ for a consistent filter); the
    initial truth is drawn from N(0, P0) of the config's initial sigmas.
    """
    c = config or GpsInsConfig()
    dt = c.dt_s
    k = round(duration_s * c.imu_rate_hz)
    t = (np.arange(k) + 1) * dt
    w = 2.0 * math.pi / 20.0
    a_true = np.column_stack(
        [-8.0 * w * w * np.sin(w * t), -4.0 * (2 * w) ** 2 * np.sin(2 * w * t), -0.5 * (w / 2) ** 2 * np.cos(w * t / 2)]
    )
    sig0 = np.array([c.init_pos_sigma_m] * 3 + [c.init_vel_sigma_mps] * 3 + [c.init_bias_sigma_mps2] * 3)
    x0 = rng.normal(size=9) * sig0
    bias = x0[6:9] + np.cumsum(rng.normal(size=(k, 3)) * c.accel_bias_walk_mps2_per_sqrt_s * math.sqrt(dt), axis=0)
    bias_prev = np.vstack([x0[6:9], bias[:-1]])
    accel_meas = a_true + bias_prev + rng.normal(size=(k, 3)) * c.accel_noise_mps2
    # truth: p+ = p + v dt + ½ a dt²;  v+ = v + a dt (a = a_meas - b - noise = the true acceleration)
    vel = x0[3:6] + np.cumsum(a_true * dt, axis=0)
    vel_prev = np.vstack([x0[3:6], vel[:-1]])
    pos = x0[0:3] + np.cumsum(vel_prev * dt + 0.5 * a_true * dt * dt, axis=0)
    stride = round(c.imu_rate_hz / gps_rate_hz)
    delay = round(gps_delay_s * c.imu_rate_hz)
    idx = np.arange(stride - 1, k, stride)
    arrival = idx + delay
    keep = arrival < k
    idx, arrival = idx[keep], arrival[keep]
    gps = pos[idx] + rng.normal(size=(idx.size, 3)) * c.gps_sigma_m
    return SyntheticFlight(t, pos, vel, bias, accel_meas, idx, arrival, gps, x0)


def run_filter(flight: SyntheticFlight, config: GpsInsConfig | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Run `GpsIns` over a synthetic flight (fixes fused on arrival, with their stamps).

    Returns:
        ((K, 9) state estimates after each IMU sample (and any fix arriving then), (K, 9, 9) covariances).
    """
    c = config or GpsInsConfig()
    ins = GpsIns(c)
    k = flight.t_s.size
    xs = np.empty((k, N_STATE))
    ps = np.empty((k, N_STATE, N_STATE))
    arrivals: dict[int, list[int]] = {}
    for m, a in enumerate(flight.gps_arrival_index):
        arrivals.setdefault(int(a), []).append(m)
    for i in range(k):
        ins.predict(flight.accel_meas[i])
        for m in arrivals.get(i, ()):
            ins.update_gps(flight.gps_position[m], stamp_s=float(flight.t_s[flight.gps_index[m]]))
        xs[i] = ins._buf_x[ins._head]
        ps[i] = ins._buf_P[ins._head]
    return xs, ps

"""Loosely coupled GPS/baro/INS Kalman filter in NED with delayed fusion and innovation gating.

State (10,): ``[p_ned (3) m, v_ned (3) m/s, b_acc (3) m/s², b_baro (1) m]`` — position, velocity, the
accelerometer bias (expressed in NED: attitude comes from the AHRS and is not estimated here) and the barometer's
offset (its altitude minus the true altitude above the datum: weather and calibration; PX4's EKF2 estimates the same
bias of a height source that is not its reference). One IMU sample of kinematic acceleration
``a_m = R_nb f_b + g ẑ`` (m/s², NED; see `accel_ned_from_specific_force`) drives the prediction over
``dt = 1/imu_rate_hz``:

    p⁺ = p + v dt + ½ (a_m - b) dt²,   v⁺ = v + (a_m - b) dt,   b⁺ = b,   b_baro⁺ = b_baro

i.e. ``x⁺ = F x + G a_m`` with process noise ``Q = G σ_a² Gᵀ + diag(0, 0, σ_b² dt, σ_h² dt)`` (σ_a: accelerometer
white noise per sample, σ_b: bias random walk, σ_h: baro offset random walk). A GPS fix ``y = p + v_gps``,
``R = σ_gps² I``, and a barometric altitude above the datum ``h = -p_d + b_baro + v_baro``, ``R = σ_baro²``
(`isa_altitude_m` turns a static pressure into an altitude), correct it with the Joseph-form update.

Innovation gating (PX4 EKF2's innovation consistency test): a measurement whose normalised innovation squared
``NIS = νᵀ S⁻¹ ν`` (χ² with 3 / 1 degrees of freedom when the filter is consistent) exceeds its gate is rejected and
counted (`AidingStats`); the filter is left as it was. A long run of rejections must not lock the filter out for
ever (a filter that drifted during an outage would reject every good fix after it): when no measurement of a kind
passed its gate for ``reset_timeout_s`` (by the measurements' stamps), the next one that fails the gate resets the
filter to it — the measured states (position; the baro offset) lose their covariance with the rest and are fused as
if unknown — as EKF2 resets to GPS after its reset timeout. The price: after such a timeout a single outlier is
believed; a glitch that lasts longer than the timeout is followed.

Delayed measurements (fixes stamped 100–200 ms before they arrive, as PX4's EKF2 handles them): the filter keeps
a ring buffer of the last ``history_s`` of states, covariances, IMU inputs and fused measurements. A measurement
stamped ``t`` is fused into the buffered state nearest ``t`` and the filter replays the buffered IMU inputs (and the
measurements fused after ``t``) up to now — for this linear filter exactly what fusing it on time would have given.

The Kalman equations are the compiled kernels `_kf_predict_into` / `_kf_update` over (F, G, Q, H, R),
allocation-free on the IMU path; they are kept minimal so a generic ``KalmanFilter(F, H, Q, R, G)`` can replace
them without touching the model or the buffering.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from mjnav.aerial.errors import InvalidParameterError, StaleMeasurementError
from mjnav.aerial.frames import body_to_ned

__all__ = [
    "AidingStats",
    "Fusion",
    "GpsIns",
    "GpsInsConfig",
    "SyntheticFlight",
    "accel_ned_from_specific_force",
    "baro_model",
    "gps_ins_model",
    "isa_altitude_m",
    "isa_pressure_pa",
    "run_filter",
    "synthetic_flight",
]

N_STATE = 10
#: Index of the barometer's offset in the state.
BARO_OFFSET = 9
#: Variance (m²) a reset gives the states it resets before the measurement is fused: "unknown" beside any
#: measurement noise.
_RESET_VARIANCE = 1e8
_GPS, _BARO = 0, 1
#: ISA troposphere: sea-level pressure (Pa), temperature (K), lapse rate (K/m), and the exponent g M / (R L).
_P0_PA, _T0_K, _LAPSE, _EXP = 101325.0, 288.15, 0.0065, 5.25588


def isa_pressure_pa(altitude_m: float) -> float:
    """ISA troposphere static pressure (Pa) at ``altitude_m`` (m above mean sea level)."""
    return _P0_PA * (1.0 - _LAPSE * altitude_m / _T0_K) ** _EXP


def isa_altitude_m(pressure_pa: float) -> float:
    """Pressure altitude (m above mean sea level) of a static pressure (Pa) in the ISA troposphere; the inverse of
    `isa_pressure_pa`.

    Raises:
        InvalidParameterError: the pressure is not a finite positive number.
    """
    if not (math.isfinite(pressure_pa) and pressure_pa > 0.0):
        raise InvalidParameterError(f"static pressure must be finite and > 0 Pa, got {pressure_pa}")
    return _T0_K / _LAPSE * (1.0 - (pressure_pa / _P0_PA) ** (1.0 / _EXP))


@dataclass(frozen=True)
class GpsInsConfig:
    """Noise model, gates and timing of `GpsIns`.

    Attributes:
        imu_rate_hz: IMU (prediction) rate, Hz.
        accel_noise_mps2: accelerometer white noise, standard deviation per sample, m/s².
        accel_bias_walk_mps2_per_sqrt_s: bias random walk, m/s² per √s.
        gps_sigma_m: GPS position noise, standard deviation per axis, m.
        baro_sigma_m: barometric altitude noise, standard deviation, m.
        baro_offset_walk_m_per_sqrt_s: random walk of the barometer's offset, m per √s.
        history_s: how far back a delayed measurement may be stamped, s.
        init_pos_sigma_m, init_vel_sigma_mps, init_bias_sigma_mps2, init_baro_offset_sigma_m: default initial
            standard deviations.
        gps_gate_nis: a fix whose NIS exceeds this is rejected (χ²₃: 25 rejects 1 good fix in 60 000; inf: no gate).
        baro_gate_nis: the same for the barometer (χ²₁: 25 is a 5σ gate, as EKF2's default).
        reset_timeout_s: after this long (by the stamps) without a measurement of a kind passing its gate, the next
            one resets the filter to it, s.
    """

    imu_rate_hz: float = 200.0
    accel_noise_mps2: float = 0.02
    accel_bias_walk_mps2_per_sqrt_s: float = 1e-3
    gps_sigma_m: float = 1.5
    baro_sigma_m: float = 0.2
    baro_offset_walk_m_per_sqrt_s: float = 0.005
    history_s: float = 0.5
    init_pos_sigma_m: float = 3.0
    init_vel_sigma_mps: float = 0.5
    init_bias_sigma_mps2: float = 0.1
    init_baro_offset_sigma_m: float = 10.0
    gps_gate_nis: float = 25.0
    baro_gate_nis: float = 25.0
    reset_timeout_s: float = 5.0

    def __post_init__(self) -> None:
        for name in (
            "imu_rate_hz",
            "accel_noise_mps2",
            "gps_sigma_m",
            "baro_sigma_m",
            "history_s",
            "init_pos_sigma_m",
            "init_vel_sigma_mps",
            "init_bias_sigma_mps2",
            "init_baro_offset_sigma_m",
            "reset_timeout_s",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise InvalidParameterError(f"{name} must be finite and > 0, got {v}")
        for name in ("accel_bias_walk_mps2_per_sqrt_s", "baro_offset_walk_m_per_sqrt_s"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0.0):
                raise InvalidParameterError(f"{name} must be finite and >= 0, got {getattr(self, name)}")
        for name in ("gps_gate_nis", "baro_gate_nis"):
            if not getattr(self, name) > 0.0:  # inf: no gate
                raise InvalidParameterError(f"{name} must be > 0 (inf: no gate), got {getattr(self, name)}")

    @property
    def dt_s(self) -> float:
        """IMU period, s."""
        return 1.0 / self.imu_rate_hz


def gps_ins_model(config: GpsInsConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(F (10, 10), G (10, 3), Q (10, 10), H (3, 10), R (3, 3)) of the filter and its GPS fix at the configured IMU
    period."""
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
    q[BARO_OFFSET, BARO_OFFSET] = config.baro_offset_walk_m_per_sqrt_s**2 * dt
    h = np.zeros((3, N_STATE))
    h[:, 0:3] = i3
    r = config.gps_sigma_m**2 * i3
    return f, g, q, h, r


def baro_model(config: GpsInsConfig) -> tuple[np.ndarray, np.ndarray]:
    """(H (1, 10), R (1, 1)) of a barometric altitude above the datum: ``h = -p_d + b_baro``."""
    h = np.zeros((1, N_STATE))
    h[0, 2], h[0, BARO_OFFSET] = -1.0, 1.0
    return h, np.array([[config.baro_sigma_m**2]])


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
    gps_has: np.ndarray,
    baro_has: np.ndarray,
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
    gps_has[nxt] = False
    baro_has[nxt] = False
    _kf_predict_into(buf_x[head], buf_P[head], u, F, G, Q, buf_x[nxt], buf_P[nxt], tmp)
    return nxt


@njit(cache=True)
def _fuse_delayed(
    buf_x: np.ndarray,
    buf_P: np.ndarray,
    buf_u: np.ndarray,
    gps_y: np.ndarray,
    gps_has: np.ndarray,
    baro_y: np.ndarray,
    baro_has: np.ndarray,
    head: int,
    age: int,
    kind: int,
    y: np.ndarray,
    gate: float,
    reset: bool,
    reset_states: np.ndarray,
    F: np.ndarray,
    G: np.ndarray,
    Q: np.ndarray,
    Hg: np.ndarray,
    Rg: np.ndarray,
    Hb: np.ndarray,
    Rb: np.ndarray,
    tmp: np.ndarray,
) -> tuple[float, int]:
    """Gate and fuse measurement ``y`` of ``kind`` (GPS or baro) at the buffered sample ``age`` steps back, then
    replay to the head. Returns (NIS before the update, 0 rejected / 1 fused / 2 fused as a reset)."""
    n = buf_x.shape[0]
    j = (head - age) % n
    H, R = (Hg, Rg) if kind == _GPS else (Hb, Rb)
    x, P = buf_x[j], buf_P[j]
    pht = P @ H.T
    s_inv = np.linalg.inv(H @ pht + R)
    innov = y - H @ x
    nis = float(innov @ s_inv @ innov)
    if nis <= gate:
        outcome = 1
        k = pht @ s_inv  # the update of `_kf_update`, with the innovation's covariance already at hand
        x += k @ innov
        ikh = np.eye(x.size) - k @ H
        P[:, :] = ikh @ P @ ikh.T + k @ R @ k.T
    elif reset:
        outcome = 2
        for s in reset_states:
            for c in range(P.shape[0]):
                P[s, c] = 0.0
                P[c, s] = 0.0
            P[s, s] = _RESET_VARIANCE
        _kf_update(x, P, y, H, R)
    else:
        return nis, 0
    if kind == _GPS:
        gps_y[j, :] = y
        gps_has[j] = True
    else:
        baro_y[j, :] = y
        baro_has[j] = True
    for a in range(age - 1, -1, -1):
        i = (head - a) % n
        prev = (i - 1) % n
        _kf_predict_into(buf_x[prev], buf_P[prev], buf_u[i], F, G, Q, buf_x[i], buf_P[i], tmp)
        if gps_has[i]:
            _kf_update(buf_x[i], buf_P[i], gps_y[i], Hg, Rg)
        if baro_has[i]:
            _kf_update(buf_x[i], buf_P[i], baro_y[i], Hb, Rb)
    return nis, outcome


@dataclass(frozen=True)
class Fusion:
    """What became of one measurement.

    Attributes:
        nis: its normalised innovation squared before the update (χ² with the measurement's dimension when the
            filter is consistent).
        fused: it was fused (passed the gate, or reset the filter).
        reset: it failed the gate after the reset timeout and reset the filter to it.
    """

    nis: float
    fused: bool
    reset: bool


@dataclass
class AidingStats:
    """Counters of one aiding sensor of `GpsIns` (GPS or barometer).

    Attributes:
        fused: measurements fused (resets included).
        rejected: measurements that failed the gate (and did not reset the filter).
        resets: measurements that reset the filter after the reset timeout.
        last_fused_s: stamp of the newest fused measurement (the filter's start before the first), s.
        last_nis: NIS of the newest measurement, fused or not (NaN before the first).
    """

    fused: int = 0
    rejected: int = 0
    resets: int = 0
    last_fused_s: float = 0.0
    last_nis: float = field(default=math.nan)


class GpsIns:
    """GPS/baro/INS filter: 100–200 Hz IMU prediction, 5–10 Hz GPS and 25 Hz barometer corrections, each gated,
    delayed measurements fused by replay.

    Args:
        config: noise model, gates and rates.
        x0: (10,) initial state ``[p, v, b, b_baro]`` (default zeros).
        P0: (10, 10) initial covariance (default from the config's initial sigmas).
        t0_s: time of the initial state, s.

    Attributes:
        gps, baro: `AidingStats` of the two aiding sensors.
    """

    def __init__(self, config: GpsInsConfig | None = None, x0: Any = None, P0: Any = None, t0_s: float = 0.0) -> None:
        self.config = config or GpsInsConfig()
        c = self.config
        self.F, self.G, self.Q, self.H, self.R = gps_ins_model(c)
        self.H_baro, self.R_baro = baro_model(c)
        size = max(2, math.ceil(c.history_s * c.imu_rate_hz) + 2)
        self._buf_x = np.zeros((size, N_STATE))
        self._buf_P = np.zeros((size, N_STATE, N_STATE))
        self._buf_u = np.zeros((size, 3))
        self._gps_y = np.zeros((size, 3))
        self._gps_has = np.zeros(size, dtype=np.bool_)
        self._baro_y = np.zeros((size, 1))
        self._baro_has = np.zeros(size, dtype=np.bool_)
        self._tmp = np.zeros((N_STATE, N_STATE))
        self._head = 0
        self._count = 1
        self._steps = 0
        self.t0_s = float(t0_s)
        if x0 is not None:
            x = np.asarray(x0, dtype=np.float64)
            if x.shape != (N_STATE,):
                raise InvalidParameterError(f"x0 must have shape ({N_STATE},), got {x.shape}")
            self._buf_x[0] = x
        if P0 is not None:
            p = np.asarray(P0, dtype=np.float64)
            if p.shape != (N_STATE, N_STATE):
                raise InvalidParameterError(f"P0 must have shape ({N_STATE}, {N_STATE}), got {p.shape}")
            self._buf_P[0] = p
        else:
            sig = [c.init_pos_sigma_m] * 3 + [c.init_vel_sigma_mps] * 3 + [c.init_bias_sigma_mps2] * 3
            self._buf_P[0] = np.diag(np.square([*sig, c.init_baro_offset_sigma_m]))
        self.gps = AidingStats(last_fused_s=self.t0_s)
        self.baro = AidingStats(last_fused_s=self.t0_s)

    @property
    def t_s(self) -> float:
        """Time of the current estimate, s."""
        return self.t0_s + self._steps / self.config.imu_rate_hz

    @property
    def x(self) -> np.ndarray:
        """(10,) current state estimate (a copy)."""
        return self._buf_x[self._head].copy()

    @property
    def P(self) -> np.ndarray:  # noqa: N802 - the usual name of a covariance
        """(10, 10) current covariance (a copy)."""
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

    @property
    def baro_offset(self) -> float:
        """Barometer offset estimate (its altitude minus the altitude above the datum), m."""
        return float(self._buf_x[self._head, BARO_OFFSET])

    def predict(self, accel_ned: np.ndarray) -> None:
        """Propagate one IMU period with a kinematic acceleration sample (3,) NED m/s² (gravity removed)."""
        u = accel_ned if type(accel_ned) is np.ndarray else np.asarray(accel_ned, dtype=np.float64)
        if u.shape != (3,) or u.dtype != np.float64:
            u = np.asarray(u, dtype=np.float64).reshape(3)
        self._head = _step(
            self._buf_x,
            self._buf_P,
            self._buf_u,
            self._gps_has,
            self._baro_has,
            self._head,
            u,
            self.F,
            self.G,
            self.Q,
            self._tmp,
        )
        if self._count < self._buf_x.shape[0]:
            self._count += 1
        self._steps += 1

    def update_gps(self, position_ned: Any, stamp_s: float | None = None) -> Fusion:
        """Gate and fuse a GPS position fix (3,) NED m taken at ``stamp_s`` (default: now).

        The fix is fused at the buffered IMU sample nearest its stamp and the later samples are replayed.

        Raises:
            StaleMeasurementError: the stamp is older than the history or later than the current time, or a fix is
                already fused at that IMU sample.
            InvalidParameterError: the fix is not finite.
        """
        return self._fuse(_GPS, np.asarray(position_ned, dtype=np.float64).reshape(3), stamp_s)

    def update_baro(self, altitude_m: float, stamp_s: float | None = None) -> Fusion:
        """Gate and fuse a barometric altitude above the datum (m, up: `isa_altitude_m` minus the datum's altitude)
        taken at ``stamp_s`` (default: now), as `update_gps` does a fix."""
        return self._fuse(_BARO, np.array([altitude_m], dtype=np.float64), stamp_s)

    def _fuse(self, kind: int, y: np.ndarray, stamp_s: float | None) -> Fusion:
        what = "fix" if kind == _GPS else "baro altitude"
        if not np.all(np.isfinite(y)):
            raise InvalidParameterError(f"{what} must be finite, got {y}")
        stamp = self.t_s if stamp_s is None else float(stamp_s)
        age = round((self.t_s - stamp) * self.config.imu_rate_hz)
        if age < 0:
            raise StaleMeasurementError(f"{what} stamped {stamp_s} s is after the filter time {self.t_s} s")
        if age > self._count - 1:
            raise StaleMeasurementError(
                f"{what} stamped {stamp_s} s is older than the {self.config.history_s} s history (now {self.t_s} s)"
            )
        has = self._gps_has if kind == _GPS else self._baro_has
        if has[(self._head - age) % has.size]:
            raise StaleMeasurementError(f"a {what} is already fused at the IMU sample nearest {stamp} s")
        c = self.config
        stats, gate = (self.gps, c.gps_gate_nis) if kind == _GPS else (self.baro, c.baro_gate_nis)
        timed_out = stamp - stats.last_fused_s >= c.reset_timeout_s
        nis, outcome = _fuse_delayed(
            self._buf_x,
            self._buf_P,
            self._buf_u,
            self._gps_y,
            self._gps_has,
            self._baro_y,
            self._baro_has,
            self._head,
            age,
            kind,
            y,
            gate,
            timed_out,
            _RESET_STATES[kind],
            self.F,
            self.G,
            self.Q,
            self.H,
            self.R,
            self.H_baro,
            self.R_baro,
            self._tmp,
        )
        stats.last_nis = nis
        if outcome == 0:
            stats.rejected += 1
        else:
            stats.fused += 1
            stats.resets += outcome == 2
            stats.last_fused_s = max(stats.last_fused_s, stamp)
        return Fusion(nis, outcome > 0, outcome == 2)


#: The states a reset of each aiding kind makes unknown before fusing: the position (GPS), the baro offset.
_RESET_STATES = (np.arange(3, dtype=np.int64), np.array([BARO_OFFSET], dtype=np.int64))


@dataclass(frozen=True)
class SyntheticFlight:
    """A seeded synthetic flight consistent with the filter's model.

    Attributes:
        t_s: (K,) IMU sample times (time after each sample's prediction), s.
        position, velocity, bias: (K, 3) true NED position m, velocity m/s, accelerometer bias m/s².
        baro_offset: (K,) true barometer offset, m.
        accel_meas: (K, 3) IMU kinematic-acceleration samples (true acceleration + bias + white noise), m/s².
        gps_index: (M,) IMU index at which each fix was taken.
        gps_arrival_index: (M,) IMU index after which each fix arrives (taken + delay).
        gps_position: (M, 3) fixes (true position + N(0, σ_gps²)), m.
        baro_index: (B,) IMU index at which each barometric altitude was taken (and arrives).
        baro_altitude: (B,) barometric altitudes (true altitude + offset + N(0, σ_baro²)), m.
        x0: (10,) true initial state (drawn around zero with the config's initial sigmas).
    """

    t_s: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    bias: np.ndarray
    baro_offset: np.ndarray
    accel_meas: np.ndarray
    gps_index: np.ndarray
    gps_arrival_index: np.ndarray
    gps_position: np.ndarray
    baro_index: np.ndarray
    baro_altitude: np.ndarray
    x0: np.ndarray


def synthetic_flight(
    rng: np.random.Generator,
    config: GpsInsConfig | None = None,
    duration_s: float = 60.0,
    gps_rate_hz: float = 5.0,
    gps_delay_s: float = 0.15,
    baro_rate_hz: float = 25.0,
) -> SyntheticFlight:
    """A figure-eight climb sampled at the IMU rate, with noisy IMU, delayed noisy GPS and a noisy barometer with a
    drifting offset (seeded).

    The truth is propagated with the filter's own discrete model (so NEES is χ²₁₀ for a consistent filter); the
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
    sig0 = np.append(sig0, c.init_baro_offset_sigma_m)
    x0 = rng.normal(size=N_STATE) * sig0
    bias = x0[6:9] + np.cumsum(rng.normal(size=(k, 3)) * c.accel_bias_walk_mps2_per_sqrt_s * math.sqrt(dt), axis=0)
    bias_prev = np.vstack([x0[6:9], bias[:-1]])
    accel_meas = a_true + bias_prev + rng.normal(size=(k, 3)) * c.accel_noise_mps2
    # truth: p+ = p + v dt + ½ a dt²;  v+ = v + a dt (a = a_meas - b - noise = the true acceleration)
    vel = x0[3:6] + np.cumsum(a_true * dt, axis=0)
    vel_prev = np.vstack([x0[3:6], vel[:-1]])
    pos = x0[0:3] + np.cumsum(vel_prev * dt + 0.5 * a_true * dt * dt, axis=0)
    offset = x0[BARO_OFFSET] + np.cumsum(rng.normal(size=k) * c.baro_offset_walk_m_per_sqrt_s * math.sqrt(dt))
    stride = round(c.imu_rate_hz / gps_rate_hz)
    delay = round(gps_delay_s * c.imu_rate_hz)
    idx = np.arange(stride - 1, k, stride)
    arrival = idx + delay
    keep = arrival < k
    idx, arrival = idx[keep], arrival[keep]
    gps = pos[idx] + rng.normal(size=(idx.size, 3)) * c.gps_sigma_m
    b_idx = np.arange(round(c.imu_rate_hz / baro_rate_hz) - 1, k, round(c.imu_rate_hz / baro_rate_hz))
    baro = -pos[b_idx, 2] + offset[b_idx] + rng.normal(size=b_idx.size) * c.baro_sigma_m
    return SyntheticFlight(t, pos, vel, bias, offset, accel_meas, idx, arrival, gps, b_idx, baro, x0)


def run_filter(flight: SyntheticFlight, config: GpsInsConfig | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Run `GpsIns` over a synthetic flight (fixes fused on arrival, with their stamps; barometric altitudes when
    taken).

    Returns:
        ((K, 10) state estimates after each IMU sample (and any measurement arriving then), (K, 10, 10)
        covariances).
    """
    c = config or GpsInsConfig()
    ins = GpsIns(c)
    k = flight.t_s.size
    xs = np.empty((k, N_STATE))
    ps = np.empty((k, N_STATE, N_STATE))
    arrivals: dict[int, list[int]] = {}
    for m, a in enumerate(flight.gps_arrival_index):
        arrivals.setdefault(int(a), []).append(m)
    baro = dict(zip(flight.baro_index.tolist(), flight.baro_altitude.tolist(), strict=True))
    for i in range(k):
        ins.predict(flight.accel_meas[i])
        if i in baro:
            ins.update_baro(baro[i])
        for m in arrivals.get(i, ()):
            ins.update_gps(flight.gps_position[m], stamp_s=float(flight.t_s[flight.gps_index[m]]))
        xs[i] = ins._buf_x[ins._head]
        ps[i] = ins._buf_P[ins._head]
    return xs, ps

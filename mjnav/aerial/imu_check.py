"""Plausibility checks of IMU samples before an estimator or a controller uses them.

`ImuCheck` looks at samples in stamp order (sensor_msgs/Imu conventions, REP-103: attitude body FLU → ENU as
(w, x, y, z), body rates and specific force in FLU) and rejects, counting each reason:

* ``non_finite``: a NaN or infinite value;
* ``accel_range`` / ``gyro_range``: a specific force or rate beyond the sensor's range (±16 g, ±2000 °/s by
  default: what a MEMS IMU can report at all);
* ``quaternion``: an attitude that is not a unit quaternion;
* ``stamp_not_increasing``: a stamp at or before the last accepted one (a repeat, an older sample, a second stream
  that lost the race to the same stamp);
* ``stamp_off_period``: a stamp that is not a whole number of IMU periods after the last accepted one (the period
  is the first two samples' spacing unless given);
* ``stamp_jump``: a stamp more than ``max_gap_s`` after the last accepted one;
* ``gravity``: at rest — gyro still and ``|f|`` within ``rest_accel_tol_mps2`` of g — a specific force that is not
  along the vertical the attitude says (more than ``rest_tilt_tol_rad`` away): a wrong attitude.

What these checks cannot see is a forged stream that is plausible sample by sample (a slightly wrong attitude
consistent with its own rates, stamped on the sensor's period and arriving before the real sample of each stamp):
only access control (``--secure``: the router accepts ``imu`` from the sim's identity alone) prevents that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from mjnav.aerial.errors import InvalidParameterError

__all__ = ["IMU_REJECT_REASONS", "ImuCheck", "ImuCheckConfig"]

#: Why `ImuCheck` rejects a sample; code ``i + 1`` in the kernel's output is ``IMU_REJECT_REASONS[i]``.
IMU_REJECT_REASONS = (
    "non_finite",
    "accel_range",
    "gyro_range",
    "quaternion",
    "stamp_not_increasing",
    "stamp_off_period",
    "stamp_jump",
    "gravity",
)
#: How far from a whole number of periods a stamp may be (in periods; the sim's stamps are whole physics steps).
_PERIOD_TOL = 0.01


@dataclass(frozen=True)
class ImuCheckConfig:
    """Limits of `ImuCheck`.

    Attributes:
        accel_range_mps2: the accelerometer's range per axis, m/s² (16 g).
        gyro_range_radps: the gyro's range per axis, rad/s (2000 °/s).
        quat_norm_tol: how far from 1 the attitude quaternion's norm may be.
        max_gap_s: the longest gap between two accepted samples, s.
        rest_rate_radps: below this body rate (norm) and ...
        rest_accel_tol_mps2: ... with ``|f|`` this close to g, the vehicle is taken to be at rest, m/s²;
        rest_tilt_tol_rad: ... and its specific force must be within this angle of the attitude's vertical, rad.
        gravity_mps2: gravity, m/s².
    """

    accel_range_mps2: float = 16.0 * 9.80665
    gyro_range_radps: float = math.radians(2000.0)
    quat_norm_tol: float = 0.01
    max_gap_s: float = 0.1
    rest_rate_radps: float = 0.05
    rest_accel_tol_mps2: float = 0.3
    rest_tilt_tol_rad: float = 0.5
    gravity_mps2: float = 9.80665

    def __post_init__(self) -> None:
        for name, v in self.__dict__.items():
            if not (math.isfinite(v) and v > 0.0):
                raise InvalidParameterError(f"{name} must be finite and > 0, got {v}")


@njit(cache=True)
def _check_imu(
    stamps: np.ndarray,
    quats: np.ndarray,
    rates: np.ndarray,
    forces: np.ndarray,
    state: np.ndarray,
    limits: np.ndarray,
    codes: np.ndarray,
    periods: np.ndarray,
) -> None:
    """Check samples in order. ``state`` = [last accepted stamp (NaN: none), period (NaN: not yet known)], updated;
    ``limits`` = [accel range, gyro range, quaternion tolerance, max gap, rest rate, rest |f| tolerance,
    cos(rest tilt tolerance), g]. ``codes[i]`` 0 (accepted) or 1 + the reason's index; ``periods[i]`` the IMU periods
    since the previous accepted sample (1 for the first), 0 when rejected."""
    acc_max, gyro_max, q_tol, max_gap, rest_rate, rest_tol, rest_cos, g = (
        limits[0], limits[1], limits[2], limits[3], limits[4], limits[5], limits[6], limits[7],
    )  # fmt: skip
    for i in range(stamps.size):
        codes[i] = 0
        periods[i] = 0
        t = stamps[i]
        finite = math.isfinite(t)
        for k in range(4):
            finite = finite and math.isfinite(quats[i, k])
        for k in range(3):
            finite = finite and math.isfinite(rates[i, k]) and math.isfinite(forces[i, k])
        if not finite:
            codes[i] = 1
            continue
        if max(abs(forces[i, 0]), abs(forces[i, 1]), abs(forces[i, 2])) > acc_max:
            codes[i] = 2
            continue
        if max(abs(rates[i, 0]), abs(rates[i, 1]), abs(rates[i, 2])) > gyro_max:
            codes[i] = 3
            continue
        w, x, y, z = quats[i, 0], quats[i, 1], quats[i, 2], quats[i, 3]
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        if abs(norm - 1.0) > q_tol:
            codes[i] = 4
            continue
        last, period = state[0], state[1]
        k_periods = 1
        if not math.isnan(last):
            gap = t - last
            if not gap > 0.0:
                codes[i] = 5
                continue
            if gap > max_gap + 1e-9:
                codes[i] = 7
                continue
            if not math.isnan(period):
                k_periods = round(gap / period)
                if k_periods < 1 or abs(gap / period - k_periods) > _PERIOD_TOL:
                    codes[i] = 6
                    continue
        fx, fy, fz = forces[i, 0], forces[i, 1], forces[i, 2]
        f_norm = math.sqrt(fx * fx + fy * fy + fz * fz)
        w_norm = math.sqrt(rates[i, 0] ** 2 + rates[i, 1] ** 2 + rates[i, 2] ** 2)
        if w_norm < rest_rate and abs(f_norm - g) < rest_tol:
            w, x, y, z = w / norm, x / norm, y / norm, z / norm
            up = 2 * (x * z - w * y) * fx + 2 * (y * z + w * x) * fy + (1 - 2 * (x * x + y * y)) * fz  # (R f)_z, ENU
            if up < rest_cos * f_norm:
                codes[i] = 8
                continue
        if not math.isnan(last) and math.isnan(period):
            state[1] = round(t - last, 9)  # the first two samples' spacing: the sim's stamps are whole physics steps
        state[0] = t
        periods[i] = k_periods


@dataclass
class ImuCheck:
    """Accepts or rejects IMU samples in stamp order, counting the reasons (see the module's docs).

    Args:
        config: the limits.
        period_s: the IMU period, s (None: the spacing of the first two accepted samples).

    Attributes:
        accepted: samples accepted so far.
        rejected: rejections so far, by reason (every reason of `IMU_REJECT_REASONS`, 0 when none).
        last_reason: the reason of the newest rejection ("" before the first).
    """

    config: ImuCheckConfig = field(default_factory=ImuCheckConfig)
    period_s: float | None = None
    accepted: int = 0
    rejected: dict[str, int] = field(default_factory=lambda: dict.fromkeys(IMU_REJECT_REASONS, 0))
    last_reason: str = ""

    def __post_init__(self) -> None:
        if self.period_s is not None and not (math.isfinite(self.period_s) and self.period_s > 0.0):
            raise InvalidParameterError(f"period_s must be finite and > 0, got {self.period_s}")
        c = self.config
        self._state = np.array([math.nan, math.nan if self.period_s is None else self.period_s])
        self._limits = np.array(
            [
                c.accel_range_mps2,
                c.gyro_range_radps,
                c.quat_norm_tol,
                c.max_gap_s,
                c.rest_rate_radps,
                c.rest_accel_tol_mps2,
                math.cos(c.rest_tilt_tol_rad),
                c.gravity_mps2,
            ]
        )

    @property
    def last_stamp_s(self) -> float:
        """Stamp of the newest accepted sample (NaN before the first), s."""
        return float(self._state[0])

    @property
    def learnt_period_s(self) -> float:
        """The IMU period in use (given, or learnt from the first two samples; NaN before), s."""
        return float(self._state[1])

    def check(self, stamps_s: Any, quat_wxyz: Any, rate_radps: Any, force_mps2: Any) -> np.ndarray:
        """Check N samples in the order given (sort them by stamp first).

        Args:
            stamps_s: (N,) stamps, s.
            quat_wxyz: (N, 4) attitudes (w, x, y, z), body FLU → ENU.
            rate_radps: (N, 3) body rates, FLU, rad/s.
            force_mps2: (N, 3) specific forces, FLU, m/s².

        Returns:
            (N,) int: for an accepted sample the number of IMU periods since the previous accepted one (1 for the
            first; more than 1 across a gap), 0 for a rejected one.
        """
        stamps = np.ascontiguousarray(stamps_s, dtype=np.float64).reshape(-1)
        n = stamps.size
        quats = np.ascontiguousarray(quat_wxyz, dtype=np.float64).reshape(n, 4)
        rates = np.ascontiguousarray(rate_radps, dtype=np.float64).reshape(n, 3)
        forces = np.ascontiguousarray(force_mps2, dtype=np.float64).reshape(n, 3)
        codes = np.zeros(n, dtype=np.int64)
        periods = np.zeros(n, dtype=np.int64)
        _check_imu(stamps, quats, rates, forces, self._state, self._limits, codes, periods)
        self.accepted += int(np.count_nonzero(codes == 0))
        for code in codes[codes > 0]:
            self.last_reason = IMU_REJECT_REASONS[int(code) - 1]
            self.rejected[self.last_reason] += 1
        return periods

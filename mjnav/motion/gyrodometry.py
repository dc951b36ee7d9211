"""Gyro-aided wheel odometry: distance from the wheels, heading from the gyro.

Wheel odometry's worst error is its heading: a 1 % wrong wheel separation turns every turn 1 % wrong, and the
position error grows with the distance driven after it (UMBmark's E_b). A rate gyro measures the turn directly,
so its integrated rate replaces the wheels' heading increments, as in Borenstein & Feng's *gyrodometry* (1996;
here the gyro is always used, not only when the two disagree). The gyro's bias is estimated while the wheels
report standstill (an exponential average of the rate then), as real gyros drift.

Poses are (x, y, θ) in the frame of the first odometry pose (the fused pose starts equal to it).
"""

from __future__ import annotations

import math
from collections import deque

from mjnav.geometry import Pose2D, wrap_angle


class GyroOdometry:
    """Fuses wheel-odometry poses and gyro yaw rates into one drift-reduced pose.

    Args:
        bias_gain: weight of each standstill interval's mean rate in the bias estimate (0 = no bias estimation).
        still_m: a wheel increment shorter than this (metres) ...
        still_rad: ... and turning less than this (radians) counts as standstill.
        min_gyro_coverage: the share of an odometry interval the gyro samples must cover for their mean rate to
            give the interval's turn; below it the wheels' own heading increment is used (no gyro, no guess).

    Feed samples in time order per source (:meth:`add_gyro`, :meth:`add_odom`); gyro samples up to an odometry
    stamp must be added before that odometry pose.
    """

    def __init__(
        self,
        bias_gain: float = 0.02,
        still_m: float = 1e-5,
        still_rad: float = 1e-5,
        min_gyro_coverage: float = 0.5,
    ) -> None:
        if not 0.0 <= bias_gain <= 1.0:
            raise ValueError(f"bias_gain must be in [0, 1], got {bias_gain}")
        if not 0.0 < min_gyro_coverage <= 1.0:
            raise ValueError(f"min_gyro_coverage must be in (0, 1], got {min_gyro_coverage}")
        if not (still_m >= 0.0 and still_rad >= 0.0):
            raise ValueError("still_m and still_rad must be >= 0")
        self.bias_gain = bias_gain
        self.still_m = still_m
        self.still_rad = still_rad
        self.min_gyro_coverage = min_gyro_coverage
        self.bias_radps = 0.0
        self._gyro: deque[tuple[float, float]] = deque(maxlen=10_000)  # (t, rate) not yet used
        self._last_gyro_t: float | None = None
        self._wheel: tuple[float, Pose2D] | None = None  # last wheel pose and its stamp
        self._fused: Pose2D | None = None

    def reset(self) -> None:
        """Forget the poses (the wheel odometry restarted); the bias estimate is kept."""
        self._gyro.clear()
        self._last_gyro_t = None
        self._wheel = None
        self._fused = None

    @property
    def pose(self) -> Pose2D | None:
        """The latest fused pose (None before the first odometry pose)."""
        return self._fused

    def add_gyro(self, t_s: float, rate_radps: float) -> None:
        """A yaw-rate sample (rad/s) at ``t_s``; it holds from the previous sample's time to ``t_s``."""
        if not (math.isfinite(t_s) and math.isfinite(rate_radps)):
            return
        if self._last_gyro_t is not None and t_s <= self._last_gyro_t:
            return
        self._gyro.append((t_s, rate_radps))
        self._last_gyro_t = t_s

    def add_odom(self, t_s: float, wheel_pose: Pose2D) -> Pose2D:
        """The wheel-odometry pose at ``t_s``; returns the fused pose at ``t_s``."""
        if self._wheel is None or self._fused is None or t_s <= self._wheel[0]:
            if self._wheel is None or self._fused is None:
                self._fused = wheel_pose
            self._wheel = (t_s, wheel_pose)
            self._drop_gyro_until(t_s)
            return self._fused
        t0, prev = self._wheel
        step = prev.inverse() * wheel_pose  # the wheels' increment in the previous wheel frame
        distance = math.copysign(math.hypot(step.x, step.y), step.x)
        covered, mean_rate = self._gyro_rate(t0, t_s)
        if covered < self.min_gyro_coverage * (t_s - t0):
            turn = step.theta  # the gyro missed (most of) the interval: keep the wheels' heading
        elif abs(distance) < self.still_m and abs(step.theta) < self.still_rad:
            self.bias_radps += self.bias_gain * (mean_rate - self.bias_radps)
            turn = 0.0  # standing still: no heading change, whatever the gyro's noise says
        else:
            turn = (mean_rate - self.bias_radps) * (t_s - t0)  # a missing sample is bridged by the others' mean
        heading = self._fused.theta + 0.5 * turn
        self._fused = Pose2D(
            self._fused.x + distance * math.cos(heading),
            self._fused.y + distance * math.sin(heading),
            wrap_angle(self._fused.theta + turn),
        )
        self._wheel = (t_s, wheel_pose)
        return self._fused

    def _gyro_rate(self, t0: float, t1: float) -> tuple[float, float]:
        """(seconds of (t0, t1] covered by gyro samples, their time-weighted mean raw rate in rad/s)."""
        covered = raw = 0.0
        prev_t = t0
        while self._gyro and self._gyro[0][0] <= t1 + 1e-9:
            t, rate = self._gyro.popleft()
            if t <= t0 + 1e-9:
                continue
            dt = t - max(prev_t, t0)
            raw += rate * dt
            covered += dt
            prev_t = t
        return covered, (raw / covered if covered > 0.0 else 0.0)

    def _drop_gyro_until(self, t_s: float) -> None:
        while self._gyro and self._gyro[0][0] <= t_s + 1e-9:
            self._gyro.popleft()

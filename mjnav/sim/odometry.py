"""Wheel odometry: integrate the encoders into a pose that drifts like a real robot's.

The physics already makes the wheels slip a little (soft contacts, traction limits); encoders cannot see that.
On top, this integrator models the three classic error sources, all seeded:

* **encoder quantisation**: wheel angles are read as whole ticks (``ticks_per_rev``);
* **wheel-radius error**: each wheel's radius as the odometry believes it is off by a fixed factor
  ``1 + N(0, wheel_radius_error_std²)`` drawn once (a systematic error: bias in distance and heading);
* **wheel-base error**: the effective wheel separation (contact patches are not points) is off by a fixed
  factor ``1 + N(0, wheel_separation_error_std²)`` drawn once (a systematic error in every turn; UMBmark's E_b);
* **random slip / encoder noise**: every increment is scaled by ``1 + N(0, slip_noise_std²)`` (a random walk).

Frames (REP-105): the pose is ``odom → base_link``; the ``odom`` frame is where the robot was at the last
:meth:`WheelOdometry.reset` (the world's start pose for a fresh simulator), so it starts at (0, 0, 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mjnav.geometry import Pose2D, wrap_angle
from mjnav.motion import DiffDriveKinematics


@dataclass(frozen=True, slots=True)
class OdometryConfig:
    """Wheel-odometry error model and rate.

    Attributes:
        rate_hz: odometry updates per second of sim time.
        ticks_per_rev: encoder resolution, ticks per wheel revolution (0 = no quantisation).
        wheel_radius_error_std: std of the fixed relative radius error of each wheel (0.003 = 0.3 %).
        wheel_separation_error_std: std of the fixed relative error of the wheel separation (0.01 = 1 %).
        slip_noise_std: std of the relative random error of each wheel increment.
    """

    rate_hz: float = 50.0
    ticks_per_rev: int = 4096
    wheel_radius_error_std: float = 0.003
    wheel_separation_error_std: float = 0.01
    slip_noise_std: float = 0.01

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0.0):
            raise ValueError(f"rate_hz must be positive, got {self.rate_hz}")
        if self.ticks_per_rev < 0:
            raise ValueError(f"ticks_per_rev must be >= 0, got {self.ticks_per_rev}")
        for name in ("wheel_radius_error_std", "wheel_separation_error_std", "slip_noise_std"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value < 0.5):
                raise ValueError(f"{name} must be in [0, 0.5), got {value}")


@dataclass(frozen=True, slots=True)
class OdometryEstimate:
    """Odometry output (``nav_msgs/Odometry`` content).

    Attributes:
        stamp_s: sim time of the update, seconds.
        pose: ``odom → base_link`` pose, metres and radians.
        v_mps: forward speed estimated over the last update interval, m/s (base_link frame).
        omega_radps: yaw rate estimated over the last update interval, rad/s.
    """

    stamp_s: float
    pose: Pose2D
    v_mps: float
    omega_radps: float


class WheelOdometry:
    """Dead reckoning from the two wheel angles with a seeded error model (see module docstring)."""

    def __init__(
        self,
        wheel_diameter_m: float,
        wheel_separation_m: float,
        config: OdometryConfig,
        rng: np.random.Generator,
    ) -> None:
        """Draw the fixed radius errors.

        Args:
            wheel_diameter_m: true wheel diameter W, metres.
            wheel_separation_m: wheel separation L, metres.
            config: error model.
            rng: generator for the radius errors and the per-increment noise.
        """
        self.config = config
        self._diameter = wheel_diameter_m
        self._separation = wheel_separation_m
        self._rng = rng
        self.radius_scale = (
            1.0 + float(rng.normal(0.0, config.wheel_radius_error_std)),
            1.0 + float(rng.normal(0.0, config.wheel_radius_error_std)),
        )
        self.separation_scale = 1.0 + float(rng.normal(0.0, config.wheel_separation_error_std))
        self._kinematics = DiffDriveKinematics(self._diameter, self._separation * self.separation_scale)
        self._tick = 2.0 * math.pi / config.ticks_per_rev if config.ticks_per_rev > 0 else 0.0
        self._x = self._y = self._theta = 0.0
        self._last = (0.0, 0.0)
        self._stamp = 0.0
        self.latest = OdometryEstimate(0.0, Pose2D(), 0.0, 0.0)

    def _read(self, angle_rad: float) -> float:
        return math.floor(angle_rad / self._tick) * self._tick if self._tick else angle_rad

    def reset(self, stamp_s: float, left_rad: float, right_rad: float, pose: Pose2D | None = None) -> None:
        """Restart integration from ``pose`` (default: the odom origin) at the given wheel angles."""
        p = pose or Pose2D()
        self._x, self._y, self._theta = p.x, p.y, p.theta
        self._last = (self._read(left_rad), self._read(right_rad))
        self._stamp = stamp_s
        self.latest = OdometryEstimate(stamp_s, p, 0.0, 0.0)

    def update(self, stamp_s: float, left_rad: float, right_rad: float) -> OdometryEstimate:
        """Integrate wheel angles (radians, unwrapped) read at ``stamp_s`` (seconds); return the estimate."""
        left, right = self._read(left_rad), self._read(right_rad)
        dl, dr = left - self._last[0], right - self._last[1]
        self._last = (left, right)
        std = self.config.slip_noise_std
        if std > 0.0:
            noise = self._rng.normal(0.0, std, 2)
            dl *= 1.0 + float(noise[0])
            dr *= 1.0 + float(noise[1])
        dl *= self.radius_scale[0]
        dr *= self.radius_scale[1]
        ds, dtheta = self._kinematics.wheel_increments_to_motion(dr, dl)
        # The exact arc of DiffDriveKinematics.integrate_encoders, in scalar math: this runs at 50 Hz of sim time
        # inside the stepping loop, where the array version's ~16 µs per call costs ~20 % of the real-time factor.
        chord = ds * math.sin(0.5 * dtheta) / (0.5 * dtheta) if dtheta else ds
        mid = self._theta + 0.5 * dtheta
        self._x += chord * math.cos(mid)
        self._y += chord * math.sin(mid)
        self._theta = wrap_angle(self._theta + dtheta)
        dt = stamp_s - self._stamp
        self._stamp = stamp_s
        v, w = (ds / dt, dtheta / dt) if dt > 0.0 else (0.0, 0.0)
        self.latest = OdometryEstimate(stamp_s, Pose2D(self._x, self._y, self._theta), v, w)
        return self.latest

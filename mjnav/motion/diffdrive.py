"""Differential-drive kinematics: wheel rates <-> body twist, turning radius and encoder odometry.

With W the wheel DIAMETER and L the wheel separation (track width), the right and left wheel rates
ϑ̇_R, ϑ̇_L (rad/s) give

    v = W/4 · (ϑ̇_R + ϑ̇_L)          (forward speed, m/s; the wheel radius is W/2)
    ω = W/(2L) · (ϑ̇_R - ϑ̇_L)       (yaw rate, rad/s, counter-clockwise positive)
    r = v / ω                        (turning radius, m; a straight line when ω = 0)

and the inverse ϑ̇_R = (2v + Lω)/W, ϑ̇_L = (2v - Lω)/W.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mjnav.geometry import wrap_angles
from mjnav.motion._poses import FloatArray, PoseLike, as_poses


@dataclass(frozen=True, slots=True)
class DiffDriveKinematics:
    """Kinematics of a differential-drive base.

    Attributes:
        wheel_diameter_m: wheel diameter W, metres, > 0.
        wheel_separation_m: distance L between the wheel contact points, metres, > 0.
    """

    wheel_diameter_m: float
    wheel_separation_m: float

    def __post_init__(self) -> None:
        for name in ("wheel_diameter_m", "wheel_separation_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be positive and finite, got {v}")

    def body_twist(self, right_radps: float, left_radps: float) -> tuple[float, float]:
        """Forward speed and yaw rate from wheel rates.

        Args:
            right_radps: right wheel rate ϑ̇_R, rad/s.
            left_radps: left wheel rate ϑ̇_L, rad/s.

        Returns:
            (v m/s, ω rad/s) with v = W/4 (ϑ̇_R + ϑ̇_L) and ω = W/(2L) (ϑ̇_R - ϑ̇_L).
        """
        w = self.wheel_diameter_m
        return 0.25 * w * (right_radps + left_radps), 0.5 * w / self.wheel_separation_m * (right_radps - left_radps)

    def body_twists(
        self, right_radps: ArrayLike, left_radps: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Vectorised :meth:`body_twist` for arrays of wheel rates (same shapes), returns (v, ω) arrays."""
        r = np.asarray(right_radps, dtype=np.float64)
        lft = np.asarray(left_radps, dtype=np.float64)
        w = self.wheel_diameter_m
        return 0.25 * w * (r + lft), 0.5 * w / self.wheel_separation_m * (r - lft)

    def wheel_rates(self, v_mps: float, omega_radps: float) -> tuple[float, float]:
        """Wheel rates that realise a body twist (the inverse of :meth:`body_twist`).

        Args:
            v_mps: forward speed, m/s.
            omega_radps: yaw rate, rad/s.

        Returns:
            (ϑ̇_R, ϑ̇_L) rad/s with ϑ̇_R = (2v + Lω)/W and ϑ̇_L = (2v - Lω)/W.
        """
        w, sep = self.wheel_diameter_m, self.wheel_separation_m
        return (2.0 * v_mps + sep * omega_radps) / w, (2.0 * v_mps - sep * omega_radps) / w

    def limit_wheel_rates(self, v_mps: float, omega_radps: float, max_wheel_radps: float) -> tuple[float, float]:
        """Scale (v, ω) down uniformly so that neither wheel exceeds ``max_wheel_radps``.

        Scaling both by the same factor keeps the turning radius, so the robot stays on the commanded arc.

        Returns:
            (v m/s, ω rad/s), unchanged when already within the limit.
        """
        if not (max_wheel_radps > 0.0):
            raise ValueError(f"max_wheel_radps must be > 0, got {max_wheel_radps}")
        # Work on (v, ω) normalised by their magnitude so that huge (finite) inputs cannot overflow to inf.
        norm = max(abs(v_mps), abs(omega_radps), 1.0)
        right, left = self.wheel_rates(v_mps / norm, omega_radps / norm)
        peak = max(abs(right), abs(left))
        if peak * norm <= max_wheel_radps:
            return v_mps, omega_radps
        k = max_wheel_radps / peak
        return v_mps / norm * k, omega_radps / norm * k

    @staticmethod
    def turning_radius(v_mps: float, omega_radps: float) -> float:
        """Signed turning radius r = v / ω, metres (positive: centre on the left).

        Returns ``math.inf`` for ω = 0 (straight line; the sign follows v) and 0 for a turn on the spot.
        """
        if omega_radps == 0.0:
            return math.copysign(math.inf, v_mps) if v_mps != 0.0 else math.inf
        return v_mps / omega_radps

    def wheel_increments_to_motion(self, d_right_rad: float, d_left_rad: float) -> tuple[float, float]:
        """Distance travelled and heading change from wheel encoder increments.

        Args:
            d_right_rad: right wheel rotation since the last reading, rad.
            d_left_rad: left wheel rotation since the last reading, rad.

        Returns:
            (Δs m, Δθ rad) = (W/4 (Δϑ_R + Δϑ_L), W/(2L) (Δϑ_R - Δϑ_L)).
        """
        return self.body_twist(d_right_rad, d_left_rad)

    def integrate_encoders(self, pose: PoseLike, d_right_rad: float, d_left_rad: float) -> FloatArray:
        """Dead-reckon a pose from wheel encoder increments, assuming a constant-curvature arc.

        Args:
            pose: (3,) or (N, 3) poses (x m, y m, θ rad), or a Pose2D.
            d_right_rad: right wheel rotation since the last reading, rad.
            d_left_rad: left wheel rotation since the last reading, rad.

        Returns:
            The new pose(s), θ wrapped to [-π, π): the robot advances Δs·sinc(Δθ/2) along θ + Δθ/2 (the
            exact arc of radius Δs/Δθ; a straight line when Δθ = 0).
        """
        p = as_poses(pose)
        ds, dth = self.wheel_increments_to_motion(d_right_rad, d_left_rad)
        chord = ds * float(np.sinc(dth / (2.0 * math.pi)))
        mid = p[..., 2] + 0.5 * dth
        return np.stack(
            (p[..., 0] + chord * np.cos(mid), p[..., 1] + chord * np.sin(mid), wrap_angles(p[..., 2] + dth)), axis=-1
        )

"""Speed profile along a path from curvature, speed and acceleration limits."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from mjnav.smoothing.path import check_path, curvature, segment_lengths

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class SpeedLimits:
    """Limits for :func:`velocity_profile`.

    Attributes:
        max_speed_mps: top forward speed, m/s, > 0.
        max_accel_mps2: largest forward acceleration, m/s², > 0.
        max_decel_mps2: largest braking deceleration (positive number), m/s², > 0.
        max_lateral_accel_mps2: largest centripetal acceleration v²|κ|, m/s², > 0.
        max_yaw_rate_radps: largest yaw rate v|κ|, rad/s, > 0 (inf: no limit).
    """

    max_speed_mps: float = 0.5
    max_accel_mps2: float = 0.5
    max_decel_mps2: float = 0.5
    max_lateral_accel_mps2: float = 0.5
    max_yaw_rate_radps: float = math.inf

    def __post_init__(self) -> None:
        for name in ("max_speed_mps", "max_accel_mps2", "max_decel_mps2", "max_lateral_accel_mps2"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be positive and finite, got {v}")
        if not (self.max_yaw_rate_radps > 0.0):
            raise ValueError(f"max_yaw_rate_radps must be positive, got {self.max_yaw_rate_radps}")


@njit(cache=True)
def _forward_backward(
    cap: NDArray[np.float64], ds: NDArray[np.float64], accel: float, decel: float
) -> NDArray[np.float64]:  # pragma: no cover - compiled
    n = cap.shape[0]
    v = cap.copy()
    for i in range(1, n):  # acceleration limit: v_i² <= v_{i-1}² + 2 a ds
        reach = math.sqrt(v[i - 1] * v[i - 1] + 2.0 * accel * ds[i - 1])
        if reach < v[i]:
            v[i] = reach
    for i in range(n - 2, -1, -1):  # braking limit: v_i² <= v_{i+1}² + 2 b ds
        reach = math.sqrt(v[i + 1] * v[i + 1] + 2.0 * decel * ds[i])
        if reach < v[i]:
            v[i] = reach
    return v


def velocity_profile(
    path: ArrayLike,
    limits: SpeedLimits = SpeedLimits(),
    *,
    start_speed_mps: float = 0.0,
    end_speed_mps: float = 0.0,
    curvature_invm: ArrayLike | None = None,
) -> FloatArray:
    """Fastest speed at every path point that respects the curvature, speed and acceleration limits.

    Each point is first capped at min(v_max, sqrt(a_lat / |κ|), ω_max / |κ|); a forward pass then applies
    v_i² <= v_{i-1}² + 2 a_max Δs and a backward pass v_i² <= v_{i+1}² + 2 b_max Δs (constant acceleration
    over each segment), with the first and last points pinned to the start and end speeds (each clipped to
    its point's cap). Both turning directions are handled through |κ|.

    Args:
        path: (N, 2) positions, metres, N >= 2.
        limits: the speed and acceleration limits.
        start_speed_mps: speed at the first point, m/s, >= 0 (e.g. the robot's current speed).
        end_speed_mps: speed at the last point, m/s, >= 0 (0: stop at the goal).
        curvature_invm: optional (N,) signed curvature, 1/m; default :func:`mjnav.smoothing.curvature`.

    Returns:
        (N,) speeds, m/s, >= 0.

    Raises:
        PathError: invalid path.
        ValueError: negative speeds or a wrongly shaped curvature.
    """
    p = check_path(path)
    if not (math.isfinite(start_speed_mps) and start_speed_mps >= 0.0):
        raise ValueError(f"start_speed_mps must be finite and >= 0, got {start_speed_mps}")
    if not (math.isfinite(end_speed_mps) and end_speed_mps >= 0.0):
        raise ValueError(f"end_speed_mps must be finite and >= 0, got {end_speed_mps}")
    if curvature_invm is None:
        kappa = np.abs(curvature(p))
    else:
        kappa = np.abs(np.asarray(curvature_invm, dtype=np.float64))
        if kappa.shape != (p.shape[0],) or not np.isfinite(kappa).all():
            raise ValueError(f"curvature_invm must be ({p.shape[0]},) finite values, got shape {kappa.shape}")
    with np.errstate(divide="ignore"):
        cap = np.minimum(limits.max_speed_mps, np.sqrt(limits.max_lateral_accel_mps2 / kappa))
        cap = np.minimum(cap, limits.max_yaw_rate_radps / kappa)
    cap[0] = min(cap[0], start_speed_mps)
    cap[-1] = min(cap[-1], end_speed_mps)
    return np.asarray(
        _forward_backward(cap, segment_lengths(p), float(limits.max_accel_mps2), float(limits.max_decel_mps2))
    )


def profile_times(path: ArrayLike, speeds_mps: ArrayLike) -> FloatArray:
    """Time stamps along a path driven with a speed profile (constant acceleration per segment).

    Args:
        path: (N, 2) positions, metres.
        speeds_mps: (N,) speeds at the points, m/s, >= 0.

    Returns:
        (N,) times from the first point, seconds; inf after a segment that would need zero speed at both
        of its ends.
    """
    p = check_path(path)
    v = np.asarray(speeds_mps, dtype=np.float64)
    if v.shape != (p.shape[0],) or not np.isfinite(v).all() or (v < 0.0).any():
        raise ValueError(f"speeds_mps must be ({p.shape[0]},) finite non-negative values")
    ds = segment_lengths(p)
    vsum = v[1:] + v[:-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        dt = np.where(ds > 0.0, 2.0 * ds / vsum, 0.0)
    return np.concatenate(([0.0], np.cumsum(dt)))

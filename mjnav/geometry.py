"""Planar geometry: angle wrapping, SE(2) poses and transforms (numpy only).

Conventions follow REP-103: x forward, y left, θ counter-clockwise from +x, metres and radians.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray


def wrap_angle(angle_rad: float) -> float:
    """Wrap an angle to [-π, π).

    Args:
        angle_rad: any finite angle, radians.

    Returns:
        The equivalent angle in [-π, π), radians.
    """
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


def wrap_angles(angles_rad: ArrayLike) -> NDArray[np.float64]:
    """Vectorised :func:`wrap_angle`: wraps every element to [-π, π)."""
    a = np.asarray(angles_rad, dtype=np.float64)
    return np.mod(a + np.pi, 2.0 * np.pi) - np.pi


def angle_diff(a_rad: float, b_rad: float) -> float:
    """Shortest signed angle a − b, radians in [-π, π)."""
    return wrap_angle(a_rad - b_rad)


def yaw_to_quaternion(yaw_rad: float) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) of a rotation by ``yaw_rad`` about +z."""
    half = 0.5 * yaw_rad
    return (0.0, 0.0, math.sin(half), math.cos(half))


def quaternion_to_yaw(x: float, y: float, z: float, w: float) -> float:
    """Yaw (rotation about +z, radians) of a quaternion (x, y, z, w); roll and pitch are ignored."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


@dataclass(frozen=True, slots=True)
class Pose2D:
    """A planar pose: position (x, y) in metres and heading θ in radians.

    Poses compose as SE(2) elements: ``a * b`` is b expressed in a's parent frame.
    """

    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.x) and math.isfinite(self.y) and math.isfinite(self.theta)):
            raise ValueError(f"Pose2D needs finite values, got ({self.x}, {self.y}, {self.theta})")

    @classmethod
    def from_array(cls, a: ArrayLike) -> Pose2D:
        """Build from a length-3 array (x, y, θ)."""
        v = np.asarray(a, dtype=np.float64).reshape(-1)
        if v.shape != (3,):
            raise ValueError(f"Pose2D.from_array needs 3 values (x, y, theta), got shape {v.shape}")
        return cls(float(v[0]), float(v[1]), float(v[2]))

    def as_array(self) -> NDArray[np.float64]:
        """(3,) float array (x, y, θ)."""
        return np.array([self.x, self.y, self.theta], dtype=np.float64)

    def matrix(self) -> NDArray[np.float64]:
        """(3, 3) homogeneous transform of this pose."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        return np.array([[c, -s, self.x], [s, c, self.y], [0.0, 0.0, 1.0]])

    def __mul__(self, other: Pose2D) -> Pose2D:
        c, s = math.cos(self.theta), math.sin(self.theta)
        return Pose2D(
            self.x + c * other.x - s * other.y,
            self.y + s * other.x + c * other.y,
            wrap_angle(self.theta + other.theta),
        )

    def inverse(self) -> Pose2D:
        """The inverse transform, so that ``p * p.inverse()`` is the identity."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        return Pose2D(-c * self.x - s * self.y, s * self.x - c * self.y, wrap_angle(-self.theta))

    def transform_points(self, points: ArrayLike) -> NDArray[np.float64]:
        """Map (N, 2) points from this pose's frame to its parent frame (metres)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        c, s = math.cos(self.theta), math.sin(self.theta)
        rot = np.array([[c, -s], [s, c]])
        return p @ rot.T + np.array([self.x, self.y])

    def to_local(self, points: ArrayLike) -> NDArray[np.float64]:
        """Map (N, 2) points from the parent frame into this pose's frame (metres)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2) - np.array([self.x, self.y])
        c, s = math.cos(self.theta), math.sin(self.theta)
        rot = np.array([[c, s], [-s, c]])
        return p @ rot.T

    def distance_to(self, other: Pose2D) -> float:
        """Euclidean distance between the two positions, metres."""
        return math.hypot(other.x - self.x, other.y - self.y)


def interpolate_pose(a: Pose2D, b: Pose2D, alpha: float) -> Pose2D:
    """Pose a fraction ``alpha`` (0 → a, 1 → b) of the way from ``a`` to ``b``; heading along the shortest arc."""
    return Pose2D(
        a.x + alpha * (b.x - a.x),
        a.y + alpha * (b.y - a.y),
        wrap_angle(a.theta + alpha * angle_diff(b.theta, a.theta)),
    )


class PoseHistory:
    """Time-stamped poses, for looking up where the robot was when a sensor reading was taken.

    Args:
        horizon_s: how much history to keep, seconds.
    """

    def __init__(self, horizon_s: float = 2.0) -> None:
        if not horizon_s > 0:
            raise ValueError(f"horizon_s must be > 0, got {horizon_s}")
        self.horizon_s = horizon_s
        self._t: list[float] = []
        self._poses: list[Pose2D] = []

    def __len__(self) -> int:
        return len(self._t)

    def add(self, t_s: float, pose: Pose2D) -> None:
        """Record ``pose`` at time ``t_s`` (seconds); older-than-latest stamps are ignored, old entries dropped."""
        if self._t and t_s <= self._t[-1]:
            if t_s == self._t[-1]:
                self._poses[-1] = pose
            return
        self._t.append(t_s)
        self._poses.append(pose)
        cut = 0
        while cut < len(self._t) - 1 and self._t[cut] < t_s - self.horizon_s:
            cut += 1
        if cut:
            del self._t[:cut], self._poses[:cut]

    def latest(self) -> tuple[float, Pose2D] | None:
        """The newest (time, pose), or None when empty."""
        return (self._t[-1], self._poses[-1]) if self._t else None

    def at(self, t_s: float, max_extrapolation_s: float = 0.05) -> Pose2D | None:
        """The pose at ``t_s``: interpolated between the bracketing entries; the end pose within
        ``max_extrapolation_s`` past either end; ``None`` further out (or when empty)."""
        if not self._t:
            return None
        if t_s <= self._t[0]:
            return self._poses[0] if self._t[0] - t_s <= max_extrapolation_s else None
        if t_s >= self._t[-1]:
            return self._poses[-1] if t_s - self._t[-1] <= max_extrapolation_s else None
        i = bisect.bisect_right(self._t, t_s)
        t0, t1 = self._t[i - 1], self._t[i]
        return interpolate_pose(self._poses[i - 1], self._poses[i], (t_s - t0) / (t1 - t0))

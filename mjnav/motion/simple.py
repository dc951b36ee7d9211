"""The seed's simplified motion model: drive straight along the current heading, then rotate in place.

    x' = x + d cos θ,   y' = y + d sin θ,   θ' = θ + Δθ

Sampling adds independent zero-mean Gaussian noise to the distance and to the rotation.
"""

from __future__ import annotations

import math

import numpy as np

from mjnav.geometry import wrap_angles
from mjnav.motion._poses import FloatArray, PoseLike, as_poses


def simple_motion(pose: PoseLike, distance_m: float, rotation_rad: float) -> FloatArray:
    """Move straight by ``distance_m`` along the heading, then rotate by ``rotation_rad``.

    Args:
        pose: (3,) or (N, 3) poses (x m, y m, θ rad), or a Pose2D.
        distance_m: signed travel distance d, metres (negative drives backwards).
        rotation_rad: rotation Δθ after the move, radians.

    Returns:
        Poses with the input's shape, θ wrapped to [-π, π).
    """
    if not (math.isfinite(distance_m) and math.isfinite(rotation_rad)):
        raise ValueError("distance_m and rotation_rad must be finite")
    p = as_poses(pose)
    return np.stack(
        (
            p[..., 0] + distance_m * np.cos(p[..., 2]),
            p[..., 1] + distance_m * np.sin(p[..., 2]),
            wrap_angles(p[..., 2] + rotation_rad),
        ),
        axis=-1,
    )


def sample_simple_motion(
    poses: PoseLike,
    distance_m: float,
    rotation_rad: float,
    distance_std_m: float,
    rotation_std_rad: float,
    rng: np.random.Generator,
) -> FloatArray:
    """Sample the simplified model: d ~ N(distance, σ_d²) and Δθ ~ N(rotation, σ_θ²) per pose.

    Args:
        poses: (N, 3) or (3,) poses, or a Pose2D.
        distance_m: commanded distance, metres.
        rotation_rad: commanded rotation, radians.
        distance_std_m: standard deviation of the distance, metres, >= 0.
        rotation_std_rad: standard deviation of the rotation, radians, >= 0.
        rng: random generator.

    Returns:
        Sampled poses with the input's shape.
    """
    if not (distance_std_m >= 0.0 and rotation_std_rad >= 0.0):
        raise ValueError("standard deviations must be >= 0")
    if not (math.isfinite(distance_m) and math.isfinite(rotation_rad)):
        raise ValueError("distance_m and rotation_rad must be finite")
    p = as_poses(poses)
    shape = p.shape[:-1]
    d = distance_m + rng.normal(0.0, distance_std_m, shape)
    r = rotation_rad + rng.normal(0.0, rotation_std_rad, shape)
    return np.stack(
        (p[..., 0] + d * np.cos(p[..., 2]), p[..., 1] + d * np.sin(p[..., 2]), wrap_angles(p[..., 2] + r)), axis=-1
    )

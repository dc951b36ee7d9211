"""Odometry motion model (Thrun, Burgard, Fox, Probabilistic Robotics, §5.4).

The relative motion between two odometry poses (x̄, ȳ, θ̄) -> (x̄', ȳ', θ̄') is decomposed into a
rotation, a translation and a second rotation:

    δ_rot1 = atan2(ȳ' - ȳ, x̄' - x̄) - θ̄,   δ_trans = sqrt((x̄' - x̄)² + (ȳ' - ȳ)²),   δ_rot2 = θ̄' - θ̄ - δ_rot1

and re-applied to the pose to be moved. Noise is zero-mean Gaussian with variances

    var(rot1) = α1 δ_rot1² + α2 δ_trans²
    var(trans) = α3 δ_trans² + α4 (δ_rot1² + δ_rot2²)
    var(rot2) = α1 δ_rot2² + α2 δ_trans²

(Tables 5.5 and 5.6). For a pure rotation (δ_trans below ``1e-9`` m) the direction atan2(0, 0) is
meaningless, so δ_rot1 = 0 and the whole turn goes into δ_rot2. All angles are wrapped to [-π, π).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from mjnav.geometry import wrap_angles
from mjnav.motion._poses import FloatArray, PoseLike, as_poses, check_alphas

_STILL = 1e-9  # translations shorter than this (m) count as pure rotation


def odometry_delta(odom_prev: PoseLike, odom_curr: PoseLike) -> FloatArray:
    """Decompose odometry motion into (δ_rot1 rad, δ_trans m, δ_rot2 rad).

    Args:
        odom_prev: (3,) or (N, 3) previous odometry pose(s) (x, y, θ), or a Pose2D.
        odom_curr: current odometry pose(s), same shape as ``odom_prev``.

    Returns:
        (3,) or (N, 3) array (δ_rot1, δ_trans, δ_rot2).
    """
    a = as_poses(odom_prev, "odom_prev")
    b = as_poses(odom_curr, "odom_curr")
    if a.shape != b.shape:
        raise ValueError(f"odometry pose shapes differ: {a.shape} vs {b.shape}")
    dx = b[..., 0] - a[..., 0]
    dy = b[..., 1] - a[..., 1]
    trans = np.hypot(dx, dy)
    rot1 = np.where(trans < _STILL, 0.0, wrap_angles(np.arctan2(dy, dx) - a[..., 2]))
    rot2 = wrap_angles(b[..., 2] - a[..., 2] - rot1)
    return np.stack((rot1, trans, rot2), axis=-1)


def apply_odometry_delta(pose: PoseLike, delta: ArrayLike) -> FloatArray:
    """Move pose(s) by (δ_rot1, δ_trans, δ_rot2): rotate, drive straight, rotate.

    Args:
        pose: (3,) or (N, 3) poses, or a Pose2D.
        delta: (3,) or broadcastable (N, 3) motion (rad, m, rad).

    Returns:
        Poses with the broadcast shape, θ wrapped to [-π, π).
    """
    p = as_poses(pose)
    d = np.asarray(delta, dtype=np.float64)
    heading = p[..., 2] + d[..., 0]
    x = p[..., 0] + d[..., 1] * np.cos(heading)
    y = p[..., 1] + d[..., 1] * np.sin(heading)
    return np.stack(np.broadcast_arrays(x, y, wrap_angles(heading + d[..., 2])), axis=-1)


def sample_odometry_motion(
    poses: PoseLike, odom_prev: PoseLike, odom_curr: PoseLike, alphas: ArrayLike, rng: np.random.Generator
) -> FloatArray:
    """Sample the odometry motion model once per pose (Table 5.6).

    Args:
        poses: (N, 3) or (3,) poses to move (x m, y m, θ rad), or a Pose2D.
        odom_prev: (3,) previous odometry reading.
        odom_curr: (3,) current odometry reading.
        alphas: (α1, α2, α3, α4) noise parameters.
        rng: random generator.

    Returns:
        Sampled poses with the shape of ``poses``.
    """
    a = check_alphas(alphas, 4)
    rot1, trans, rot2 = (float(v) for v in odometry_delta(odom_prev, odom_curr).reshape(3))
    p = as_poses(poses)
    shape = p.shape[:-1]
    s_rot1 = math.sqrt(a[0] * rot1 * rot1 + a[1] * trans * trans)
    s_trans = math.sqrt(a[2] * trans * trans + a[3] * (rot1 * rot1 + rot2 * rot2))
    s_rot2 = math.sqrt(a[0] * rot2 * rot2 + a[1] * trans * trans)
    noisy = np.stack(
        (
            rot1 - rng.normal(0.0, s_rot1, shape),
            trans - rng.normal(0.0, s_trans, shape),
            rot2 - rng.normal(0.0, s_rot2, shape),
        ),
        axis=-1,
    )
    return apply_odometry_delta(p, noisy)


def _gauss(err: FloatArray, var: FloatArray) -> FloatArray:
    return np.asarray(np.exp(-0.5 * err * err / var) / np.sqrt(2.0 * np.pi * var))


def odometry_likelihood(
    pose_curr: PoseLike,
    pose_prev: PoseLike,
    odom_prev: PoseLike,
    odom_curr: PoseLike,
    alphas: ArrayLike,
    *,
    min_variance: float = 1e-12,
) -> FloatArray:
    """p(x_t | u_t, x_{t-1}) of the odometry motion model (Table 5.5).

    The hypothesised motion (δ̂_rot1, δ̂_trans, δ̂_rot2) from ``pose_prev`` to ``pose_curr`` is compared
    with the odometry motion; each component's error is scored by a Gaussian with the variance computed
    from the hypothesised motion, and the three densities are multiplied.

    Args:
        pose_curr: (3,) or (N, 3) hypothesised current pose(s).
        pose_prev: (3,) or (N, 3) previous pose(s), broadcastable with ``pose_curr``.
        odom_prev: (3,) previous odometry reading.
        odom_curr: (3,) current odometry reading.
        alphas: (α1, α2, α3, α4) noise parameters.
        min_variance: variance floor so that noise-free motion gives a finite density, > 0.

    Returns:
        Density (product of three 1-D densities, units 1/(rad² m)); a scalar array for single poses,
        (N,) otherwise.
    """
    if not (min_variance > 0.0):
        raise ValueError(f"min_variance must be > 0, got {min_variance}")
    a = check_alphas(alphas, 4)
    rot1, trans, rot2 = (float(v) for v in odometry_delta(odom_prev, odom_curr).reshape(3))
    cur = as_poses(pose_curr, "pose_curr")
    prev = as_poses(pose_prev, "pose_prev")
    cur, prev = np.broadcast_arrays(cur, prev)
    h = odometry_delta(prev, cur)
    h1, ht, h2 = h[..., 0], h[..., 1], h[..., 2]
    p1 = _gauss(wrap_angles(np.asarray(rot1 - h1)), np.maximum(a[0] * h1**2 + a[1] * ht**2, min_variance))
    pt = _gauss(np.asarray(trans - ht), np.maximum(a[2] * ht**2 + a[3] * (h1**2 + h2**2), min_variance))
    p2 = _gauss(wrap_angles(np.asarray(rot2 - h2)), np.maximum(a[0] * h2**2 + a[1] * ht**2, min_variance))
    return np.asarray(p1 * pt * p2)

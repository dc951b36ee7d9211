"""Velocity motion model (Thrun, Burgard, Fox, Probabilistic Robotics, §5.3).

The robot executes the command (v, ω) for Δt seconds on an arc of radius r = v / ω about the centre
(x - r sin θ, y + r cos θ):

    x' = x - r sin θ + r sin(θ + ω Δt)
    y' = y + r cos θ - r cos(θ + ω Δt)
    θ' = θ + ω Δt + γ Δt

(γ = 0 deterministically; a straight line x' = x + v Δt cos θ, y' = y + v Δt sin θ when ω = 0; the code
uses the equivalent chord form, see ``_arc``). Sampling
perturbs the command with zero-mean Gaussian noise whose variances grow with the command:

    v̂ = v + ε(α1 v² + α2 ω²),   ω̂ = ω + ε(α3 v² + α4 ω²),   γ̂ = ε(α5 v² + α6 ω²)

where ε(b²) draws from N(0, b²) (the α terms are variances, as in the book's Table 5.3).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from mjnav.geometry import wrap_angles
from mjnav.motion._poses import FloatArray, PoseLike, as_poses, check_alphas


def _arc(
    x: FloatArray, y: FloatArray, th: FloatArray, v: FloatArray, w: FloatArray, dt: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    # Equivalent chord form of the arc equations: the robot moves 2 r sin(ωΔt/2) = vΔt·sinc(ωΔt/2) along
    # the direction θ + ωΔt/2. It is exact, needs no ω = 0 special case and does not lose precision to
    # the cancellation in r sin(θ + ωΔt) - r sin θ when ω is tiny and r huge.
    dth = w * dt
    chord = v * dt * np.sinc(dth / (2.0 * np.pi))  # np.sinc(z) = sin(πz) / (πz)
    mid = th + 0.5 * dth
    return x + chord * np.cos(mid), y + chord * np.sin(mid), th + dth


def velocity_motion(pose: PoseLike, v_mps: float, omega_radps: float, dt_s: float) -> FloatArray:
    """Deterministic velocity motion model: the pose after driving (v, ω) for Δt on an exact arc.

    Args:
        pose: (3,) or (N, 3) poses (x m, y m, θ rad), or a :class:`~mjnav.geometry.Pose2D`.
        v_mps: forward speed v, m/s.
        omega_radps: yaw rate ω, rad/s (0: straight line).
        dt_s: duration Δt, s, >= 0.

    Returns:
        Poses with the input's shape, θ wrapped to [-π, π).
    """
    if not (math.isfinite(v_mps) and math.isfinite(omega_radps) and math.isfinite(dt_s) and dt_s >= 0.0):
        raise ValueError(f"need finite v, omega and dt >= 0, got ({v_mps}, {omega_radps}, {dt_s})")
    p = as_poses(pose)
    x, y, th = _arc(p[..., 0], p[..., 1], p[..., 2], np.asarray(v_mps), np.asarray(omega_radps), dt_s)
    return np.stack((x, y, wrap_angles(th)), axis=-1)


def sample_velocity_motion(
    poses: PoseLike,
    v_mps: float,
    omega_radps: float,
    dt_s: float,
    alphas: ArrayLike,
    rng: np.random.Generator,
) -> FloatArray:
    """Sample the velocity motion model once per pose (e.g. for every particle of a filter).

    Args:
        poses: (N, 3) or (3,) poses (x m, y m, θ rad), or a Pose2D.
        v_mps: commanded forward speed, m/s.
        omega_radps: commanded yaw rate, rad/s.
        dt_s: duration, s, >= 0.
        alphas: (α1, .., α6) noise parameters (variances per squared command, see the module docstring).
        rng: random generator.

    Returns:
        Sampled poses with the input's shape, θ wrapped to [-π, π).
    """
    if not (math.isfinite(v_mps) and math.isfinite(omega_radps) and math.isfinite(dt_s) and dt_s >= 0.0):
        raise ValueError(f"need finite v, omega and dt >= 0, got ({v_mps}, {omega_radps}, {dt_s})")
    a = check_alphas(alphas, 6)
    p = as_poses(poses)
    shape = p.shape[:-1]
    v2, w2 = v_mps * v_mps, omega_radps * omega_radps
    v_hat = v_mps + rng.normal(0.0, math.sqrt(a[0] * v2 + a[1] * w2), shape)
    w_hat = omega_radps + rng.normal(0.0, math.sqrt(a[2] * v2 + a[3] * w2), shape)
    g_hat = rng.normal(0.0, math.sqrt(a[4] * v2 + a[5] * w2), shape)
    x, y, th = _arc(p[..., 0], p[..., 1], p[..., 2], v_hat, w_hat, dt_s)
    return np.stack((x, y, wrap_angles(th + g_hat * dt_s)), axis=-1)

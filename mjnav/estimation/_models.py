"""Range-bearing measurement model and velocity-motion Jacobians shared by EKF-SLAM and FastSLAM.

Measurement of landmark (mx, my) from pose (x, y, θ), with δ = (mx − x, my − y), q = |δ|²:

    z = (√q, atan2(δy, δx) − θ)            (range m, bearing rad in the robot frame, wrapped)

Motion: :func:`mjnav.motion.velocity_motion` in its chord form x' = x + c cos(θ + ωΔt/2), y' = y + c sin(θ + ωΔt/2),
θ' = θ + ωΔt + γΔt with c = vΔt·sin(a)/a, a = ωΔt/2; the Jacobians below are of that exact form (no ω = 0 case).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def range_bearing(pose: FloatArray, landmarks: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Predicted measurements and Jacobians.

    Args:
        pose: (3,) robot pose.
        landmarks: (M, 2) landmark positions, metres.

    Returns:
        z_pred (M, 2), H_pose (M, 2, 3) = ∂z/∂pose, H_landmark (M, 2, 2) = ∂z/∂landmark.
    """
    dx = landmarks[:, 0] - pose[0]
    dy = landmarks[:, 1] - pose[1]
    q = np.maximum(dx * dx + dy * dy, 1e-12)
    r = np.sqrt(q)
    z = np.stack((r, np.mod(np.arctan2(dy, dx) - pose[2] + np.pi, 2.0 * np.pi) - np.pi), axis=-1)
    Hl = np.empty((landmarks.shape[0], 2, 2))
    Hl[:, 0, 0] = dx / r
    Hl[:, 0, 1] = dy / r
    Hl[:, 1, 0] = -dy / q
    Hl[:, 1, 1] = dx / q
    Hp = np.zeros((landmarks.shape[0], 2, 3))
    Hp[:, :, :2] = -Hl
    Hp[:, 1, 2] = -1.0
    return z, Hp, Hl


def inverse_range_bearing(pose: FloatArray, z: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Landmark positions from observations and the Jacobians of that map.

    Args:
        pose: (3,) robot pose.
        z: (K, 2) range (m), bearing (rad).

    Returns:
        landmarks (K, 2), G_pose (K, 2, 3) = ∂m/∂pose, G_z (K, 2, 2) = ∂m/∂z.
    """
    a = pose[2] + z[:, 1]
    c, s = np.cos(a), np.sin(a)
    r = z[:, 0]
    lm = np.stack((pose[0] + r * c, pose[1] + r * s), axis=-1)
    Gp = np.zeros((z.shape[0], 2, 3))
    Gp[:, 0, 0] = 1.0
    Gp[:, 1, 1] = 1.0
    Gp[:, 0, 2] = -r * s
    Gp[:, 1, 2] = r * c
    Gz = np.empty((z.shape[0], 2, 2))
    Gz[:, 0, 0] = c
    Gz[:, 0, 1] = -r * s
    Gz[:, 1, 0] = s
    Gz[:, 1, 1] = r * c
    return lm, Gp, Gz


def velocity_jacobians(theta: float, v: float, w: float, dt: float) -> tuple[FloatArray, FloatArray]:
    """Jacobians of the velocity motion model at heading θ and command (v, ω) for Δt.

    Returns:
        G (3, 3) = ∂pose'/∂pose and V (3, 3) = ∂pose'/∂(v, ω, γ).
    """
    a = 0.5 * w * dt
    if abs(a) < 1e-4:
        sa = 1.0 - a * a / 6.0
        dsa = -a / 3.0 + a**3 / 30.0
    else:
        sa = math.sin(a) / a
        dsa = (a * math.cos(a) - math.sin(a)) / (a * a)
    chord = v * dt * sa
    mid = theta + a
    cm, sm = math.cos(mid), math.sin(mid)
    G = np.array([[1.0, 0.0, -chord * sm], [0.0, 1.0, chord * cm], [0.0, 0.0, 1.0]])
    dchord_dw = v * dt * dsa * 0.5 * dt
    V = np.array(
        [
            [dt * sa * cm, dchord_dw * cm - chord * sm * 0.5 * dt, 0.0],
            [dt * sa * sm, dchord_dw * sm + chord * cm * 0.5 * dt, 0.0],
            [0.0, dt, dt],
        ]
    )
    return G, V

"""Outer (position) loops designed by LQR or H∞ on the per-axis double integrator with integral action, and the
P–PI cascade's gains from loop separation.

Per NED axis the attitude loop turns an acceleration command into acceleration, so the outer plant is
``p̈ = u + w`` (w: an acceleration disturbance such as wind). With the error state ``x = [∫e, e, ė]``
(``e = p_ref - p``) and the reference's acceleration fed forward, ``ẋ = A x + B (-(u - a_ref)) + B (-w)``: the law
``u = a_ref + K x = a_ref + k_i ∫e + k_p e + k_d ė`` has exactly the structure of the RPT outer loop, so the designs
return :class:`~mjnav.aerial.control.RptGains` and run in :class:`~mjnav.aerial.control.RptController` (the
cascade's loop-separation check then applies to them as well).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mjnav.aerial.control import RptGains, hinf_state_feedback, lqr
from mjnav.aerial.errors import InvalidParameterError

__all__ = ["PidOuterGains", "hinf_outer_gains", "lqr_outer_gains", "outer_plant", "pid_outer_gains"]


def outer_plant() -> tuple[np.ndarray, np.ndarray]:
    """(A (3, 3), B (3, 1)) of the error state ``[∫e, e, ė]`` with input ``-(u - a_ref)``."""
    a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    b = np.array([[0.0], [0.0], [1.0]])
    return a, b


def _weights(q_int: float, q_pos: float, q_vel: float, r: float) -> tuple[np.ndarray, np.ndarray]:
    for name, v in {"q_int": q_int, "q_pos": q_pos, "q_vel": q_vel}.items():
        if not (math.isfinite(v) and v >= 0.0):
            raise InvalidParameterError(f"{name} must be finite and >= 0, got {v}")
    if not (math.isfinite(r) and r > 0.0):
        raise InvalidParameterError(f"r must be finite and > 0, got {r}")
    return np.diag([q_int, q_pos, q_vel]), np.array([[r]])


def _gains(k: np.ndarray) -> RptGains:
    ki, kp, kd = (float(v) for v in np.asarray(k).reshape(3))
    return RptGains(kp=kp, kd=kd, ki=ki, eps=math.nan)


def lqr_outer_gains(q_int: float = 400.0, q_pos: float = 300.0, q_vel: float = 20.0, r: float = 1.0) -> RptGains:
    """LQR outer-loop gains minimising ∫ xᵀ diag(q_int, q_pos, q_vel) x + r (u - a_ref)² dt.

    Raises:
        InvalidParameterError: negative weights or r <= 0.
    """
    a, b = outer_plant()
    q, rr = _weights(q_int, q_pos, q_vel, r)
    return _gains(lqr(a, b, q, rr).K)


def hinf_outer_gains(
    q_int: float = 400.0, q_pos: float = 300.0, q_vel: float = 20.0, r: float = 1.0, suboptimality: float = 1.2
) -> RptGains:
    """H∞ outer-loop gains: the acceleration disturbance w enters like the input; γ = ``suboptimality`` · γ_opt.

    Raises:
        InvalidParameterError: negative weights, r <= 0 or suboptimality <= 1.
    """
    a, b = outer_plant()
    q, rr = _weights(q_int, q_pos, q_vel, r)
    return _gains(hinf_state_feedback(a, b, b, q, rr, suboptimality=suboptimality).K)


@dataclass(frozen=True)
class PidOuterGains:
    """Position P and velocity PI gains of the P–PI cascade (the same on every NED axis).

    Attributes:
        pos_p: position P, 1/s (the position loop's bandwidth).
        vel_p: velocity P, 1/s (the velocity loop's bandwidth).
        vel_i: velocity I, 1/s² (``vel_i / vel_p`` is the PI zero, rad/s).
    """

    pos_p: float
    vel_p: float
    vel_i: float


def pid_outer_gains(
    attitude_bandwidth_rad_s: float, separation: float = 4.0, integral_separation: float = 5.0
) -> PidOuterGains:
    """P–PI cascade gains by bandwidth separation from the attitude loop it commands.

    Each loop of the cascade is ``separation`` times slower than the loop inside it: the velocity loop (P on the
    integrator from acceleration to velocity, so its bandwidth is ``vel_p``) at ``ω_att / separation``, the position
    loop (P, bandwidth ``pos_p``) at ``vel_p / separation``; the velocity integrator's zero sits
    ``integral_separation`` times below the velocity bandwidth, where it removes steady wind without eating the
    loop's phase margin. With the reference's velocity and acceleration fed forward the law per axis is
    ``a = a_r + vel_p (pos_p e + ė) + vel_i ∫(pos_p e + ė)`` (e = reference − position), whose characteristic
    polynomial ``s³ + vel_p s² + (vel_p pos_p + vel_i) s + vel_i pos_p`` has three real poles near ``pos_p``,
    ``vel_i / vel_p`` and ``vel_p``.

    Args:
        attitude_bandwidth_rad_s: -3 dB bandwidth of the attitude loop, rad/s
            (:meth:`~mjnav.aerial.control.CascadeController.attitude_bandwidth_rad_s`).
        separation: ratio between the bandwidths of nested loops (3–5 is the usual rule).
        integral_separation: ratio of the velocity bandwidth to the PI zero.

    Raises:
        InvalidParameterError: a non-positive bandwidth or a ratio not above 1.
    """
    if not (math.isfinite(attitude_bandwidth_rad_s) and attitude_bandwidth_rad_s > 0.0):
        raise InvalidParameterError(f"attitude_bandwidth_rad_s must be finite and > 0, got {attitude_bandwidth_rad_s}")
    for name, v in {"separation": separation, "integral_separation": integral_separation}.items():
        if not (math.isfinite(v) and v > 1.0):
            raise InvalidParameterError(f"{name} must be finite and > 1, got {v}")
    vel_p = attitude_bandwidth_rad_s / separation
    return PidOuterGains(pos_p=vel_p / separation, vel_p=vel_p, vel_i=vel_p * vel_p / integral_separation)

"""Differential-drive encoder kinematics (private, temporary).

TODO(mjnav.motion): this is the only place in :mod:`mjnav.sim` that converts between wheel rates and body
twist; switch both functions to :mod:`mjnav.motion`'s diff-drive kinematics once it exists.

Convention: W = wheel diameter (m), L = wheel separation (m), wheel rates in rad/s, positive = forward.
    v = W/4 · (ϑ̇_R + ϑ̇_L),    ω = W/(2L) · (ϑ̇_R − ϑ̇_L)
    ϑ̇_R = (2v + Lω)/W,        ϑ̇_L = (2v − Lω)/W
The same formulas map wheel-angle increments (rad) to a travelled distance (m) and a heading change (rad).
"""

from __future__ import annotations


def twist_from_wheels(
    left_radps: float, right_radps: float, wheel_diameter_m: float, separation_m: float
) -> tuple[float, float]:
    """Body twist (v m/s, ω rad/s) from the wheel rates (rad/s); also maps increments (rad) to (m, rad)."""
    v = 0.25 * wheel_diameter_m * (right_radps + left_radps)
    omega = wheel_diameter_m / (2.0 * separation_m) * (right_radps - left_radps)
    return v, omega


def wheels_from_twist(
    v_mps: float, omega_radps: float, wheel_diameter_m: float, separation_m: float
) -> tuple[float, float]:
    """Wheel rates (left, right) in rad/s that produce the body twist (v m/s, ω rad/s)."""
    left = (2.0 * v_mps - separation_m * omega_radps) / wheel_diameter_m
    right = (2.0 * v_mps + separation_m * omega_radps) / wheel_diameter_m
    return left, right

"""Regulation terms of (regulated) pure pursuit as free functions.

The formulas follow the seed (after Macenski et al., "Regulated Pure Pursuit for Robot Path Tracking",
Autonomous Robots 2023):

* adaptive lookahead L = clamp(v·g, L_min, L_max);
* pure-pursuit curvature κ = 2y'/L², with y' the lateral offset of the lookahead point in the robot frame;
* yaw rate ω = κ·v;
* curvature heuristic v' = v·κ_h/|κ| when |κ| > κ_h (slow down on tight arcs, either turning direction);
* proximity heuristic v' = v·d_O/d_prox when d_O <= d_prox (slow down near obstacles);
* approach slow-down v' = v·d_goal/d_approach inside d_approach of the goal, with a floor so the robot
  still arrives;
* rotate-in-place rate ω = clamp(k·α, ±ω_max) for a large heading error α.

All take and return plain floats (they sit in a 20 Hz control loop).
"""

from __future__ import annotations

import math


def adaptive_lookahead(speed_mps: float, gain_s: float, min_m: float, max_m: float) -> float:
    """Lookahead distance L = clamp(|v|·g, L_min, L_max), metres.

    Args:
        speed_mps: robot speed v, m/s (its magnitude is used).
        gain_s: lookahead time g, seconds.
        min_m: L_min, metres.
        max_m: L_max, metres, >= L_min.
    """
    return min(max(abs(speed_mps) * gain_s, min_m), max_m)


def pursuit_curvature(lateral_offset_m: float, lookahead_m: float) -> float:
    """Curvature κ = 2y'/L² of the arc through the robot tangent to its heading and the lookahead point.

    Args:
        lateral_offset_m: y', lateral offset of the lookahead point in the robot frame (left positive), m.
        lookahead_m: L, distance from the robot to the lookahead point, m, > 0.

    Returns:
        Signed curvature, 1/m (positive: turn left).
    """
    return 2.0 * lateral_offset_m / (lookahead_m * lookahead_m)


def angular_velocity(curvature_invm: float, speed_mps: float) -> float:
    """Yaw rate ω = κ·v, rad/s, that drives speed v along curvature κ."""
    return curvature_invm * speed_mps


def curvature_regulated_speed(
    speed_mps: float, curvature_invm: float, curvature_threshold_invm: float, min_speed_mps: float = 0.0
) -> float:
    """Curvature heuristic: v' = v·κ_h/|κ| when |κ| > κ_h, else v.

    Args:
        speed_mps: nominal speed v, m/s.
        curvature_invm: path/pursuit curvature κ, 1/m (either sign).
        curvature_threshold_invm: κ_h, 1/m, > 0.
        min_speed_mps: floor for the regulated speed (never above v), m/s.

    Returns:
        The regulated speed, m/s.
    """
    k = abs(curvature_invm)
    if k <= curvature_threshold_invm:
        return speed_mps
    return max(speed_mps * curvature_threshold_invm / k, min(min_speed_mps, speed_mps))


def proximity_regulated_speed(speed_mps: float, obstacle_distance_m: float, proximity_distance_m: float) -> float:
    """Proximity heuristic: v' = v·d_O/d_prox when d_O <= d_prox, else v (0 when touching an obstacle).

    Args:
        speed_mps: nominal speed v, m/s.
        obstacle_distance_m: d_O, distance to the nearest obstacle, m (inf: none known).
        proximity_distance_m: d_prox, m, > 0.

    Returns:
        The regulated speed, m/s.
    """
    if obstacle_distance_m > proximity_distance_m:
        return speed_mps
    return speed_mps * max(obstacle_distance_m, 0.0) / proximity_distance_m


def approach_regulated_speed(
    speed_mps: float, distance_to_goal_m: float, approach_distance_m: float, min_speed_mps: float
) -> float:
    """Slow-down on approach: v' = v·d/d_approach inside d_approach of the goal, floored at min_speed.

    Args:
        speed_mps: nominal speed v, m/s.
        distance_to_goal_m: remaining distance d, m.
        approach_distance_m: d_approach, m, > 0.
        min_speed_mps: floor (never above v) so the robot reaches its goal tolerance, m/s.

    Returns:
        The regulated speed, m/s.
    """
    if distance_to_goal_m >= approach_distance_m:
        return speed_mps
    return max(speed_mps * max(distance_to_goal_m, 0.0) / approach_distance_m, min(min_speed_mps, speed_mps))


def rotate_in_place_rate(heading_error_rad: float, gain_per_s: float, max_rate_radps: float) -> float:
    """Yaw rate to turn on the spot towards a heading: ω = clamp(k·α, -ω_max, ω_max), rad/s.

    Args:
        heading_error_rad: α, desired minus current heading, rad (wrapped by the caller).
        gain_per_s: proportional gain k, 1/s.
        max_rate_radps: ω_max, rad/s.
    """
    return max(-max_rate_radps, min(max_rate_radps, gain_per_s * heading_error_rad))


def clamp_yaw_rate(v_mps: float, omega_radps: float, max_omega_radps: float) -> tuple[float, float]:
    """Limit |ω| to ω_max by lowering v in proportion, so the commanded curvature ω/v is kept.

    Returns:
        (v m/s, ω rad/s).
    """
    if abs(omega_radps) <= max_omega_radps:
        return v_mps, omega_radps
    scale = max_omega_radps / abs(omega_radps)
    return v_mps * scale, math.copysign(max_omega_radps, omega_radps)

"""Obstacle distance from a planar scan, for the proximity heuristic of pure pursuit."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray


def nearest_obstacle_ahead(
    angles_rad: ArrayLike,
    ranges_m: ArrayLike,
    *,
    sector_rad: float,
    range_min_m: float,
    robot_radius_m: float,
    ignore: ArrayLike | None = None,
) -> float:
    """Distance from the robot's edge to the nearest valid return within the front sector, metres.

    Args:
        angles_rad: (N,) beam angles in the robot frame (0 = straight ahead), radians; any wrapping.
        ranges_m: (N,) ranges from the robot centre, metres; non-finite values and readings below ``range_min_m``
            (REP-117 "no return" / "too close" / invalid) are ignored.
        sector_rad: full width of the sector centred on the heading, radians.
        range_min_m: the sensor's minimum range, metres.
        robot_radius_m: subtracted from the range: the distance is from the robot's edge, clipped at 0.
        ignore: (N,) bool, True for beams whose return does not count (e.g. an obstacle moving away from the
            robot, :func:`moving_away`); None: every beam counts.

    Returns:
        The distance d_O, metres; ``inf`` when no valid return lies in the sector.
    """
    a = np.asarray(angles_rad, dtype=np.float64)
    r = np.asarray(ranges_m, dtype=np.float64)
    if a.shape != r.shape:
        raise ValueError(f"angles and ranges differ in shape: {a.shape} vs {r.shape}")
    bearing = np.abs(np.arctan2(np.sin(a), np.cos(a)))
    valid = (bearing <= 0.5 * sector_rad) & np.isfinite(r) & (r >= range_min_m)
    if ignore is not None:
        skip = np.asarray(ignore, dtype=bool)
        if skip.shape != r.shape:
            raise ValueError(f"ignore and ranges differ in shape: {skip.shape} vs {r.shape}")
        valid &= ~skip
    if not valid.any():
        return math.inf
    return max(0.0, float(r[valid].min()) - robot_radius_m)


def moving_away(points_xy: ArrayLike, velocities_mps: ArrayLike, robot_xy: tuple[float, float]) -> NDArray[np.bool_]:
    """(M,) True for the points that move away from the robot: their velocity has a positive component along the
    line from the robot to them (their distance from it grows; the robot's own motion not counted).

    A static point (zero velocity) never moves away, nor does one moving across the line of sight only. The
    proximity heuristic leaves such points out: an obstacle that recedes by itself is no reason to creep; driving
    into the space it leaves is the collision check's business, which predicts it (see
    :mod:`mjnav.control.collision`).

    Args:
        points_xy: (M, 2) points in a fixed frame, metres.
        velocities_mps: (M, 2) their velocities in that frame, m/s.
        robot_xy: (x, y) of the robot's centre in that frame, metres.
    """
    p = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
    u = np.asarray(velocities_mps, dtype=np.float64).reshape(-1, 2)
    if p.shape != u.shape:
        raise ValueError(f"points and velocities differ in shape: {p.shape} vs {u.shape}")
    rel = p - np.asarray(robot_xy, dtype=np.float64)
    return np.asarray(np.sum(rel * u, axis=1) > 0.0)

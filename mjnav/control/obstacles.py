"""Obstacle distance from a planar scan, for the proximity heuristic of pure pursuit."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike


def nearest_obstacle_ahead(
    angles_rad: ArrayLike, ranges_m: ArrayLike, *, sector_rad: float, range_min_m: float, robot_radius_m: float
) -> float:
    """Distance from the robot's edge to the nearest valid return within the front sector, metres.

    Args:
        angles_rad: (N,) beam angles in the robot frame (0 = straight ahead), radians; any wrapping.
        ranges_m: (N,) ranges from the robot centre, metres; non-finite values and readings below ``range_min_m``
            (REP-117 "no return" / "too close" / invalid) are ignored.
        sector_rad: full width of the sector centred on the heading, radians.
        range_min_m: the sensor's minimum range, metres.
        robot_radius_m: subtracted from the range: the distance is from the robot's edge, clipped at 0.

    Returns:
        The distance d_O, metres; ``inf`` when no valid return lies in the sector.
    """
    a = np.asarray(angles_rad, dtype=np.float64)
    r = np.asarray(ranges_m, dtype=np.float64)
    if a.shape != r.shape:
        raise ValueError(f"angles and ranges differ in shape: {a.shape} vs {r.shape}")
    bearing = np.abs(np.arctan2(np.sin(a), np.cos(a)))
    valid = (bearing <= 0.5 * sector_rad) & np.isfinite(r) & (r >= range_min_m)
    if not valid.any():
        return math.inf
    return max(0.0, float(r[valid].min()) - robot_radius_m)

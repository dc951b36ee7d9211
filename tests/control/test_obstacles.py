"""Nearest obstacle in the front sector, for the proximity heuristic."""

from __future__ import annotations

import math

import numpy as np

from mjnav.control import nearest_obstacle_ahead


def test_front_sector_only_valid_returns_minus_radius() -> None:
    angles = np.radians([0.0, 30.0, 90.0, 180.0, -20.0, 10.0])
    ranges = np.array([2.0, 1.0, 0.3, 0.2, math.inf, math.nan])
    d = nearest_obstacle_ahead(angles, ranges, sector_rad=math.radians(80), range_min_m=0.1, robot_radius_m=0.2)
    assert d == 0.8  # the 1.0 m return at 30°; 90° and 180° are outside ±40°, inf/NaN ignored
    assert nearest_obstacle_ahead(angles, ranges, sector_rad=0.1, range_min_m=0.1, robot_radius_m=0.2) == 1.8
    assert math.isinf(nearest_obstacle_ahead([0.0], [math.inf], sector_rad=1.0, range_min_m=0.1, robot_radius_m=0.2))
    # wrapped angles count too, and a return inside the robot's radius clips at 0
    assert nearest_obstacle_ahead([2 * math.pi], [0.1], sector_rad=1.0, range_min_m=0.05, robot_radius_m=0.2) == 0.0

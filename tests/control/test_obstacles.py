"""Nearest obstacle in the front sector, for the proximity heuristic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.control import moving_away, nearest_obstacle_ahead


def test_front_sector_only_valid_returns_minus_radius() -> None:
    angles = np.radians([0.0, 30.0, 90.0, 180.0, -20.0, 10.0])
    ranges = np.array([2.0, 1.0, 0.3, 0.2, math.inf, math.nan])
    d = nearest_obstacle_ahead(angles, ranges, sector_rad=math.radians(80), range_min_m=0.1, robot_radius_m=0.2)
    assert d == 0.8  # the 1.0 m return at 30°; 90° and 180° are outside ±40°, inf/NaN ignored
    assert nearest_obstacle_ahead(angles, ranges, sector_rad=0.1, range_min_m=0.1, robot_radius_m=0.2) == 1.8
    assert math.isinf(nearest_obstacle_ahead([0.0], [math.inf], sector_rad=1.0, range_min_m=0.1, robot_radius_m=0.2))
    # wrapped angles count too, and a return inside the robot's radius clips at 0
    assert nearest_obstacle_ahead([2 * math.pi], [0.1], sector_rad=1.0, range_min_m=0.05, robot_radius_m=0.2) == 0.0


def test_ignored_beams_do_not_count() -> None:
    angles = np.radians([0.0, 10.0, 20.0])
    ranges = np.array([0.5, 0.8, 1.2])
    kw = {"sector_rad": 1.0, "range_min_m": 0.1, "robot_radius_m": 0.2}
    assert nearest_obstacle_ahead(angles, ranges, **kw) == pytest.approx(0.3)
    assert nearest_obstacle_ahead(angles, ranges, ignore=[True, False, False], **kw) == pytest.approx(0.6)
    assert math.isinf(nearest_obstacle_ahead(angles, ranges, ignore=[True, True, True], **kw))
    with pytest.raises(ValueError):
        nearest_obstacle_ahead(angles, ranges, ignore=[True], **kw)


def test_moving_away_is_a_positive_velocity_component_along_the_line_of_sight() -> None:
    robot = (1.0, 2.0)
    points = np.array([[2.0, 2.0], [2.0, 2.0], [2.0, 2.0], [2.0, 2.0], [1.0, 1.0], [2.0, 1.5]])
    velocities = np.array(
        [
            [0.0, 0.0],  # static
            [0.5, 0.0],  # straight away
            [-0.5, 0.0],  # straight towards the robot
            [0.0, 0.8],  # across the line of sight
            [0.0, -0.8],  # south of the robot, moving further south
            [0.0, 0.8],  # ahead and below the robot's line, moving up towards it
        ]
    )
    assert moving_away(points, velocities, robot).tolist() == [False, True, False, False, True, False]
    assert moving_away(np.zeros((0, 2)), np.zeros((0, 2)), robot).shape == (0,)

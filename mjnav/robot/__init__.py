"""The robot's facts from its description (pure: numpy and the standard library's XML parser).

The sim publishes the robot's MJCF on ``robot_description``; :func:`parse_robot_description` turns it into a
:class:`RobotDescription` (footprint, radius, sensor frames, the lidar), the one place services learn them.
"""

from mjnav.robot.description import (
    CIRCLE_SIDES,
    LIDAR_SITE,
    DescriptionError,
    Frame,
    RobotDescription,
    convex_hull,
    parse_robot_description,
)
from mjnav.robot.lidar import LIDAR_NUMERICS, LidarConfig, lidar_config_from_numerics

__all__ = [
    "CIRCLE_SIDES",
    "LIDAR_NUMERICS",
    "LIDAR_SITE",
    "DescriptionError",
    "Frame",
    "LidarConfig",
    "RobotDescription",
    "convex_hull",
    "lidar_config_from_numerics",
    "parse_robot_description",
]

"""Semantic checks on decoded messages: what a well-formed payload can still get wrong (NaN, ranges, sizes).

:func:`validate` is applied by the bus to every message it receives; a failure becomes a counted, logged rejection.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np

from mjnav.msgs.codec import MessageError, all_finite, check_finite


def _laser_scan(msg: Any) -> None:
    if not 0.0 <= msg.range_min < msg.range_max:
        raise MessageError(f"LaserScan range limits invalid: range_min={msg.range_min}, range_max={msg.range_max}")
    if msg.angle_increment == 0.0 and len(msg.ranges) > 1:
        raise MessageError("LaserScan angle_increment is 0 with more than one range")
    if len(msg.intensities) not in (0, len(msg.ranges)):
        raise MessageError(f"LaserScan has {len(msg.intensities)} intensities for {len(msg.ranges)} ranges")


def _occupancy_grid(msg: Any) -> None:
    info = msg.info
    if not info.resolution > 0.0:
        raise MessageError(f"OccupancyGrid resolution must be > 0, got {info.resolution}")
    if len(msg.data) != info.width * info.height:
        raise MessageError(f"OccupancyGrid has {len(msg.data)} cells for {info.width}x{info.height}")
    data = np.asarray(msg.data)
    if data.size and (data.min() < -1 or data.max() > 100):
        raise MessageError("OccupancyGrid values must be -1 (unknown) or 0..100")


def _quaternion(q: Any, what: str) -> None:
    norm = math.sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w)
    if not 0.5 < norm < 1.5:
        raise MessageError(f"{what} orientation is not a unit quaternion (norm {norm:.3g})")


def _pose_stamped(msg: Any) -> None:
    q = msg.pose.orientation
    if q.x == q.y == q.z == q.w == 0.0:
        return  # orientation left out (a goal with any final heading): see ros.has_orientation
    _quaternion(q, "PoseStamped")


def _path(msg: Any) -> None:
    for i, pose in enumerate(msg.poses):
        _quaternion(pose.pose.orientation, f"Path.poses[{i}]")


def _odometry(msg: Any) -> None:
    _quaternion(msg.pose.pose.orientation, "Odometry")


def _clock(msg: Any) -> None:
    if msg.clock.sec < 0 or not 0 <= msg.clock.nanosec < 1_000_000_000:
        raise MessageError(f"Clock time invalid: sec={msg.clock.sec}, nanosec={msg.clock.nanosec}")


_CHECKS: dict[str, Callable[[Any], None]] = {
    "rosgraph_msgs/msg/Clock": _clock,
    "sensor_msgs/msg/LaserScan": _laser_scan,
    "nav_msgs/msg/OccupancyGrid": _occupancy_grid,
    "geometry_msgs/msg/PoseStamped": _pose_stamped,
    "nav_msgs/msg/Path": _path,
    "nav_msgs/msg/Odometry": _odometry,
}


def validate(msg: Any) -> None:
    """Raise :class:`MessageError` when a decoded message is not usable.

    Every float field must be finite (laser ranges excepted, see REP-117), then type-specific rules apply:
    scan range limits and sizes, grid size and cell values, unit quaternions in poses.
    """
    validator(msg.__msgtype__)(msg)


@cache
def validator(typename: str) -> Callable[[Any], None]:
    """:func:`validate` for messages of ``typename``, resolved once (the bus applies it to every message)."""
    finite = all_finite(typename)
    rule = _CHECKS.get(typename)

    def check(msg: Any) -> None:
        if not finite(msg):
            check_finite(msg)  # raises, naming the field
        if rule is not None:
            rule(msg)

    return check

"""Conversions from ROS 2 messages to what the viewer draws: transforms, map images, point and line arrays.

All functions take decoded messages (rosbags typestore objects) or plain arrays and return numpy arrays or bytes;
they draw nothing themselves.
"""

from __future__ import annotations

import io
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: RGBA of unknown cells (-1): fully transparent, so the floor shows through.
UNKNOWN_RGBA = (0, 0, 0, 0)


def pose_matrix(x_m: float, y_m: float, yaw_rad: float, z_m: float = 0.0) -> NDArray[np.float64]:
    """(4, 4) transform of a planar pose (yaw about +z) lifted to height ``z_m``."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    out = np.eye(4)
    out[0, 0], out[0, 1], out[1, 0], out[1, 1] = c, -s, s, c
    out[0, 3], out[1, 3], out[2, 3] = x_m, y_m, z_m
    return out


def quaternion_matrix(x: float, y: float, z: float, w: float) -> NDArray[np.float64]:
    """(3, 3) rotation of a quaternion (normalised first; the zero quaternion gives the identity)."""
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if n == 0.0:
        return np.eye(3)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def pose_msg_matrix(pose: Any) -> NDArray[np.float64]:
    """(4, 4) transform of a geometry_msgs/Pose (position in metres, any orientation)."""
    return _matrix(pose.position, pose.orientation)


def transform_msg_matrix(transform: Any) -> NDArray[np.float64]:
    """(4, 4) matrix of a geometry_msgs/Transform (translation in metres, any rotation)."""
    return _matrix(transform.translation, transform.rotation)


def _matrix(p: Any, q: Any) -> NDArray[np.float64]:
    out = np.eye(4)
    out[:3, :3] = quaternion_matrix(q.x, q.y, q.z, q.w)
    out[:3, 3] = (p.x, p.y, p.z)
    return out


def occupancy_rgba(grid: Any, kind: str = "map") -> NDArray[np.uint8]:
    """RGBA image of a nav_msgs/OccupancyGrid, ready to texture a plane.

    ``kind="map"``: free (0) white through occupied (100) black, unknown (-1) transparent. ``kind="costmap"``:
    cost 0 transparent, 1–98 a translucent blue→purple ramp, 99–100 (inscribed/lethal) translucent magenta.

    Returns:
        (height, width, 4) uint8 image whose *first row is the grid's last row* (image rows run top-down, grid rows
        run along +y), so it maps onto a plane with +y up.
    """
    width, height = int(grid.info.width), int(grid.info.height)
    cells = np.asarray(grid.data, dtype=np.int16).reshape(height, width)
    rgba = np.zeros((height, width, 4), dtype=np.uint8)
    known = cells >= 0
    if kind == "map":
        shade = np.clip(255 - np.rint(cells * 2.55), 0, 255).astype(np.uint8)
        rgba[..., 0] = rgba[..., 1] = rgba[..., 2] = shade
        rgba[..., 3] = np.where(known, 255, 0)
    elif kind == "costmap":
        t = np.clip(cells, 0, 100) / 100.0
        rgba[..., 0] = np.rint(90 + 165 * t).astype(np.uint8)
        rgba[..., 1] = np.rint(140 * (1 - t)).astype(np.uint8)
        rgba[..., 2] = 255
        rgba[..., 3] = np.where(cells > 0, np.rint(40 + 70 * t), 0).astype(np.uint8)
        rgba[cells >= 99] = (255, 0, 200, 120)
    else:
        raise ValueError(f"kind must be 'map' or 'costmap', got {kind!r}")
    return np.ascontiguousarray(rgba[::-1])


def png_bytes(image: NDArray[np.uint8]) -> bytes:
    """Encode an (H, W, 3|4) uint8 image as PNG (fastest zlib level: maps are redrawn often, and mostly flat)."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG", optimize=False, compress_level=1)
    return buf.getvalue()


def grid_plane_transform(grid: Any, z_m: float = 0.0) -> NDArray[np.float64]:
    """(4, 4) pose of the centre of an OccupancyGrid's area (a plane of ``width·res × height·res`` metres).

    The grid's ``info.origin`` is the pose of the corner of cell (0, 0); the plane's centre is half the grid's size
    along the origin's x and y axes, lifted by ``z_m`` (to draw above the floor).
    """
    info = grid.info
    origin = pose_msg_matrix(info.origin)
    centre = np.eye(4)
    centre[:3, 3] = (0.5 * info.width * info.resolution, 0.5 * info.height * info.resolution, z_m)
    return origin @ centre


def scan_points(scan: Any) -> NDArray[np.float32]:
    """Points of a sensor_msgs/LaserScan in its own frame: (3, N) float32, metres.

    Returns with range in ``[range_min, range_max]`` only (REP-117: ±inf and NaN are no return).
    """
    ranges = np.asarray(scan.ranges, dtype=np.float64)
    angles = scan.angle_min + scan.angle_increment * np.arange(ranges.size)
    valid = np.isfinite(ranges) & (ranges >= scan.range_min) & (ranges <= scan.range_max)
    r, a = ranges[valid], angles[valid]
    return np.vstack([r * np.cos(a), r * np.sin(a), np.zeros_like(r)]).astype(np.float32)


def path_points(path: Any, z_m: float = 0.0) -> NDArray[np.float32]:
    """Positions of a nav_msgs/Path: (3, N) float32, metres, in the path's frame, lifted by ``z_m``."""
    n = len(path.poses)
    out = np.zeros((3, n), dtype=np.float32)
    for i, stamped in enumerate(path.poses):
        p = stamped.pose.position
        out[:, i] = (p.x, p.y, p.z + z_m)
    return out


def rgb_hex(rgba: tuple[float, ...]) -> int:
    """``0xRRGGBB`` of a colour with components in [0, 1]."""
    r, g, b = (round(255 * min(max(c, 0.0), 1.0)) for c in rgba[:3])
    return (r << 16) | (g << 8) | b

"""Where a grid sits in the world: resolution, origin and size, and the cell ↔ world conversions.

Same convention as :class:`~mjnav.mapping.OccupancyGrid` and ``nav_msgs/OccupancyGrid``: cell (row, col) covers
x ∈ [ox + col·res, ox + (col+1)·res), y ∈ [oy + row·res, oy + (row+1)·res); row 0 is the lowest y. A ROS map may
also rotate the grid about its origin by ``yaw_rad`` (the origin pose's yaw, map_server's third origin value): the
same intervals then hold in the grid's own axes, (lx, ly) = R(−yaw)·((x, y) − (ox, oy)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mjnav.mapping.errors import InvalidParameterError


@dataclass(frozen=True, slots=True)
class GridFrame:
    """Placement of an (H, W) grid in the map frame.

    Attributes:
        resolution_m: cell size, metres.
        origin_m: (x, y) of the outer corner of cell (0, 0), metres.
        shape: (H, W) cells.
        yaw_rad: rotation of the grid's axes about the origin, radians (0 for every grid mjnav makes).
    """

    resolution_m: float
    origin_m: tuple[float, float]
    shape: tuple[int, int]
    yaw_rad: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.resolution_m) and self.resolution_m > 0):
            raise InvalidParameterError(f"resolution_m must be > 0, got {self.resolution_m}")
        if not all(math.isfinite(v) for v in self.origin_m):
            raise InvalidParameterError(f"origin_m must be finite, got {self.origin_m}")
        if len(self.shape) != 2 or min(self.shape) < 1:
            raise InvalidParameterError(f"shape must be (H, W) with H, W >= 1, got {self.shape}")
        if not math.isfinite(self.yaw_rad):
            raise InvalidParameterError(f"yaw_rad must be finite, got {self.yaw_rad}")

    def world_to_cell(self, x_m: float, y_m: float) -> tuple[int, int]:
        """(row, col) of the cell holding world point (x, y); may lie outside the grid (see :meth:`contains`)."""
        res = self.resolution_m
        dx, dy = x_m - self.origin_m[0], y_m - self.origin_m[1]
        if self.yaw_rad:
            c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
            dx, dy = c * dx + s * dy, -s * dx + c * dy
        return math.floor(dy / res), math.floor(dx / res)

    def contains(self, row: int, col: int) -> bool:
        """Whether (row, col) is a cell of the grid."""
        return 0 <= row < self.shape[0] and 0 <= col < self.shape[1]

    def cells_to_world(self, cells: ArrayLike) -> NDArray[np.float64]:
        """(N, 2) cell centres (x, y) in metres of (N, 2) (row, col) cells."""
        c = np.asarray(cells, dtype=np.float64).reshape(-1, 2)
        res = self.resolution_m
        lx, ly = (c[:, 1] + 0.5) * res, (c[:, 0] + 0.5) * res
        if self.yaw_rad:
            co, si = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
            lx, ly = co * lx - si * ly, si * lx + co * ly
        return np.column_stack((self.origin_m[0] + lx, self.origin_m[1] + ly))

    def values_at(self, grid: ArrayLike, points: ArrayLike, outside: Any = 0) -> NDArray[Any]:
        """(N,) values of an (H, W) array on this grid at (N, 2) world points; ``outside`` for points off the grid."""
        g = np.asarray(grid)
        idx = self.world_to_cells(points)
        inside = (idx[:, 0] >= 0) & (idx[:, 0] < g.shape[0]) & (idx[:, 1] >= 0) & (idx[:, 1] < g.shape[1])
        out = np.full(len(idx), outside, dtype=g.dtype)
        out[inside] = g[idx[inside, 0], idx[inside, 1]]
        return out

    def world_to_cells(self, points: ArrayLike) -> NDArray[np.int64]:
        """(N, 2) (row, col) cells of (N, 2) world points (x, y); may lie outside the grid."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        res = self.resolution_m
        dx, dy = p[:, 0] - self.origin_m[0], p[:, 1] - self.origin_m[1]
        if self.yaw_rad:
            c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
            dx, dy = c * dx + s * dy, -s * dx + c * dy
        return np.column_stack((np.floor(dy / res), np.floor(dx / res))).astype(np.int64)

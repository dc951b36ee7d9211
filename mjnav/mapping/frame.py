"""Where a grid sits in the world: resolution, origin and size, and the cell ↔ world conversions.

Same convention as :class:`~mjnav.mapping.OccupancyGrid` and ``nav_msgs/OccupancyGrid``: cell (row, col) covers
x ∈ [ox + col·res, ox + (col+1)·res), y ∈ [oy + row·res, oy + (row+1)·res); row 0 is the lowest y.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

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
    """

    resolution_m: float
    origin_m: tuple[float, float]
    shape: tuple[int, int]

    def __post_init__(self) -> None:
        if not (math.isfinite(self.resolution_m) and self.resolution_m > 0):
            raise InvalidParameterError(f"resolution_m must be > 0, got {self.resolution_m}")
        if not all(math.isfinite(v) for v in self.origin_m):
            raise InvalidParameterError(f"origin_m must be finite, got {self.origin_m}")
        if len(self.shape) != 2 or min(self.shape) < 1:
            raise InvalidParameterError(f"shape must be (H, W) with H, W >= 1, got {self.shape}")

    def world_to_cell(self, x_m: float, y_m: float) -> tuple[int, int]:
        """(row, col) of the cell holding world point (x, y); may lie outside the grid (see :meth:`contains`)."""
        res = self.resolution_m
        return math.floor((y_m - self.origin_m[1]) / res), math.floor((x_m - self.origin_m[0]) / res)

    def contains(self, row: int, col: int) -> bool:
        """Whether (row, col) is a cell of the grid."""
        return 0 <= row < self.shape[0] and 0 <= col < self.shape[1]

    def cells_to_world(self, cells: ArrayLike) -> NDArray[np.float64]:
        """(N, 2) cell centres (x, y) in metres of (N, 2) (row, col) cells."""
        c = np.asarray(cells, dtype=np.float64).reshape(-1, 2)
        res = self.resolution_m
        return np.column_stack((self.origin_m[0] + (c[:, 1] + 0.5) * res, self.origin_m[1] + (c[:, 0] + 0.5) * res))

    def world_to_cells(self, points: ArrayLike) -> NDArray[np.int64]:
        """(N, 2) (row, col) cells of (N, 2) world points (x, y); may lie outside the grid."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        res = self.resolution_m
        rows = np.floor((p[:, 1] - self.origin_m[1]) / res)
        cols = np.floor((p[:, 0] - self.origin_m[0]) / res)
        return np.column_stack((rows, cols)).astype(np.int64)

"""Obstacle inflation and clearance from a Euclidean distance transform.

Costmap values follow the ROS ``nav_msgs/OccupancyGrid`` translation of Nav2's costmap_2d costs:

* 100 — lethal: an obstacle cell;
* 99 — inscribed (:attr:`CellState.INFLATED`): a cell whose centre is within ``robot_radius_m`` of an obstacle
  cell centre, so the robot centred there would collide;
* 98·exp(−s·(d − r)) truncated to an integer — the Nav2 inflation-layer decay for
  robot_radius_m < d <= inflation_radius_m (s = ``cost_scaling_factor``, 1/m; r = ``robot_radius_m``);
* 0 — beyond ``inflation_radius_m``;
* −1 — unknown (only with ``unknown="unknown"``).

Distances d are between cell centres, metres, from :func:`scipy.ndimage.distance_transform_edt`.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from mjnav.mapping.errors import InvalidGridError, InvalidParameterError
from mjnav.mapping.grid import CellState

__all__ = [
    "INSCRIBED_COST",
    "LETHAL_COST",
    "MAX_DECAY_COST",
    "clearance_m",
    "inflate_mask",
    "inflation_costmap",
]

#: Cost of an obstacle cell.
LETHAL_COST = 100
#: Cost of a cell within the inscribed (robot) radius of an obstacle; equals :attr:`CellState.INFLATED`.
INSCRIBED_COST = int(CellState.INFLATED)
#: Largest cost of the exponential decay (just outside the inscribed radius).
MAX_DECAY_COST = 98


def _bool_grid(mask: ArrayLike, name: str) -> NDArray[np.bool_]:
    a = np.asarray(mask)
    if a.dtype != np.bool_:
        raise InvalidGridError(f"{name} must be a boolean array (True = obstacle), got dtype {a.dtype}")
    if a.ndim != 2 or a.size == 0:
        raise InvalidGridError(f"{name} must be a non-empty 2-D array, got shape {a.shape}")
    return a


def _resolution(resolution_m: Any) -> float:
    try:
        res = float(resolution_m)
    except (TypeError, ValueError) as exc:
        raise InvalidParameterError(f"resolution_m must be a real number, got {resolution_m!r}") from exc
    if not (math.isfinite(res) and res > 0.0):
        raise InvalidParameterError(f"resolution_m must be finite and > 0, got {res}")
    return res


def _nonneg(value: Any, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise InvalidParameterError(f"{name} must be a real number, got {value!r}") from exc
    if not (math.isfinite(v) and v >= 0.0):
        raise InvalidParameterError(f"{name} must be finite and >= 0, got {v}")
    return v


def _near_box(obstacles: NDArray[np.bool_], resolution_m: float, within_m: float) -> tuple[slice, slice]:
    """Rows and columns of the obstacles' bounding box grown by ``within_m`` (clipped to the grid); it holds every
    obstacle, so a distance transform inside it is exact there, and every cell outside it is farther than
    ``within_m`` from all obstacles."""
    rows = np.flatnonzero(obstacles.any(axis=1))
    cols = np.flatnonzero(obstacles.any(axis=0))
    pad = math.ceil(within_m / resolution_m) + 1 if math.isfinite(within_m) else max(obstacles.shape)
    return (
        slice(max(rows[0] - pad, 0), min(rows[-1] + pad + 1, obstacles.shape[0])),
        slice(max(cols[0] - pad, 0), min(cols[-1] + pad + 1, obstacles.shape[1])),
    )


def _edt(obstacles: NDArray[np.bool_], resolution_m: float, within_m: float = math.inf) -> NDArray[np.float64]:
    """Centre-to-centre Euclidean distance (m) to the nearest True cell; +inf everywhere if there is none.

    With ``within_m`` finite, only distances up to ``within_m`` are exact; cells farther than that from every
    obstacle may get +inf (the transform runs on :func:`_near_box` only: most of a map under construction is empty).
    """
    d = np.full(obstacles.shape, np.inf)
    if obstacles.any():
        box = _near_box(obstacles, resolution_m, within_m)
        d[box] = ndimage.distance_transform_edt(~obstacles[box], sampling=resolution_m)
    return d


def clearance_m(
    obstacles: ArrayLike,
    resolution_m: float,
    *,
    norm: Literal["euclidean", "chebyshev"] = "euclidean",
    within_m: float = math.inf,
) -> NDArray[np.float64]:
    """Distance from every cell centre to the nearest obstacle cell centre.

    Args:
        obstacles: (H, W) bool, True = obstacle (e.g. ``states == CellState.OCCUPIED``, or including unknown
            cells for a conservative answer).
        resolution_m: cell size, metres.
        norm: "euclidean" (default): straight-line distance. "chebyshev": L∞ distance k·res, k = max(|Δrow|,
            |Δcol|) — then an axis-aligned square box of half-width h centred on a cell centre contains no
            obstacle cell *centre* iff h < clearance, and no part of an obstacle cell iff
            h < clearance − res/2, which makes it the right measure for per-point box constraints.
        within_m: distances up to this are exact; a cell farther than this from every obstacle may read +inf.
            A finite value restricts the transform to the obstacles' surroundings (faster on sparse maps), for
            callers that clip the clearance anyway.

    Returns:
        (H, W) float64, metres; 0 on obstacle cells; +inf everywhere if there is no obstacle.

    Raises:
        InvalidGridError: ``obstacles`` is not a non-empty 2-D bool array.
        InvalidParameterError: bad resolution, ``within_m`` or norm.
    """
    obs = _bool_grid(obstacles, "obstacles")
    res = _resolution(resolution_m)
    if not within_m >= 0.0:
        raise InvalidParameterError(f"within_m must be >= 0, got {within_m}")
    if norm == "euclidean":
        return _edt(obs, res, within_m)
    if norm == "chebyshev":
        d = np.full(obs.shape, np.inf)
        if obs.any():
            box = _near_box(obs, res, within_m)
            d[box] = ndimage.distance_transform_cdt(~obs[box], metric="chessboard") * res
        return d
    raise InvalidParameterError(f"norm must be 'euclidean' or 'chebyshev', got {norm!r}")


def inflate_mask(obstacles: ArrayLike, resolution_m: float, radius_m: float) -> NDArray[np.bool_]:
    """Obstacles grown by a radius: the configuration-space obstacle mask of a disc robot.

    Args:
        obstacles: (H, W) bool, True = obstacle.
        resolution_m: cell size, metres.
        radius_m: growth radius, metres (>= 0).

    Returns:
        (H, W) bool, True where the cell centre lies within ``radius_m`` (inclusive) of an obstacle cell
        centre.

    Raises:
        InvalidGridError: ``obstacles`` is not a non-empty 2-D bool array.
        InvalidParameterError: bad resolution or radius.
    """
    obs = _bool_grid(obstacles, "obstacles")
    res = _resolution(resolution_m)
    radius = _nonneg(radius_m, "radius_m")
    return _dilate_disc(obs, res, radius)


def _dilate_disc(obstacles: NDArray[np.bool_], resolution_m: float, radius_m: float) -> NDArray[np.bool_]:
    """:func:`inflate_mask` as a dilation by the disc of cell offsets within ``radius_m``, one row of the disc at a
    time: each distinct half-width is one running maximum along the rows, OR-ed in at the offsets of the disc's rows
    that have it. Three grids of memory, where the distance transform took 41 bytes a cell (723 MB on 17.6 M)."""
    h, w = obstacles.shape
    reach = int(radius_m / resolution_m) + 1
    offsets = np.arange(-reach, reach + 1)
    inside = np.hypot(offsets[:, None] * resolution_m, offsets[None, :] * resolution_m) <= radius_m
    half = {int(dy): int(np.abs(offsets[row]).max()) for dy, row in zip(offsets, inside, strict=True) if row.any()}
    out = np.zeros((h, w), dtype=bool)
    cells = obstacles.view(np.uint8)
    for width in sorted(set(half.values())):
        grown = ndimage.maximum_filter1d(cells, 2 * width + 1, axis=1, mode="constant", cval=0).view(bool)
        for dy, hw in half.items():
            if hw != width or abs(dy) >= h:
                continue
            if dy >= 0:  # a cell is blocked by an obstacle dy rows below it
                out[: h - dy] |= grown[dy:]
            else:
                out[-dy:] |= grown[: h + dy]
    return out


def inflation_costmap(
    occupancy: ArrayLike,
    resolution_m: float,
    robot_radius_m: float,
    inflation_radius_m: float,
    cost_scaling_factor: float = 3.0,
    *,
    occupied_threshold: int = 65,
    unknown: Literal["unknown", "free", "lethal"] = "unknown",
) -> NDArray[np.int8]:
    """Nav2-style inflated costmap (values 0–100, see the module docstring) from a ROS occupancy array.

    Args:
        occupancy: (H, W) integer ROS occupancy values (−1 unknown, 0..100), e.g. ``OccupancyGrid.states()``,
            ``OccupancyGrid.to_ros()`` or ``RosMap.occupancy``; the layout is kept (row 0 = lowest y). A bool
            array is accepted as an obstacle mask (True = 100, False = 0).
        resolution_m: cell size, metres.
        robot_radius_m: inscribed radius r of the robot, metres (>= 0).
        inflation_radius_m: radius beyond which the cost is 0, metres (>= robot_radius_m).
        cost_scaling_factor: decay rate s of the exponential, 1/m (>= 0); larger = faster decay.
        occupied_threshold: cells with value >= this (1..100) are obstacles.
        unknown: how unknown (−1) cells are treated.
            "unknown" (default): not obstacles; they stay −1 unless within the inscribed radius of an
            obstacle, where they get 99 (Nav2's inflation layer with ``inflate_unknown: false``).
            "free": treated as free space and costed by distance like any free cell.
            "lethal": treated as obstacles (100) and inflated like them.

    Returns:
        (H, W) int8 costs in 0..100, plus −1 for unknown cells with ``unknown="unknown"``.

    Raises:
        InvalidGridError: not a non-empty 2-D integer array, or values outside {−1} ∪ [0, 100].
        InvalidParameterError: bad radii, scaling factor, threshold or ``unknown`` option.
    """
    occ = np.asarray(occupancy)
    if occ.dtype == np.bool_:
        occ = np.where(occ, np.int8(100), np.int8(0))
    if occ.dtype.kind not in "iu":
        raise InvalidGridError(f"occupancy must have an integer dtype (int8 ROS values), got {occ.dtype}")
    if occ.ndim != 2 or occ.size == 0:
        raise InvalidGridError(f"occupancy must be a non-empty 2-D array, got shape {occ.shape}")
    if occ.min() < -1 or occ.max() > 100:
        raise InvalidGridError("occupancy values must be -1 (unknown) or 0..100")
    res = _resolution(resolution_m)
    r_in = _nonneg(robot_radius_m, "robot_radius_m")
    r_out = _nonneg(inflation_radius_m, "inflation_radius_m")
    if r_out < r_in:
        raise InvalidParameterError(f"inflation_radius_m ({r_out}) must be >= robot_radius_m ({r_in})")
    scale = _nonneg(cost_scaling_factor, "cost_scaling_factor")
    if isinstance(occupied_threshold, bool) or not isinstance(occupied_threshold, int | np.integer):
        raise InvalidParameterError(f"occupied_threshold must be an integer, got {occupied_threshold!r}")
    if not 1 <= int(occupied_threshold) <= 100:
        raise InvalidParameterError(f"occupied_threshold must be in 1..100, got {occupied_threshold}")
    if unknown not in ("unknown", "free", "lethal"):
        raise InvalidParameterError(f"unknown must be 'unknown', 'free' or 'lethal', got {unknown!r}")

    is_unknown = occ < 0
    obstacles = occ >= int(occupied_threshold)
    if unknown == "lethal":
        obstacles = obstacles | is_unknown
    d = _edt(obstacles, res, within_m=r_out)  # cells farther than r_out cost 0: their exact distance is not needed
    cost = np.zeros(occ.shape, dtype=np.int8)
    decay = (d > r_in) & (d <= r_out)
    cost[decay] = np.floor(MAX_DECAY_COST * np.exp(-scale * (d[decay] - r_in))).astype(np.int8)
    cost[(d > 0.0) & (d <= r_in)] = INSCRIBED_COST
    cost[obstacles] = LETHAL_COST
    if unknown == "unknown":
        cost[is_unknown & (cost < INSCRIBED_COST)] = -1
    return cost

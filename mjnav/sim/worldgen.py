"""Turn an occupancy grid (ROS map_server ``.yaml`` + image, or Moving AI ``.map``) into a MuJoCo world.

Occupied cells are merged into few axis-aligned boxes by greedy rectangle merging (:func:`merge_rectangles`),
a floor and the robot are added, and the scene is written as one self-contained MJCF file (includes and the
robot attachment flattened by ``MjSpec.to_xml``), so it can be moved anywhere.

Grid convention here: ``occupied[row, col]`` with row 0 = lowest y (the ``nav_msgs/OccupancyGrid`` order);
cell (r, c) covers x in origin_x + [c, c+1]·res, y in origin_y + [r, r+1]·res (before the origin's yaw).

* ROS maps keep their own ``resolution`` and ``origin`` (read by :func:`mjnav.mapping.ros_map.read_ros_map`),
  so the world's frame *is* the map frame.
* Moving AI maps have no scale: each cell becomes ``resolution_m`` metres (default 0.5) with the origin at
  (0, 0). Their row 0 is the top of the picture, so it becomes the highest y: the top camera shows the map as
  printed, and a scenario cell (x = col, y = row) lies at ((col + 0.5)·res, (H − 1 − row + 0.5)·res).

Start and goal: given explicitly, or chosen automatically in the largest connected region of *known* free cells
that keep at least ``clearance_m`` from every obstacle and every unknown cell (a saved map's unexplored outside is
never chosen): start = the region cell nearest the map centre, goal = the region cell farthest from the start; or,
with a seeded ``numpy.random.Generator`` (``mjnav demo --world MAP``), a random region cell as start and a random
region cell within a distance band of it as goal — the region is connected, so the goal is reachable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from numba import njit
from numpy.typing import NDArray

from mjnav.geometry import Pose2D
from mjnav.sim.errors import MapConversionError
from mjnav.sim.worlds import GOAL_NUMERIC, MJCF_DIR

#: Cell size given to Moving AI maps when none is specified, metres.
DEFAULT_MOVINGAI_RESOLUTION_M = 0.5


@dataclass(frozen=True, slots=True)
class GridMap:
    """An occupancy grid ready to become a world.

    Attributes:
        occupied: (H, W) bool, True = wall, row 0 = lowest y.
        resolution_m: cell size, metres.
        origin_m: (x, y, yaw) of the outer corner of cell (0, 0) in the world frame, metres and radians.
        name: a name for the world (the map file stem).
        unknown: (H, W) bool, True = the map did not know the cell (free floor in the world, but never a start or
            goal); ``None`` = every cell known.
    """

    occupied: NDArray[np.bool_]
    resolution_m: float
    origin_m: tuple[float, float, float]
    name: str
    unknown: NDArray[np.bool_] | None = None

    def cell_to_world(self, row: float, col: float) -> tuple[float, float]:
        """World (x, y) in metres of the centre of cell (row, col)."""
        lx, ly = (col + 0.5) * self.resolution_m, (row + 0.5) * self.resolution_m
        ox, oy, yaw = self.origin_m
        c, s = math.cos(yaw), math.sin(yaw)
        return ox + c * lx - s * ly, oy + s * lx + c * ly


@dataclass(frozen=True, slots=True)
class SceneSummary:
    """What :func:`write_scene_from_map` produced.

    Attributes:
        path: the written MJCF file.
        occupied_cells: number of occupied cells (including the added border).
        boxes: number of wall boxes after merging.
        start: robot start pose, world frame.
        goal: default goal pose, world frame.
    """

    path: Path
    occupied_cells: int
    boxes: int
    start: Pose2D
    goal: Pose2D


@njit(cache=True)
def _merge_kernel(occupied: NDArray[np.bool_]) -> NDArray[np.int64]:  # pragma: no cover - compiled
    h, w = occupied.shape
    covered = np.zeros((h, w), dtype=np.bool_)
    out = np.empty((h * w, 4), dtype=np.int64)
    n = 0
    for r in range(h):
        c = 0
        while c < w:
            if not occupied[r, c] or covered[r, c]:
                c += 1
                continue
            c1 = c
            while c1 < w and occupied[r, c1] and not covered[r, c1]:
                c1 += 1
            r1 = r + 1
            while r1 < h:
                ok = True
                for cc in range(c, c1):
                    if not occupied[r1, cc] or covered[r1, cc]:
                        ok = False
                        break
                if not ok:
                    break
                r1 += 1
            for rr in range(r, r1):
                for cc in range(c, c1):
                    covered[rr, cc] = True
            out[n, 0] = r
            out[n, 1] = c
            out[n, 2] = r1 - r
            out[n, 3] = c1 - c
            n += 1
            c = c1
    return out[:n]


def merge_rectangles(occupied: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Cover the True cells of a grid exactly with few non-overlapping rectangles (greedy).

    Scans rows bottom-up, left to right; at each uncovered occupied cell grows a run to the right, then
    extends the run upwards while the whole run stays occupied and uncovered.

    Args:
        occupied: (H, W) bool grid.

    Returns:
        (K, 4) int64 rectangles (row, col, n_rows, n_cols), together covering exactly the True cells.

    Raises:
        MapConversionError: ``occupied`` is not a 2-D array.
    """
    grid = np.asarray(occupied, dtype=np.bool_)
    if grid.ndim != 2:
        raise MapConversionError(f"occupied must be a 2-D grid, got shape {grid.shape}")
    return _merge_kernel(np.ascontiguousarray(grid))


def load_grid_map(path: str | Path, *, resolution_m: float | None = None, unknown_is_occupied: bool = False) -> GridMap:
    """Read a ROS map (``.yaml``/``.yml`` + its image) or a Moving AI map (``.map``) as a :class:`GridMap`.

    Args:
        path: the map file.
        resolution_m: cell size for a Moving AI map, metres (default 0.5); must be omitted for ROS maps,
            which carry their own.
        unknown_is_occupied: ROS maps only — turn unknown cells into walls too (default: only occupied cells).

    Raises:
        MapConversionError: unknown suffix, unreadable or malformed file, bad resolution.
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".map":
        from mjnav.mapping.movingai import read_movingai_map

        res = DEFAULT_MOVINGAI_RESOLUTION_M if resolution_m is None else float(resolution_m)
        if not (math.isfinite(res) and res > 0.0):
            raise MapConversionError(f"resolution_m must be positive, got {resolution_m}")
        try:
            mai = read_movingai_map(p)
        except (OSError, ValueError) as exc:
            raise MapConversionError(f"cannot read Moving AI map {p}: {exc}") from exc
        return GridMap(np.asarray(mai.blocked)[::-1].copy(), res, (0.0, 0.0, 0.0), p.stem)
    if suffix in (".yaml", ".yml"):
        from mjnav.mapping.ros_map import read_ros_map

        if resolution_m is not None:
            raise MapConversionError("a ROS map has its own resolution; do not pass resolution_m")
        try:
            ros = read_ros_map(p)
        except (OSError, ValueError) as exc:
            raise MapConversionError(f"cannot read ROS map {p}: {exc}") from exc
        occ = np.asarray(ros.occupied_mask(unknown_is_occupied=unknown_is_occupied), dtype=np.bool_)
        unknown = (np.asarray(ros.occupancy) < 0) & ~occ
        ox, oy, yaw = (float(v) for v in ros.origin_m)
        return GridMap(occ, float(ros.resolution_m), (ox, oy, yaw), p.stem, unknown if unknown.any() else None)
    raise MapConversionError(f"{p}: unknown map format {suffix!r}; use a ROS .yaml (+ image) or a Moving AI .map")


def add_border(grid: GridMap) -> GridMap:
    """The map with a one-cell wall ring around it (origin moved out by one cell), so the world is closed."""
    h, w = grid.occupied.shape
    occ = np.ones((h + 2, w + 2), dtype=np.bool_)
    occ[1:-1, 1:-1] = grid.occupied
    unknown = None
    if grid.unknown is not None:
        unknown = np.zeros_like(occ)
        unknown[1:-1, 1:-1] = grid.unknown
    ox, oy, yaw = grid.origin_m
    c, s = math.cos(yaw), math.sin(yaw)
    res = grid.resolution_m
    return GridMap(occ, res, (ox - res * (c - s), oy - res * (s + c), yaw), grid.name, unknown)


def choose_start_goal(
    grid: GridMap,
    clearance_m: float,
    rng: np.random.Generator | None = None,
    *,
    min_distance_m: float = 2.0,
    max_distance_m: float = 12.0,
) -> tuple[Pose2D, Pose2D]:
    """Pick a start and a goal with at least ``clearance_m`` to every wall and unknown cell (module docstring).

    Both lie in the largest connected region of such cells, so the goal is reachable from the start for a robot
    of radius ``clearance_m``. The start faces the goal; the goal keeps that heading.

    Args:
        grid: the map.
        clearance_m: free distance to walls and unknown cells, metres.
        rng: ``None``: start = the region cell nearest the map centre, goal = the region cell farthest from it.
            A generator: start = a random region cell, goal = a random region cell whose straight-line distance
            from the start lies in [``min_distance_m``, ``max_distance_m``] (the band is widened to the nearest
            achievable distance when no cell lies in it).
        min_distance_m, max_distance_m: the goal's distance band with ``rng``, metres.

    Raises:
        MapConversionError: no free cell has that much clearance, or the region is a single cell.
    """
    labels = _regions(grid, clearance_m)
    sizes = np.bincount(labels.ravel())[1:]
    region = np.argwhere(labels == int(np.argmax(sizes)) + 1)
    if len(region) < 2:
        raise MapConversionError(
            f"{grid.name}: only one cell keeps {clearance_m:.2f} m from the walls; use a larger resolution "
            "or give the start and goal explicitly"
        )
    if rng is None:
        h, w = grid.occupied.shape
        centre = np.array([(h - 1) / 2.0, (w - 1) / 2.0])
        start_rc = region[int(np.argmin(np.sum((region - centre) ** 2, axis=1)))]
        goal_rc = region[int(np.argmax(np.sum((region - start_rc) ** 2, axis=1)))]
    else:
        start_rc = region[int(rng.integers(len(region)))]
        goal_rc = _goal_in_band(grid, region, start_rc, rng, min_distance_m, max_distance_m)
    sx, sy = grid.cell_to_world(float(start_rc[0]), float(start_rc[1]))
    gx, gy = grid.cell_to_world(float(goal_rc[0]), float(goal_rc[1]))
    heading = math.atan2(gy - sy, gx - sx) if (gx, gy) != (sx, sy) else 0.0
    return Pose2D(sx, sy, heading), Pose2D(gx, gy, heading)


def _regions(grid: GridMap, clearance_m: float) -> NDArray[np.int32]:
    """(H, W) labels of the connected regions of known free cells keeping ``clearance_m`` from walls and unknown
    cells (0 = not such a cell).

    Raises:
        MapConversionError: there is no such cell.
    """
    from scipy import ndimage

    blocked = grid.occupied if grid.unknown is None else grid.occupied | grid.unknown
    clearance = ndimage.distance_transform_edt(~blocked) * grid.resolution_m
    labels, n = ndimage.label(clearance >= clearance_m + 0.5 * grid.resolution_m)
    if n == 0:
        raise MapConversionError(
            f"{grid.name}: no free cell keeps {clearance_m:.2f} m from the walls; the robot does not fit"
        )
    return np.asarray(labels, dtype=np.int32)


def _goal_in_band(
    grid: GridMap,
    region: NDArray[np.int64],
    start_rc: NDArray[np.int64],
    rng: np.random.Generator,
    min_distance_m: float,
    max_distance_m: float,
) -> NDArray[np.int64]:
    """A random cell of ``region`` (K, 2) whose distance from ``start_rc`` lies in the band (or is nearest it)."""
    if not 0.0 <= min_distance_m <= max_distance_m:
        raise MapConversionError(f"need 0 <= min_distance_m <= max_distance_m, got {min_distance_m}, {max_distance_m}")
    dist = np.sqrt(np.sum((region - start_rc) ** 2, axis=1)) * grid.resolution_m
    band = np.flatnonzero((dist >= min_distance_m) & (dist <= max_distance_m))
    if len(band) == 0:  # nothing in the band: the achievable distance nearest to it
        gap = np.maximum(min_distance_m - dist, dist - max_distance_m)
        gap[dist == 0.0] = np.inf
        band = np.flatnonzero(gap == gap.min())
    return region[int(band[int(rng.integers(len(band)))])]


def choose_goal(
    grid: GridMap,
    start: Pose2D,
    clearance_m: float,
    rng: np.random.Generator,
    *,
    min_distance_m: float = 2.0,
    max_distance_m: float = 12.0,
) -> Pose2D:
    """A random goal reachable from ``start``: a cell of the start's region (see :func:`choose_start_goal`; the
    region nearest the start when its own cell lacks the clearance) in the distance band, facing away from the
    start.

    Raises:
        MapConversionError: no cell has the clearance, or the start's region has no other cell.
    """
    labels = _regions(grid, clearance_m)
    cells = np.argwhere(labels > 0)
    # The start's cell: invert cell_to_world (rotate back about the origin).
    ox, oy, yaw = grid.origin_m
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = start.x - ox, start.y - oy
    rc = np.array([(-s * dx + c * dy) / grid.resolution_m - 0.5, (c * dx + s * dy) / grid.resolution_m - 0.5])
    nearest = cells[int(np.argmin(np.sum((cells - rc) ** 2, axis=1)))]
    region = np.argwhere(labels == labels[nearest[0], nearest[1]])
    if len(region) < 2:
        raise MapConversionError(f"{grid.name}: no goal reachable from the start keeps {clearance_m:.2f} m from walls")
    goal_rc = _goal_in_band(grid, region, nearest, rng, min_distance_m, max_distance_m)
    gx, gy = grid.cell_to_world(float(goal_rc[0]), float(goal_rc[1]))
    return Pose2D(gx, gy, math.atan2(gy - start.y, gx - start.x))


def _fmt(v: float) -> str:
    return f"{v:.6g}"


def scene_xml_from_grid(
    grid: GridMap,
    *,
    start: Pose2D,
    goal: Pose2D,
    wall_height_m: float = 0.5,
) -> tuple[str, int]:
    """Self-contained MJCF text of a world built from ``grid`` (walls, floor, light, robot at ``start``).

    Args:
        grid: the occupancy grid (add the border first if wanted).
        start: robot start pose, world frame.
        goal: default goal, stored as the ``mjnav_goal`` custom numeric.
        wall_height_m: wall height, metres.

    Returns:
        (MJCF text, number of wall boxes).

    Raises:
        MapConversionError: bad height, or MuJoCo rejects the generated model.
    """
    if not (math.isfinite(wall_height_m) and wall_height_m > 0.0):
        raise MapConversionError(f"wall_height_m must be positive, got {wall_height_m}")
    rects = merge_rectangles(grid.occupied)
    res = grid.resolution_m
    hz = 0.5 * wall_height_m
    walls = []
    for i, (r, c, nr, nc) in enumerate(rects.tolist()):
        x = (c + 0.5 * nc) * res
        y = (r + 0.5 * nr) * res
        walls.append(
            f'      <geom name="wall_{i}" class="wall" pos="{_fmt(x)} {_fmt(y)} {_fmt(hz)}" '
            f'size="{_fmt(0.5 * nc * res)} {_fmt(0.5 * nr * res)} {_fmt(hz)}"/>'
        )
    h, w = grid.occupied.shape
    cx, cy = grid.cell_to_world((h - 1) / 2.0, (w - 1) / 2.0)
    half = 0.5 * max(h, w) * res + 2.0
    ox, oy, yaw = grid.origin_m
    common = (MJCF_DIR / "assets" / "common.xml").resolve()
    text = f"""<mujoco model="{grid.name}">
  <include file="{common}"/>
  <worldbody>
    <light name="sun" pos="{_fmt(cx)} {_fmt(cy)} 20" dir="0 0 -1" directional="true" castshadow="false"
           diffuse="0.5 0.5 0.5"/>
    <geom name="floor" class="floor" pos="{_fmt(cx)} {_fmt(cy)} 0" size="{_fmt(half)} {_fmt(half)} 0.1"/>
    <frame name="map_origin" pos="{_fmt(ox)} {_fmt(oy)} 0" euler="0 0 {_fmt(yaw)}">
{chr(10).join(walls)}
    </frame>
    <frame name="start" pos="{_fmt(start.x)} {_fmt(start.y)} 0" euler="0 0 {_fmt(start.theta)}">
      <attach model="diffbot" body="base_link" prefix="robot/"/>
    </frame>
  </worldbody>
  <custom>
    <numeric name="{GOAL_NUMERIC}" data="{_fmt(goal.x)} {_fmt(goal.y)} {_fmt(goal.theta)}"/>
  </custom>
</mujoco>
"""
    try:
        spec = mujoco.MjSpec.from_string(text)
        spec.compile()
        flat = spec.to_xml()
    except Exception as exc:
        raise MapConversionError(f"MuJoCo rejected the world generated from {grid.name}: {exc}") from exc
    header = (
        f"<!-- Generated by 'mjnav world from-map' from {grid.name}: {int(grid.occupied.sum())} occupied "
        f"cells of {_fmt(res)} m merged into {len(rects)} boxes. -->\n"
    )
    return header + flat, len(rects)


def write_scene_from_map(
    map_path: str | Path,
    out_path: str | Path,
    *,
    resolution_m: float | None = None,
    wall_height_m: float = 0.5,
    border: bool = True,
    unknown_is_occupied: bool = False,
    start: Pose2D | None = None,
    goal: Pose2D | None = None,
    clearance_m: float = 0.35,
    rng: np.random.Generator | None = None,
    min_distance_m: float = 2.0,
    max_distance_m: float = 12.0,
) -> SceneSummary:
    """Read a map file and write a world MJCF built from it (the ``mjnav world from-map`` command).

    Args:
        map_path: ROS ``.yaml`` (with its image) or Moving AI ``.map``.
        out_path: the MJCF file to write (parent folders are created).
        resolution_m: Moving AI cell size, metres (default 0.5).
        wall_height_m: wall height, metres.
        border: surround the map with a one-cell wall so the robot cannot leave it.
        unknown_is_occupied: ROS maps: unknown cells become walls too.
        start: robot start pose (world frame); default chosen automatically.
        goal: default goal (world frame); default chosen automatically.
        clearance_m: free distance to walls required for automatic start/goal cells, metres.
        rng: seeded choice of the automatic start and goal (see :func:`choose_start_goal`); ``None``: centre
            start, farthest goal.
        min_distance_m, max_distance_m: with ``rng``, the band of the goal's distance from the start, metres.

    Raises:
        MapConversionError: unreadable map, no room for the robot, or MuJoCo rejects the result.
    """
    grid = load_grid_map(map_path, resolution_m=resolution_m, unknown_is_occupied=unknown_is_occupied)
    if border:
        grid = add_border(grid)
    if start is None or goal is None:
        auto_start, auto_goal = choose_start_goal(
            grid, clearance_m, rng, min_distance_m=min_distance_m, max_distance_m=max_distance_m
        )
        start = start or auto_start
        goal = goal or auto_goal
    xml, boxes = scene_xml_from_grid(grid, start=start, goal=goal, wall_height_m=wall_height_m)
    out = Path(out_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(xml, encoding="utf-8")
    return SceneSummary(out, int(grid.occupied.sum()), boxes, start, goal)

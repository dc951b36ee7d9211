"""The true map of a world: static obstacle footprints rasterised from the compiled MuJoCo model.

Used to score navigation runs (the optimal path length for the robot's radius, clearance) — never by the robot.
Static means welded to the world body; planes (the floor), the robot (geom group :data:`ROBOT_GEOM_GROUP`) and
moving bodies are left out. Footprints are the geoms' projections on the ground plane: oriented rectangles for
boxes, discs for cylinders, spheres, capsules and ellipsoids (their largest horizontal radius), and axis-aligned
squares around the bounding sphere for meshes and other types.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from mjnav.mapping.frame import GridFrame
from mjnav.sim.model import ROBOT_GEOM_GROUP

_G = mujoco.mjtGeom


def static_occupancy(model: mujoco.MjModel, data: mujoco.MjData, frame: GridFrame) -> NDArray[np.bool_]:
    """(H, W) bool grid of ``frame``: True where a cell centre lies inside a static obstacle's footprint.

    Each obstacle is tested only on the cells under its bounding square, so the cost grows with the obstacles' area,
    not with obstacles × cells (a real map's world has thousands of wall boxes on millions of cells).

    Args:
        model, data: the compiled world; ``data`` must hold positions (call ``mj_forward`` first).
        frame: the grid placement in the map (= MuJoCo world) frame.
    """
    h, w = frame.shape
    occupied = np.zeros((h, w), dtype=bool)
    # Only geoms whose bounding circle reaches the grid (an unrotated frame's rectangle): a world of 100 k boxes
    # spent seconds per call on the rest, one by one.
    x0, y0 = frame.origin_m
    x1, y1 = x0 + w * frame.resolution_m, y0 + h * frame.resolution_m
    xy, reach = data.geom_xpos[:, :2], model.geom_rbound
    near = (xy[:, 0] + reach >= x0) & (xy[:, 0] - reach <= x1) & (xy[:, 1] + reach >= y0) & (xy[:, 1] - reach <= y1)
    candidates = range(model.ngeom) if frame.yaw_rad else np.flatnonzero(near)
    for g in candidates:
        g = int(g)
        gtype = int(model.geom_type[g])
        body = int(model.geom_bodyid[g])
        if gtype == _G.mjGEOM_PLANE or int(model.geom_group[g]) == ROBOT_GEOM_GROUP:
            continue
        if int(model.body_weldid[body]) != 0:  # moves: not part of the static map
            continue
        if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:  # visual only
            continue
        cx, cy = float(data.geom_xpos[g, 0]), float(data.geom_xpos[g, 1])
        size = model.geom_size[g]
        rot = data.geom_xmat[g].reshape(3, 3)
        window = _cells_under(frame, cx, cy, _planar_reach(gtype, size, float(model.geom_rbound[g])))
        if window is None:
            continue
        rows, cols = window
        rr, cc = np.meshgrid(np.arange(rows.start, rows.stop), np.arange(cols.start, cols.stop), indexing="ij")
        centres = frame.cells_to_world(np.column_stack((rr.ravel(), cc.ravel())))
        dx, dy = centres[:, 0] - cx, centres[:, 1] - cy
        if gtype == _G.mjGEOM_BOX:
            # Footprint of an oriented box: |p·axis_i| <= half-extent projected, for the box's own x and y axes
            # (exact for boxes rotated about z only, which is how walls and shelves are placed).
            u = dx * rot[0, 0] + dy * rot[1, 0]
            v = dx * rot[0, 1] + dy * rot[1, 1]
            inside = (np.abs(u) <= size[0]) & (np.abs(v) <= size[1])
        elif gtype in (_G.mjGEOM_CYLINDER, _G.mjGEOM_CAPSULE, _G.mjGEOM_SPHERE):
            inside = dx * dx + dy * dy <= size[0] ** 2
        elif gtype == _G.mjGEOM_ELLIPSOID:
            r = max(size[0], size[1])
            inside = dx * dx + dy * dy <= r * r
        else:  # meshes and the rest: the square around the bounding sphere
            r = float(model.geom_rbound[g])
            inside = (np.abs(dx) <= r) & (np.abs(dy) <= r)
        occupied[rows, cols] |= inside.reshape(rr.shape)
    return occupied


def _planar_reach(gtype: int, size: NDArray[np.float64], rbound: float) -> float:
    """Radius about a geom's centre that holds its footprint as :func:`static_occupancy` draws it."""
    if gtype == _G.mjGEOM_BOX:
        return math.hypot(float(size[0]), float(size[1]))
    if gtype in (_G.mjGEOM_CYLINDER, _G.mjGEOM_CAPSULE, _G.mjGEOM_SPHERE):
        return float(size[0])
    if gtype == _G.mjGEOM_ELLIPSOID:
        return max(float(size[0]), float(size[1]))
    return rbound * math.sqrt(2.0)  # the square around the bounding sphere


def _cells_under(frame: GridFrame, cx: float, cy: float, reach: float) -> tuple[slice, slice] | None:
    """Row and column ranges of ``frame`` holding every cell centre within ``reach`` of (cx, cy) (None: none)."""
    corners = np.array([[cx - reach, cy - reach], [cx + reach, cy - reach], [cx - reach, cy + reach],
                        [cx + reach, cy + reach]])  # fmt: skip
    cells = frame.world_to_cells(corners)
    r0, c0 = (int(v) - 1 for v in cells.min(axis=0))
    r1, c1 = (int(v) + 2 for v in cells.max(axis=0))
    h, w = frame.shape
    r0, c0, r1, c1 = max(r0, 0), max(c0, 0), min(r1, h), min(c1, w)
    if r0 >= r1 or c0 >= c1:
        return None
    return slice(r0, r1), slice(c0, c1)


def compiled_world(world: str | Path) -> tuple[Any, Any]:
    """The world's :class:`~mjnav.sim.worlds.WorldInfo` and :class:`~mjnav.sim.simulator.Simulator` (no lidar,
    positions computed), read and compiled once per process and file version (a bundled name and its file are the
    same world): a world of 100 k boxes takes seconds each time, and the demo's scoring asked for it five times
    (the random 512 x 512 Moving AI map's summary ended 36-41 s after the robot arrived).

    Raises:
        UnknownWorldError, ModelLoadError, RobotNotFoundError: as :func:`mjnav.sim.worlds.world_info`.
    """
    from mjnav.sim.worlds import resolve_world

    path = resolve_world(world)
    return _compile(str(path), path.stat().st_mtime_ns)


@functools.lru_cache(maxsize=4)
def _compile(world: str, _version: int) -> tuple[Any, Any]:
    from mjnav.sim.simulator import Simulator

    sim = Simulator(world, lidar=None)
    mujoco.mj_forward(sim.model, sim.data)
    return sim.world, sim


class FootprintClearance:
    """Exact distance from the robot's footprint to the world's static obstacles (the scoring of ``mjnav demo``).

    The footprint is the disc of the robot's radius (the smallest vertical cylinder holding its colliding geoms,
    :attr:`WorldInfo.robot_radius_m`) about ``base_link``; obstacles are the footprints :func:`static_occupancy`
    rasterises (oriented boxes, discs, squares around other shapes' bounding spheres), here as exact shapes.
    A negative clearance means the footprint overlaps an obstacle.

    Args:
        world: bundled world name or MJCF path.
    """

    def __init__(self, world: str | Path) -> None:
        _info, sim = compiled_world(world)
        model, data = sim.model, sim.data
        self.robot_radius_m = float(sim.robot_radius_m)
        boxes: list[list[float]] = []  # cx, cy, cos, sin, hx, hy
        discs: list[list[float]] = []  # cx, cy, r
        for g in range(model.ngeom):
            gtype = int(model.geom_type[g])
            if gtype == _G.mjGEOM_PLANE or int(model.geom_group[g]) == ROBOT_GEOM_GROUP:
                continue
            if int(model.body_weldid[int(model.geom_bodyid[g])]) != 0:
                continue
            if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
                continue
            cx, cy = float(data.geom_xpos[g, 0]), float(data.geom_xpos[g, 1])
            size = model.geom_size[g]
            rot = data.geom_xmat[g].reshape(3, 3)
            if gtype == _G.mjGEOM_BOX:
                boxes.append([cx, cy, float(rot[0, 0]), float(rot[1, 0]), float(size[0]), float(size[1])])
            elif gtype in (_G.mjGEOM_CYLINDER, _G.mjGEOM_CAPSULE, _G.mjGEOM_SPHERE):
                discs.append([cx, cy, float(size[0])])
            elif gtype == _G.mjGEOM_ELLIPSOID:
                discs.append([cx, cy, float(max(size[0], size[1]))])
            else:
                r = float(model.geom_rbound[g])
                boxes.append([cx, cy, 1.0, 0.0, r, r])
        self._boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 6)
        self._discs = np.asarray(discs, dtype=np.float64).reshape(-1, 3)

    def obstacle_distance_m(self, x: float, y: float) -> float:
        """Signed distance (m) from point (x, y) to the nearest static obstacle (negative inside one; inf without
        obstacles)."""
        best = math.inf
        b = self._boxes
        if len(b):
            dx, dy = x - b[:, 0], y - b[:, 1]
            qx = np.abs(dx * b[:, 2] + dy * b[:, 3]) - b[:, 4]  # along the box's own x axis
            qy = np.abs(-dx * b[:, 3] + dy * b[:, 2]) - b[:, 5]
            outside = np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0))
            best = float(np.min(outside + np.minimum(np.maximum(qx, qy), 0.0)))
        d = self._discs
        if len(d):
            best = min(best, float(np.min(np.hypot(x - d[:, 0], y - d[:, 1]) - d[:, 2])))
        return best

    def clearance_m(self, x: float, y: float) -> float:
        """Footprint-to-obstacle distance (m) with the robot at (x, y): negative = overlapping an obstacle."""
        return self.obstacle_distance_m(x, y) - self.robot_radius_m


def true_grid(
    world: str | Path, resolution_m: float = 0.1, border_m: float = 1.0
) -> tuple[NDArray[np.bool_], GridFrame]:
    """The world's true static occupancy on a grid covering its static obstacles and its start, with a border.

    Args:
        world: bundled world name or MJCF path.
        resolution_m: cell size, metres.
        border_m: free margin around the obstacles' bounds (and the start), metres.

    Returns:
        ``(occupied, frame)``: (H, W) bool, True inside a static obstacle's footprint; the grid's placement.
    """

    info, sim = compiled_world(world)
    xs, ys = [info.start.x], [info.start.y]
    if info.bounds_m is not None:
        xs += [info.bounds_m[0], info.bounds_m[2]]
        ys += [info.bounds_m[1], info.bounds_m[3]]
    x0, y0 = min(xs) - border_m, min(ys) - border_m
    shape = (math.ceil((max(ys) + border_m - y0) / resolution_m), math.ceil((max(xs) + border_m - x0) / resolution_m))
    frame = GridFrame(resolution_m, (x0, y0), shape)
    return static_occupancy(sim.model, sim.data, frame), frame


#: :func:`shortest_length_m` looks for the path first within this many times the start-goal distance around them
#: (enough for any path up to 1.5 times that distance; a longer one grows the window to what it needs).
DETOUR_FACTOR = 0.25
#: ... and at least this far (metres).
MIN_BORDER_M = 10.0
#: Most cells :func:`shortest_length_m` rasterises: a bigger window gets coarser cells (a 1 km x 1 km world at
#: 5 cm was 400 M cells, and the demo's summary ran the machine out of memory; the search takes about 35 bytes a
#: cell, so 25 M cells still took 1.3 GB beside the running stack).
MAX_EVALUATION_CELLS = 10_000_000


def shortest_length_m(
    world: str | Path, start_xy: tuple[float, float], goal_xy: tuple[float, float], *, resolution_m: float = 0.05
) -> float:
    """Near-shortest collision-free path length for the robot of ``world`` on its true (static) map, metres.

    The grid first covers the start and the goal with a border of :data:`DETOUR_FACTOR` times their distance
    (at least :data:`MIN_BORDER_M`), clipped to the world's static obstacles with a 1 m border. Without a path
    there the border triples; with one of length L the grid must hold every point within L / 2 of the midpoint
    of start and goal (where any path no longer lies), else it grows to that once more. It has ``resolution_m``
    cells or, where that would take more than :data:`MAX_EVALUATION_CELLS` (a whole world over about 250 m x
    250 m), as many as that; see :func:`mjnav.planning.reference.shortest_path_length_m` for the method. (The
    whole 256 m x 256 m Boston map took 7 s of the demo's summary for a 90 m route.)

    Raises:
        mjnav.planning.PlanningError: start or goal blocked, or no path.
    """
    from mjnav.planning import NoPathFound
    from mjnav.planning.reference import shortest_path_length_m

    info, sim = compiled_world(world)
    xs = [start_xy[0], goal_xy[0]]
    ys = [start_xy[1], goal_xy[1]]
    if info.bounds_m is not None:
        xs += [info.bounds_m[0], info.bounds_m[2]]
        ys += [info.bounds_m[1], info.bounds_m[3]]
    world_box = (min(xs) - 1.0, min(ys) - 1.0, max(xs) + 1.0, max(ys) + 1.0)
    border = max(MIN_BORDER_M, DETOUR_FACTOR * math.dist(start_xy, goal_xy))
    while True:
        box = (
            max(world_box[0], min(start_xy[0], goal_xy[0]) - border),
            max(world_box[1], min(start_xy[1], goal_xy[1]) - border),
            min(world_box[2], max(start_xy[0], goal_xy[0]) + border),
            min(world_box[3], max(start_xy[1], goal_xy[1]) + border),
        )
        width, height = box[2] - box[0], box[3] - box[1]
        res = max(resolution_m, math.sqrt(width * height / MAX_EVALUATION_CELLS))
        frame = GridFrame(res, (box[0], box[1]), (math.ceil(height / res), math.ceil(width / res)))
        obstacles = static_occupancy(sim.model, sim.data, frame)
        try:
            length = shortest_path_length_m(obstacles, frame, start_xy, goal_xy, sim.robot_radius_m)
        except NoPathFound:
            if box == world_box:
                raise
            border *= 3.0
            continue
        # A path no longer than this lies in the ellipse of foci start and goal, within length / 2 of their
        # midpoint: a box that holds that square holds the shortest path.
        x, y, half = (start_xy[0] + goal_xy[0]) / 2, (start_xy[1] + goal_xy[1]) / 2, length / 2
        if box == world_box or (
            (box[0] <= x - half or box[0] == world_box[0])
            and (box[1] <= y - half or box[1] == world_box[1])
            and (box[2] >= x + half or box[2] == world_box[2])
            and (box[3] >= y + half or box[3] == world_box[3])
        ):
            return length
        border = half + 1.0


def map_accuracy(
    world: str | Path, occupancy: ArrayLike, frame: GridFrame, *, occupied_at: int = 65
) -> tuple[float, float]:
    """How well a built occupancy map matches the world's true static obstacles, within one cell.

    Args:
        world: the world the map was built in.
        occupancy: (H, W) ROS occupancy values of the map (0..100, −1 unknown).
        frame: the map's placement (map = world frame).
        occupied_at: values at or above this count as occupied.

    Returns:
        ``(recall, precision)``: the share of the truly occupied cells the map observed (known cells) that have an
        occupied map cell within one cell, and the share of the map's occupied cells that have a truly occupied
        cell within one cell. NaN where there is nothing to count.
    """
    from scipy.ndimage import binary_dilation

    occ = np.asarray(occupancy)
    _info, sim = compiled_world(world)
    true = static_occupancy(sim.model, sim.data, frame)
    built = occ >= occupied_at
    square = np.ones((3, 3), dtype=bool)
    observed_true = true & (occ >= 0)
    recall = (
        float((observed_true & binary_dilation(built, square)).sum() / observed_true.sum())
        if observed_true.any()
        else math.nan
    )
    precision = float((built & binary_dilation(true, square)).sum() / built.sum()) if built.any() else math.nan
    return recall, precision

"""Reference figures for scoring a navigation run: the shortest collision-free path length for a disc robot."""

from __future__ import annotations

from numpy.typing import ArrayLike

from mjnav.mapping.frame import GridFrame
from mjnav.mapping.inflation import inflate_mask
from mjnav.planning.grid import plan_grid


def shortest_path_length_m(
    obstacles: ArrayLike,
    frame: GridFrame,
    start_xy: tuple[float, float],
    goal_xy: tuple[float, float],
    robot_radius_m: float,
) -> float:
    """Length of the shortest 8-connected grid path (√2 diagonals, no corner cutting) for a disc robot.

    The obstacles are grown by the robot's radius (configuration space) and optimal A* runs between the cells of
    ``start_xy`` and ``goal_xy``. On a grid of resolution r the result over-estimates the true (any-angle) shortest
    length by at most ≈8 % (octile vs Euclidean) plus one cell.

    Args:
        obstacles: (H, W) bool true map, True = obstacle.
        frame: where the grid sits in the map frame.
        start_xy, goal_xy: positions in the map frame, metres.
        robot_radius_m: the robot's radius, metres.

    Raises:
        OutsideMap, StartOccupied, GoalOccupied, NoPathFound: see :func:`~mjnav.planning.plan_grid`.
    """
    free_space = inflate_mask(obstacles, frame.resolution_m, robot_radius_m)
    start = frame.world_to_cell(*start_xy)
    goal = frame.world_to_cell(*goal_xy)
    return plan_grid(free_space, start, goal, algorithm="astar").cost * frame.resolution_m

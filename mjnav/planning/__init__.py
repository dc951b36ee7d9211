"""mjnav.planning: graph search, heuristics and potential fields on occupancy grids (pure: numpy/scipy/numba).

Entry point: :func:`plan_grid` (DFS, BFS, greedy, Dijkstra, A*, jump point search, potential field) returning a
:class:`GridPlan`; cells are (row, col). Failures raise the typed errors of :mod:`mjnav.planning.errors`.
"""

from mjnav.planning.errors import (
    GoalOccupied,
    GoalOutsideMap,
    InvalidInput,
    InvalidPath,
    LocalMinimum,
    NoPathFound,
    OutsideMap,
    PlanningError,
    StartOccupied,
    StartOutsideMap,
)
from mjnav.planning.grid import ALGORITHMS, GridPlan, check_path, path_cost, plan_grid
from mjnav.planning.heuristics import METRICS, chebyshev, euclidean, manhattan, octile
from mjnav.planning.potential_field import PotentialFieldParams, plan_potential_field, potential_map

__all__ = [
    "ALGORITHMS",
    "METRICS",
    "GoalOccupied",
    "GoalOutsideMap",
    "GridPlan",
    "InvalidInput",
    "InvalidPath",
    "LocalMinimum",
    "NoPathFound",
    "OutsideMap",
    "PlanningError",
    "PotentialFieldParams",
    "StartOccupied",
    "StartOutsideMap",
    "chebyshev",
    "check_path",
    "euclidean",
    "manhattan",
    "octile",
    "path_cost",
    "plan_grid",
    "plan_potential_field",
    "potential_map",
]

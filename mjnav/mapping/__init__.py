"""mjnav.mapping: log-odds occupancy grids, inflation, line rasterisation and map files (numpy/scipy/numba
only).

Grid layout everywhere: (H, W) arrays, cell (row, col) holds world point (x, y) with
row = floor((y − oy)/res), col = floor((x − ox)/res); row 0 is the lowest y (the nav_msgs/OccupancyGrid
order).
"""

from mjnav.mapping.errors import (
    InvalidGridError,
    InvalidParameterError,
    InvalidPoseError,
    MapFileError,
    MappingError,
    OutsideMapError,
)
from mjnav.mapping.frame import GridFrame
from mjnav.mapping.grid import CellState, LogOddsModel, OccupancyGrid, log_odds_to_prob, prob_to_log_odds
from mjnav.mapping.inflation import (
    INSCRIBED_COST,
    LETHAL_COST,
    MAX_DECAY_COST,
    clearance_m,
    inflate_mask,
    inflation_costmap,
)
from mjnav.mapping.lines import bresenham, diagonal_addition, supercover
from mjnav.mapping.movingai import (
    MovingAIFormatError,
    MovingAIMap,
    MovingAIScenario,
    parse_movingai_map,
    parse_movingai_scen,
    read_movingai_map,
    read_movingai_scen,
)
from mjnav.mapping.ros_map import RosMap, read_ros_map, write_ros_map

__all__ = [
    "INSCRIBED_COST",
    "LETHAL_COST",
    "MAX_DECAY_COST",
    "CellState",
    "GridFrame",
    "InvalidGridError",
    "InvalidParameterError",
    "InvalidPoseError",
    "LogOddsModel",
    "MapFileError",
    "MappingError",
    "MovingAIFormatError",
    "MovingAIMap",
    "MovingAIScenario",
    "OccupancyGrid",
    "OutsideMapError",
    "RosMap",
    "bresenham",
    "clearance_m",
    "diagonal_addition",
    "inflate_mask",
    "inflation_costmap",
    "log_odds_to_prob",
    "parse_movingai_map",
    "parse_movingai_scen",
    "prob_to_log_odds",
    "read_movingai_map",
    "read_movingai_scen",
    "read_ros_map",
    "supercover",
    "write_ros_map",
]

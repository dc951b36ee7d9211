"""Costmap → planning inputs, string pulling and the reference shortest length."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.mapping import GridFrame
from mjnav.mapping.errors import InvalidParameterError
from mjnav.planning import InvalidInput, plan_grid
from mjnav.planning.costmap import clear_disc, planning_grid
from mjnav.planning.reference import shorten_path, shortest_path_length_m


def test_planning_grid_blocks_inscribed_and_costs_free_and_unknown() -> None:
    costmap = np.array([[0, 49, 98, 99, 100, -1]], dtype=np.int8)
    occupied, cost = planning_grid(costmap, cost_weight=2.0, unknown_cost=0.5)
    assert occupied.tolist() == [[False, False, False, True, True, False]]
    np.testing.assert_allclose(cost, [[0.0, 1.0, 2.0, 0.0, 0.0, 0.5]])
    with pytest.raises(InvalidInput):
        planning_grid(np.zeros((2, 2)), cost_weight=1.0)


def test_clear_disc_frees_only_the_disc() -> None:
    occ = np.ones((7, 7), dtype=bool)
    cleared = clear_disc(occ, (3, 3), 1.5)
    assert cleared.sum() == 49 - 9  # the 3×3 block within radius 1.5
    assert occ.all()  # the input is untouched
    assert clear_disc(occ, (0, 0), 1.0).sum() == 49 - 3  # clipped at the corner


def test_shorten_path_is_straight_in_free_space_and_bends_at_a_wall() -> None:
    free = np.zeros((10, 10), dtype=bool)
    plan = plan_grid(free, (0, 0), (9, 6))
    assert shorten_path(free, plan.cells).tolist() == [[0, 0], [9, 6]]
    wall = np.zeros((10, 10), dtype=bool)
    wall[5, 0:8] = True
    taut = shorten_path(wall, plan_grid(wall, (0, 0), (9, 0)).cells)
    assert len(taut) >= 3 and taut[0].tolist() == [0, 0] and taut[-1].tolist() == [9, 0]


def test_reference_length_is_the_straight_line_in_open_space() -> None:
    frame = GridFrame(0.1, (0.0, 0.0), (50, 50))
    length = shortest_path_length_m(np.zeros((50, 50), dtype=bool), frame, (0.55, 0.55), (3.55, 4.55), 0.2)
    assert length == pytest.approx(math.hypot(3.0, 4.0), abs=1e-9)
    walls = np.zeros((50, 50), dtype=bool)
    walls[20, :45] = True  # a wall with a gap on the right: the path must go round it
    around = shortest_path_length_m(walls, frame, (0.55, 0.55), (0.55, 4.55), 0.2)
    assert around > 2 * math.hypot(4.2, 2.0) - 0.2


def test_a_rotated_grid_frame_round_trips_and_matches_hand_worked_cells() -> None:
    # Yaw 90°: the grid's +col axis points along world +y, its +row axis along world −x.
    frame = GridFrame(0.5, (1.0, 2.0), (4, 6), yaw_rad=math.pi / 2)
    assert frame.world_to_cell(1.1, 2.7) == (-1, 1)  # east of the origin is −row: outside, below row 0
    assert frame.world_to_cell(0.9, 2.7) == (0, 1)
    centres = frame.cells_to_world([[0, 0], [3, 5]])
    np.testing.assert_allclose(centres, [[0.75, 2.25], [-0.75, 4.75]])
    np.testing.assert_array_equal(frame.world_to_cells(centres), [[0, 0], [3, 5]])
    assert [frame.world_to_cell(x, y) for x, y in centres] == [(0, 0), (3, 5)]
    with pytest.raises(InvalidParameterError):
        GridFrame(0.5, (0.0, 0.0), (4, 6), yaw_rad=math.nan)
    # Values at world points: the cell's value inside the grid, the given fill outside it.
    grid = np.arange(24).reshape(4, 6)
    np.testing.assert_array_equal(frame.values_at(grid, [[0.75, 2.25], [-0.75, 4.75], [1.1, 2.7]], -1), [0, 23, -1])

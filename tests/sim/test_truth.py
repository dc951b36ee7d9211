"""The true static map of a world, for scoring runs."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjnav.mapping import GridFrame
from mjnav.sim import Simulator
from mjnav.sim.truth import shortest_length_m, static_occupancy


def test_rooms_true_map_has_walls_and_free_start_and_goal() -> None:
    sim = Simulator("rooms", lidar=None)
    mujoco.mj_forward(sim.model, sim.data)
    frame = GridFrame(0.05, (-6.0, -6.0), (240, 240))
    occ = static_occupancy(sim.model, sim.data, frame)
    for x, y in ((-5.0, 0.0), (5.0, 2.0), (0.0, 0.0)):  # outer walls and the interior cross
        assert occ[frame.world_to_cell(x, y)], (x, y)
    for x, y in ((-3.5, -3.5), (3.8, 2.2), (-5.5, 0.0)):  # start, goal, outside the building
        assert not occ[frame.world_to_cell(x, y)], (x, y)


def test_moving_obstacles_and_the_robot_are_not_in_the_static_map() -> None:
    sim = Simulator("warehouse", lidar=None)
    mujoco.mj_forward(sim.model, sim.data)
    frame = GridFrame(0.05, (-9.0, -7.0), (280, 360))
    occ = static_occupancy(sim.model, sim.data, frame)
    start = sim.start_pose
    assert not occ[frame.world_to_cell(start.x, start.y)]  # the robot stands there
    movers = [b for b in range(sim.model.nbody) if sim.model.body_weldid[b] != 0 and b != sim.robot.root_body]
    assert movers, "the warehouse should have moving bodies"


@pytest.mark.parametrize(
    ("world", "origin", "yaw"),
    [("warehouse", (-11.0, -9.0), 0.0), ("rooms", (-5.0, -9.0), 0.3), ("maze", (-12.0, 6.0), -1.1)],
)
def test_every_cell_is_occupied_exactly_where_an_obstacle_covers_its_centre(
    world: str, origin: tuple[float, float], yaw: float
) -> None:
    """Against the exact shapes of FootprintClearance (signed distance <= 0 inside), cell by cell, also on a grid
    rotated in the world and reaching past it (each obstacle is drawn only under its own bounding square)."""
    from mjnav.sim.truth import FootprintClearance

    sim = Simulator(world, lidar=None)
    mujoco.mj_forward(sim.model, sim.data)
    frame = GridFrame(0.05, origin, (400, 440), yaw_rad=yaw)
    occ = static_occupancy(sim.model, sim.data, frame)
    fc = FootprintClearance(world)
    rng = np.random.default_rng(11)
    cells = rng.integers(0, frame.shape, size=(4000, 2))
    checked = 0
    for (r, c), (x, y) in zip(cells, frame.cells_to_world(cells), strict=True):
        d = fc.obstacle_distance_m(x, y)
        if abs(d) > 1e-9:
            assert occ[r, c] == (d < 0), (world, r, c, d)
            checked += 1
    assert checked > 3900 and 0.01 < occ.mean() < 0.5


def test_shortest_length_is_at_least_the_straight_line() -> None:
    length = shortest_length_m("rooms", (-3.5, -3.5), (3.8, 2.2))
    assert 9.28 < length < 11.0  # straight line is 9.27 m; the walls force a detour through the doorways
    with pytest.raises(Exception):  # noqa: B017 - the goal lies inside a wall: any planning error
        shortest_length_m("rooms", (-3.5, -3.5), (0.0, 0.0))


def test_shortest_length_scales_its_cells_to_a_budget_and_looks_near_the_start_and_goal_first(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Issue 30: on a 1 km x 1 km world the summary rasterised 400 M cells and ran the machine out of memory.
    The path is looked for near the start and goal first (the whole world when none lies there), on at most
    MAX_EVALUATION_CELLS cells."""
    import mjnav.sim.truth as truth

    fine = shortest_length_m("rooms", (-3.5, -3.5), (3.8, 2.2))
    monkeypatch.setattr(truth, "MAX_EVALUATION_CELLS", 4_000)  # ~15 cm cells on the rooms world
    coarse = shortest_length_m("rooms", (-3.5, -3.5), (3.8, 2.2))
    assert coarse == pytest.approx(fine, rel=0.05)
    # A window of 0.5 m around the two still holds the route (on cells placed from its own corner).
    monkeypatch.setattr(truth, "MAX_EVALUATION_CELLS", 25_000_000)
    monkeypatch.setattr(truth, "DETOUR_FACTOR", 0.0)
    monkeypatch.setattr(truth, "MIN_BORDER_M", 0.5)
    assert shortest_length_m("rooms", (-3.5, -3.5), (3.8, 2.2)) == pytest.approx(fine, rel=0.01)


def test_footprint_clearance_is_the_distance_from_the_robot_disc_to_the_walls() -> None:
    from scipy.ndimage import distance_transform_edt

    from mjnav.sim.truth import FootprintClearance

    fc = FootprintClearance("rooms")
    assert fc.robot_radius_m == pytest.approx(0.19)
    # rooms: the x = 0 partition is 0.1 m thick (x in [-0.05, 0.05]) around y = 0, the outer wall at y = 5.
    assert fc.obstacle_distance_m(-0.5, 0.9) == pytest.approx(0.45)  # nearest: the partition's face at x = -0.05
    assert fc.obstacle_distance_m(0.0, 0.5) == pytest.approx(-0.05)  # inside the partition: minus the depth
    assert fc.clearance_m(-0.2, 0.5) == pytest.approx(0.15 - 0.19)  # the disc overlaps the wall by 4 cm
    # Against an independent measure: the Euclidean distance transform of the rasterised true map (0.01 m cells).
    sim = Simulator("rooms", lidar=None)
    mujoco.mj_forward(sim.model, sim.data)
    frame = GridFrame(0.01, (-5.5, -5.5), (1100, 1100))
    occupied = static_occupancy(sim.model, sim.data, frame)
    edt = distance_transform_edt(~occupied) * 0.01
    rng = np.random.default_rng(3)
    for x, y in rng.uniform(-4.8, 4.8, size=(200, 2)):
        r, c = frame.world_to_cell(x, y)
        if occupied[r, c]:
            assert fc.obstacle_distance_m(x, y) <= 0.01
        else:
            assert fc.obstacle_distance_m(x, y) == pytest.approx(edt[r, c], abs=0.015)

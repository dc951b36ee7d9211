"""OccupancyGrid: indexing, the log-odds filter, scan integration, ROS conversion and bad input."""

from __future__ import annotations

import gzip
import math
from pathlib import Path

import numpy as np
import pytest

from mjnav.geometry import Pose2D
from mjnav.mapping import (
    CellState,
    InvalidGridError,
    InvalidParameterError,
    InvalidPoseError,
    LogOddsModel,
    OccupancyGrid,
    OutsideMapError,
    bresenham,
)

L_HIT = math.log(0.7 / 0.3)  # 0.8473
L_MISS = math.log(0.4 / 0.6)  # −0.4055
L_MIN = math.log(0.1192 / 0.8808)
L_MAX = math.log(0.971 / 0.029)


def unit_grid(w: int = 10, h: int = 10) -> OccupancyGrid:
    """1 m cells, origin at (0, 0): cell (r, c) centre is (c + 0.5, r + 0.5)."""
    return OccupancyGrid(w, h, 1.0, (0.0, 0.0))


# ---------------------------------------------------------------------------------------------------------
# Geometry
# ---------------------------------------------------------------------------------------------------------


def test_world_to_cell_and_back_hand_worked() -> None:
    g = OccupancyGrid(8, 6, 0.5, (-1.0, 2.0))
    assert g.shape == (6, 8)
    assert g.log_odds.shape == (6, 8)
    assert g.log_odds.dtype == np.float64
    # x = 0.3 → col = floor((0.3 + 1)/0.5) = 2; y = 3.9 → row = floor((3.9 − 2)/0.5) = 3.
    assert g.world_to_cell(0.3, 3.9) == (3, 2)
    assert g.cell_to_world(3, 2) == pytest.approx((0.25, 3.75))
    # The lower/left cell edges belong to the cell; the corner of the map is cell (0, 0).
    assert g.world_to_cell(-1.0, 2.0) == (0, 0)
    assert g.world_to_cell(-0.5, 2.5) == (1, 1)
    assert g.world_to_cell(2.999, 4.999) == (5, 7)
    assert g.extent_m == (-1.0, 3.0, 2.0, 5.0)
    assert g.contains(2.999, 4.999)
    assert not g.contains(3.0, 4.0)
    assert not g.contains(float("nan"), 4.0)


def test_world_to_cell_outside_and_nan() -> None:
    g = OccupancyGrid(8, 6, 0.5, (-1.0, 2.0))
    with pytest.raises(OutsideMapError) as info:
        g.world_to_cell(3.0, 3.0)  # x = 3 is the right edge: col 8 does not exist
    assert info.value.cell == (2, 8)
    with pytest.raises(OutsideMapError):
        g.world_to_cell(0.0, 1.99)
    with pytest.raises(InvalidPoseError):
        g.world_to_cell(float("nan"), 3.0)
    with pytest.raises(OutsideMapError):
        g.cell_to_world(6, 0)
    with pytest.raises(InvalidParameterError):
        g.cell_to_world(1.0, 0)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("args", "error"),
    [
        ((0, 5, 0.1), InvalidGridError),
        ((5, -1, 0.1), InvalidGridError),
        ((5.0, 5, 0.1), InvalidGridError),
        ((5, 5, 0.0), InvalidParameterError),
        ((5, 5, float("nan")), InvalidParameterError),
        ((5, 5, 0.1, (float("inf"), 0.0)), InvalidParameterError),
        ((5, 5, 0.1, (1.0, 2.0, 3.0)), InvalidParameterError),
    ],
)
def test_constructor_rejects_bad_geometry(args: tuple, error: type[Exception]) -> None:
    with pytest.raises(error):
        OccupancyGrid(*args)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"hit_log_odds": -0.1},  # a hit must raise the log-odds
        {"miss_log_odds": 0.2},
        {"free_threshold": 2.5, "occupied_threshold": 2.0},
        {"min_log_odds": -1.0},  # the free threshold −1.9956 would be unreachable
        {"max_log_odds": 1.5},
        {"prior_log_odds": 5.0},
        {"hit_log_odds": float("nan")},
    ],
)
def test_model_validation(kwargs: dict) -> None:
    with pytest.raises(InvalidParameterError):
        OccupancyGrid(4, 4, 0.1, **kwargs)


def test_default_model_values() -> None:
    m = LogOddsModel()
    assert m.free_threshold == -1.9956
    assert m.occupied_threshold == 1.9956
    assert m.hit_log_odds == pytest.approx(0.8473, abs=1e-4)
    assert m.miss_log_odds == pytest.approx(-0.4055, abs=1e-4)
    assert m.min_log_odds == pytest.approx(-2.0, abs=1e-4)
    assert m.max_log_odds == pytest.approx(3.511, abs=1e-3)
    g = unit_grid()
    assert np.all(g.log_odds == 0.0)
    assert np.all(g.probabilities() == 0.5)
    assert np.all(g.states() == CellState.UNKNOWN)


# ---------------------------------------------------------------------------------------------------------
# One beam, hand-worked
# ---------------------------------------------------------------------------------------------------------


def test_single_beam_updates_free_cells_and_the_end_cell_once() -> None:
    g = unit_grid()
    g.integrate_scan((0.5, 0.5, 0.0), [0.0], [5.0], 8.0)
    expected = np.zeros((10, 10))
    expected[0, 0:5] = L_MISS
    expected[0, 5] = L_HIT
    np.testing.assert_allclose(g.log_odds, expected, atol=1e-12)


def test_states_after_repeated_scans_and_clamping() -> None:
    g = unit_grid()
    for k in range(1, 6):
        g.integrate_scan((0.5, 0.5, 0.0), [0.0], [5.0], 8.0)
        st = g.states()
        assert st[0, 5] == (CellState.OCCUPIED if k >= 3 else CellState.UNKNOWN)  # 3·0.847 = 2.54 ≥ 1.9956
        assert st[0, 2] == (CellState.FREE if k >= 5 else CellState.UNKNOWN)  # 5·(−0.405) clamps at −2.0
    for _ in range(20):
        g.integrate_scan((0.5, 0.5, 0.0), [0.0], [5.0], 8.0)
    assert g.log_odds[0, 5] == pytest.approx(L_MAX)
    assert g.log_odds[0, 0] == pytest.approx(L_MIN)
    assert g.probabilities()[0, 5] == pytest.approx(0.971)


def test_traced_cells_are_exactly_bresenham_from_sensor_cell_to_end_cell() -> None:
    g = OccupancyGrid(40, 30, 0.1, (-2.0, -1.0))
    pose = (-1.23, 0.41, 0.3)
    angle, rng = 0.45, 1.7
    g.integrate_scan(pose, [angle], [rng], 5.0)
    r0, c0 = g.world_to_cell(pose[0], pose[1])
    ex = pose[0] + rng * math.cos(pose[2] + angle)
    ey = pose[1] + rng * math.sin(pose[2] + angle)
    r1, c1 = g.world_to_cell(ex, ey)
    line = bresenham(r0, c0, r1, c1)
    expected = np.zeros(g.shape)
    expected[line[:-1, 0], line[:-1, 1]] = L_MISS
    expected[r1, c1] = L_HIT
    np.testing.assert_allclose(g.log_odds, expected, atol=1e-12)


def test_no_return_beams_are_free_up_to_max_range_without_a_hit() -> None:
    for reading in (float("inf"), 4.0, 7.5):  # +inf, exactly max range, beyond max range
        g = unit_grid()
        g.integrate_scan((0.5, 0.5, math.pi / 2), [0.0], [reading], 4.0)
        expected = np.zeros((10, 10))
        expected[0:5, 0] = L_MISS  # y from 0.5 to 4.5 → rows 0..4, the end cell included, no hit
        np.testing.assert_allclose(g.log_odds, expected, atol=1e-12)


def test_invalid_readings_are_skipped() -> None:
    g = unit_grid()
    nan, inf = float("nan"), float("inf")
    g.integrate_scan(
        (0.5, 0.5, 0.0),
        [0.1, 0.2, 0.3, 0.4, nan, inf],
        [-inf, -1.0, 0.0, 0.2, 3.0, 3.0],
        8.0,
        min_range_m=0.3,
    )
    assert np.all(g.log_odds == 0.0)


def test_nan_and_inf_ranges_are_no_return_free_up_to_max_range() -> None:
    for special in (float("nan"), float("inf")):
        g = unit_grid()
        g.integrate_scan((0.5, 5.5, 0.0), [0.0], [special], 4.0)
        # Free along the beam to max range (cells 0..4 of row 5), and no hit anywhere.
        assert np.all(g.log_odds[5, 0:5] == pytest.approx(L_MISS))
        assert np.count_nonzero(g.log_odds) == 5


def test_one_update_per_cell_per_scan_and_hit_beats_pass_through() -> None:
    g = unit_grid()
    # Two beams ending in the same cell (5, 5): one hit update, not two.
    g.integrate_scan((0.5, 5.5, 0.0), [0.0, 0.0], [5.0, 5.2], 9.0)
    assert g.log_odds[5, 5] == pytest.approx(L_HIT)
    assert g.log_odds[5, 2] == pytest.approx(L_MISS)
    # A longer beam passing through a cell another beam of the same scan ends in: the hit wins.
    g = unit_grid()
    g.integrate_scan((0.5, 5.5, 0.0), [0.0, 0.0], [8.0, 5.0], 9.0)
    assert g.log_odds[5, 5] == pytest.approx(L_HIT)
    assert g.log_odds[5, 6] == pytest.approx(L_MISS)
    assert g.log_odds[5, 8] == pytest.approx(L_HIT)


def test_clearing_only_beams_free_their_way_and_leave_their_end_cell() -> None:
    g = unit_grid()
    g.log_odds[5, 5] = 2.5  # a cell marked before (a cart that has moved on, say)
    # Beam 0 (clearing-only) ends in (5, 5); beam 1 (marking) passes through it to (5, 8); beam 2 (clearing-only)
    # and beam 3 (marking) both end in (7, 4).
    angles = [0.0, 0.0, math.atan2(2.0, 4.0), math.atan2(2.0, 4.0)]
    ranges = [5.0, 8.0, math.hypot(4.0, 2.0), math.hypot(4.0, 2.0)]
    marks = np.array([False, True, False, True])
    g.integrate_scan((0.5, 5.5, 0.0), angles, ranges, 9.0, marks=marks)
    assert g.log_odds[5, 3] == pytest.approx(L_MISS)  # cleared on the way
    assert g.log_odds[5, 5] == pytest.approx(2.5)  # neither hit nor missed, though a marking beam crossed it
    assert g.log_odds[5, 8] == pytest.approx(L_HIT)
    assert g.log_odds[7, 4] == pytest.approx(L_HIT)  # a marking beam ends there too: the hit stands
    # Alone, the clearing-only beam into (7, 4) leaves it unknown.
    g = unit_grid()
    g.integrate_scan((0.5, 5.5, 0.0), angles[2:3], ranges[2:3], 9.0, marks=np.array([False]))
    assert g.log_odds[7, 4] == 0.0 and g.log_odds[6, 2] == pytest.approx(L_MISS)
    with pytest.raises(InvalidGridError, match="marks"):
        g.integrate_scan((0.5, 5.5, 0.0), [0.0], [3.0], 9.0, marks=np.array([1]))


def test_many_beams_through_the_sensor_cell_update_it_once() -> None:
    g = unit_grid()
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    g.integrate_scan((5.5, 5.5, 0.0), angles, np.full(360, 3.0), 10.0)
    assert g.log_odds[5, 5] == pytest.approx(L_MISS)
    assert set(np.unique(g.log_odds).tolist()) == {0.0, L_MISS, L_HIT}


def test_pose2d_and_array_poses_are_accepted() -> None:
    a = unit_grid()
    b = unit_grid()
    c = unit_grid()
    a.integrate_scan((2.5, 3.5, 0.7), [0.0, 1.0], [3.0, 2.0], 8.0)
    b.integrate_scan(Pose2D(2.5, 3.5, 0.7), np.array([0.0, 1.0]), [3, 2], 8.0)
    c.integrate_scan(np.array([2.5, 3.5, 0.7]), (0.0, 1.0), np.array([3.0, 2.0], dtype=np.float32), 8)
    np.testing.assert_array_equal(a.log_odds, b.log_odds)
    np.testing.assert_array_equal(a.log_odds, c.log_odds)


# ---------------------------------------------------------------------------------------------------------
# Clipping at the map edge
# ---------------------------------------------------------------------------------------------------------


def test_beam_leaving_the_map_marks_no_hit_and_stops_at_the_edge() -> None:
    g = unit_grid()
    g.integrate_scan((7.5, 2.5, 0.0), [0.0], [5.0], 8.0)  # ends at x = 12.5, outside
    expected = np.zeros((10, 10))
    expected[2, 7:10] = L_MISS
    np.testing.assert_allclose(g.log_odds, expected, atol=1e-12)


def test_sensor_outside_the_map_updates_the_part_inside() -> None:
    g = unit_grid()
    g.integrate_scan((-3.5, 4.5, 0.0), [0.0], [6.0], 20.0)  # from x = −3.5 to 2.5: enters at x = 0
    expected = np.zeros((10, 10))
    expected[4, 0:2] = L_MISS
    expected[4, 2] = L_HIT
    np.testing.assert_allclose(g.log_odds, expected, atol=1e-12)
    g = unit_grid()
    g.integrate_scan((-3.5, 4.5, math.pi), [0.0], [6.0], 20.0)  # pointing away: nothing
    assert np.all(g.log_odds == 0.0)


def test_absurd_but_finite_values_never_crash() -> None:
    rng = np.random.default_rng(4)
    g = OccupancyGrid(50, 40, 0.1, (-1.0, -2.0))
    specials = np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, -5.0, 1e-300, 1e300, -1e300, 1e15, 5e-324])
    for _ in range(30):
        n = int(rng.integers(0, 60))
        angles = rng.choice(np.concatenate([specials, rng.uniform(-10, 10, 20)]), size=n)
        ranges = rng.choice(np.concatenate([specials, rng.uniform(0, 8, 20)]), size=n)
        x, y = rng.choice(np.array([0.5, -1.0, 4.0, 1e200, -1e200, 1e9, 2.9999999999]), size=2)
        g.integrate_scan((float(x), float(y), float(rng.uniform(-1e6, 1e6))), angles, ranges, 9.0)
    m = g.model
    assert np.all(np.isfinite(g.log_odds))
    assert np.all((g.log_odds >= m.min_log_odds) & (g.log_odds <= m.max_log_odds))
    h = unit_grid()
    h.integrate_scan((0.5, 0.5, 0.0), [0.0], [1e300], 1e9)  # no return, huge max range: clipped to the grid
    expected = np.zeros((10, 10))
    expected[0, :] = L_MISS
    np.testing.assert_allclose(h.log_odds, expected, atol=1e-12)


@pytest.mark.parametrize(
    ("pose", "angles", "ranges", "max_range", "error"),
    [
        ((float("nan"), 0.0, 0.0), [0.0], [1.0], 5.0, InvalidPoseError),
        ((0.0, float("inf"), 0.0), [0.0], [1.0], 5.0, InvalidPoseError),
        ((0.0, 0.0, float("nan")), [0.0], [1.0], 5.0, InvalidPoseError),
        ((0.0, 0.0), [0.0], [1.0], 5.0, InvalidPoseError),
        ("abc", [0.0], [1.0], 5.0, InvalidPoseError),
        ((0.0, 0.0, 0.0), [0.0, 1.0], [1.0], 5.0, InvalidGridError),
        ((0.0, 0.0, 0.0), [[0.0]], [[1.0]], 5.0, InvalidGridError),
        ((0.0, 0.0, 0.0), ["a"], ["b"], 5.0, InvalidGridError),
        ((0.0, 0.0, 0.0), [0.0], [1.0 + 1.0j], 5.0, InvalidGridError),
        ((0.0, 0.0, 0.0), [0.0], [1.0], float("nan"), InvalidParameterError),
        ((0.0, 0.0, 0.0), [0.0], [1.0], float("inf"), InvalidParameterError),
        ((0.0, 0.0, 0.0), [0.0], [1.0], 0.0, InvalidParameterError),
        ((0.0, 0.0, 0.0), [0.0], [1.0], 1e20, InvalidParameterError),
    ],
)
def test_integrate_scan_bad_input_raises_typed_errors(pose, angles, ranges, max_range, error) -> None:
    g = unit_grid()
    with pytest.raises(error):
        g.integrate_scan(pose, angles, ranges, max_range)
    assert np.all(g.log_odds == 0.0)


@pytest.mark.parametrize("margin", [float("nan"), float("inf"), -0.1])
def test_a_bad_grazing_margin_is_a_typed_error(margin: float) -> None:
    g = unit_grid()
    with pytest.raises(InvalidParameterError, match="grazing_margin_m"):
        g.integrate_scan((5.0, 5.0, 0.0), [0.0], [2.0], 5.0, grazing_margin_m=margin)
    assert np.all(g.log_odds == 0.0)


def _scans_along_a_wall(margin_m: float) -> OccupancyGrid:
    """A robot driving along a wall whose face is the line y = -0.02 m (inside a row of 5 cm cells), 0.5 m from
    it, scanning (360 beams, 12 m) every 0.1 m for 10 m: the far beams meet the wall at a few degrees."""
    g = OccupancyGrid(600, 100, 0.05, (-15.0, -2.0))
    angles = np.linspace(-np.pi, np.pi, 360, endpoint=False)
    for x in np.arange(-5.0, 5.0, 0.1):
        heading = np.sin(angles)  # the beams' y direction (the robot faces +x)
        with np.errstate(divide="ignore"):
            ranges = np.where(heading < 0, (0.5 + 0.02) / -heading, np.inf)
        g.integrate_scan((x, 0.5, 0.0), angles, np.minimum(ranges, np.inf), 12.0, grazing_margin_m=margin_m)
    return g


def test_beams_grazing_a_wall_do_not_clear_its_face() -> None:
    """Issue 30: beams that meet a long wall at a shallow angle cross the cells of its face before they end
    further along; their misses cleared the face wherever no return ended (holes the planner took for a way
    through). With a grazing margin no cell holding wall is ever cleared, and the free side still is."""
    face_and_behind = np.s_[:40, 200:400]  # rows below y = 0 (the face's row and the wall), x in [-5, 5]
    plain = _scans_along_a_wall(0.0)
    assert (plain.log_odds[face_and_behind] < 0).any()  # what happened: the wall's face was cleared
    guarded = _scans_along_a_wall(0.1)
    assert not (guarded.log_odds[face_and_behind] < 0).any()
    assert (guarded.states()[39, 200:400] == CellState.OCCUPIED).all()  # the face, solid along the drive
    assert (guarded.states()[45:49, 200:400] == CellState.FREE).all()  # the free space before it, still free


def test_empty_scan_is_a_no_op() -> None:
    g = unit_grid()
    g.integrate_scan((1.0, 1.0, 0.0), [], [], 5.0)
    assert np.all(g.log_odds == 0.0)


# ---------------------------------------------------------------------------------------------------------
# Against an independent reference of the same update
# ---------------------------------------------------------------------------------------------------------


def reference_scan(g: OccupancyGrid, pose: tuple[float, float, float], angles, ranges, max_range: float) -> None:
    """Slow reference: Bresenham per beam from bresenham(), OctoMap rule, all beams inside the grid."""
    m = g.model
    inv = 1.0 / g.resolution_m
    sx, sy = (pose[0] - g.origin_m[0]) * inv, (pose[1] - g.origin_m[1]) * inv
    ct, st = math.cos(pose[2]), math.sin(pose[2])
    free: set[tuple[int, int]] = set()
    hits: set[tuple[int, int]] = set()
    for a, r in zip(angles, ranges, strict=True):
        r = math.inf if math.isnan(r) else r  # NaN = no return, like +inf
        if r <= 0:
            continue
        r_c = r * inv
        hit = r_c < max_range * inv
        r_c = min(r_c, max_range * inv)
        ex = sx + r_c * (ct * math.cos(a) - st * math.sin(a))
        ey = sy + r_c * (st * math.cos(a) + ct * math.sin(a))
        end = (math.floor(ey), math.floor(ex))
        free.update((int(rr), int(cc)) for rr, cc in bresenham(math.floor(sy), math.floor(sx), *end))
        if hit:
            hits.add(end)
    d_miss = m.miss_log_odds - m.prior_log_odds
    d_hit = m.hit_log_odds - m.prior_log_odds
    for cell in free - hits:
        g.log_odds[cell] = min(max(g.log_odds[cell] + d_miss, m.min_log_odds), m.max_log_odds)
    for cell in hits:
        g.log_odds[cell] = min(max(g.log_odds[cell] + d_hit, m.min_log_odds), m.max_log_odds)


def test_matches_reference_on_random_scans_inside_the_grid() -> None:
    rng = np.random.default_rng(5)
    fast = OccupancyGrid(60, 50, 0.1, (-3.0, -2.5), prior_log_odds=0.1)
    slow = OccupancyGrid(60, 50, 0.1, (-3.0, -2.5), prior_log_odds=0.1)
    for _ in range(40):
        pose = (float(rng.uniform(-0.5, 0.5)), float(rng.uniform(-0.5, 0.5)), float(rng.uniform(-4, 4)))
        angles = np.sort(rng.uniform(-math.pi, math.pi, 90))
        ranges = rng.uniform(0.05, 2.2, 90)  # the grid spans ±2.5 m around the sensor area: always inside
        ranges[rng.random(90) < 0.1] = np.inf
        ranges[rng.random(90) < 0.05] = np.nan
        fast.integrate_scan(pose, angles, ranges, 2.0)
        reference_scan(slow, pose, angles, ranges, 2.0)
        np.testing.assert_array_equal(fast.log_odds, slow.log_odds)
    assert np.count_nonzero(fast.states() == CellState.OCCUPIED) > 0
    assert np.count_nonzero(fast.states() == CellState.FREE) > 0


# ---------------------------------------------------------------------------------------------------------
# ROS conversion
# ---------------------------------------------------------------------------------------------------------


def test_to_ros_values_and_layout() -> None:
    g = unit_grid(4, 3)
    g.log_odds[0, 1] = math.log(0.7 / 0.3)  # p = 0.7 → 70
    g.log_odds[2, 3] = 4.0  # p = 0.982 → 98
    g.log_odds[1, 0] = -3.0  # p = 0.047 → 5
    ros = g.to_ros()
    assert ros.dtype == np.int8
    assert ros.shape == (3, 4)
    expected = np.full((3, 4), -1, dtype=np.int8)
    expected[0, 1], expected[2, 3], expected[1, 0] = 70, 98, 5
    np.testing.assert_array_equal(ros, expected)
    # nav_msgs/OccupancyGrid data: row-major, row 0 = lowest y → data[row·W + col].
    data = ros.ravel()
    assert data[0 * 4 + 1] == 70
    assert data[2 * 4 + 3] == 98
    x, y = g.cell_to_world(2, 3)
    assert data[int(y // 1.0) * 4 + int(x // 1.0)] == 98
    trinary = g.to_ros(trinary=True)
    np.testing.assert_array_equal(trinary, g.states())
    assert trinary[2, 3] == 100
    assert trinary[1, 0] == 0
    assert trinary[0, 1] == -1  # 0.847 is below the occupied threshold


def test_from_ros_round_trip_and_prior_values() -> None:
    values = np.array([[-1, 0, 1, 13, 30], [49, 50, 51, 80, 100]], dtype=np.int8)
    g = OccupancyGrid.from_ros(values.ravel(), 5, 2, 0.05, (1.0, 2.0))
    assert g.shape == (2, 5)
    assert g.origin_m == (1.0, 2.0)
    assert g.log_odds[0, 0] == 0.0  # unknown → prior
    assert g.log_odds[0, 1] == pytest.approx(L_MIN)  # 0 → clamped
    assert g.log_odds[1, 4] == pytest.approx(L_MAX)  # 100 → clamped
    assert g.log_odds[1, 3] == pytest.approx(math.log(0.8 / 0.2))
    back = g.to_ros()
    # Values strictly inside the clamp range (13..97) read back exactly; 50 is the prior (no information) →
    # −1.
    expected = values.copy()
    expected[0, 1] = 12  # 0 → clamped at p = 0.1192
    expected[0, 2] = 12  # 1 % is below the lower clamp too
    expected[1, 4] = 97  # 100 → clamped at p = 0.971
    expected[1, 1] = -1
    np.testing.assert_array_equal(back, expected)
    same = OccupancyGrid.from_ros(values, 5, 2, 0.05, (1.0, 2.0))
    np.testing.assert_array_equal(same.log_odds, g.log_odds)


@pytest.mark.parametrize(
    "data",
    [
        np.zeros(6, dtype=np.float64),  # wrong dtype
        np.zeros(5, dtype=np.int8),  # wrong size
        np.zeros((3, 2), dtype=np.int8),  # wrong 2-D shape
        np.array([0, 0, 0, 0, 0, 101], dtype=np.int16),
        np.array([0, 0, 0, 0, 0, -2], dtype=np.int8),
    ],
)
def test_from_ros_rejects_bad_data(data: np.ndarray) -> None:
    with pytest.raises(InvalidGridError):
        OccupancyGrid.from_ros(data, 3, 2, 0.1)


def test_copy_is_independent() -> None:
    g = unit_grid()
    g.integrate_scan((0.5, 0.5, 0.0), [0.0], [5.0], 8.0)
    h = g.copy()
    np.testing.assert_array_equal(h.log_odds, g.log_odds)
    h.integrate_scan((0.5, 0.5, 0.0), [0.0], [5.0], 8.0)
    assert h.log_odds[0, 5] == pytest.approx(2 * L_HIT)
    assert g.log_odds[0, 5] == pytest.approx(L_HIT)


# ---------------------------------------------------------------------------------------------------------
# Real data: the Intel Research Lab log
# ---------------------------------------------------------------------------------------------------------


def _intel(root: Path, limit: int) -> tuple[list[tuple[float, float, float]], np.ndarray]:
    poses, scans = [], []
    with gzip.open(root / "laser2d_carmen" / "intel-corrected.log.gz", "rt") as fh:
        for line in fh:
            if line.startswith("FLASER"):
                tok = line.split()
                n = int(tok[1])
                scans.append([float(v) for v in tok[2 : 2 + n]])
                poses.append((float(tok[2 + n]), float(tok[3 + n]), float(tok[4 + n])))
                if len(poses) == limit:
                    break
    return poses, np.asarray(scans)


def test_intel_log_builds_a_consistent_map(refdata: Path) -> None:
    """Radish Intel Research Lab log (corrected poses): the robot's cells stay free-ish and later beams end
    on walls built by earlier ones; with the beam order mirrored the same check collapses (negative
    control)."""
    poses, scans = _intel(refdata, 400)
    angles = np.deg2rad(np.arange(-90.0, 90.0, 1.0))
    from scipy import ndimage

    agreement = {}
    for sign in (1.0, -1.0):
        g = OccupancyGrid(400, 400, 0.1, (-15.0, -25.0))
        for pose, ranges in zip(poses, scans, strict=True):
            g.integrate_scan(pose, sign * angles, ranges, 50.0)
        states = g.states()
        if sign > 0:
            assert all(states[g.world_to_cell(x, y)] != CellState.OCCUPIED for x, y, _ in poses)
            assert np.count_nonzero(states == CellState.OCCUPIED) > 1500
        walls = ndimage.binary_dilation(states == CellState.OCCUPIED)
        ok = total = 0
        for (x, y, th), ranges in list(zip(poses, scans, strict=True))[::10]:
            m = ranges < 50.0
            for hx, hy in zip(
                x + ranges[m] * np.cos(th + sign * angles[m]),
                y + ranges[m] * np.sin(th + sign * angles[m]),
                strict=True,
            ):
                if g.contains(hx, hy):
                    total += 1
                    ok += bool(walls[g.world_to_cell(hx, hy)])
        agreement[sign] = ok / total
    assert agreement[1.0] > 0.7
    assert agreement[-1.0] < 0.1


def test_thresholds_are_strict_free_below_occupied_above() -> None:
    grid = OccupancyGrid(4, 1, 0.1)
    m = grid.model
    grid.log_odds[0] = (m.free_threshold, np.nextafter(m.free_threshold, -np.inf), m.occupied_threshold, 3.0)
    assert grid.states().tolist() == [[CellState.UNKNOWN, CellState.FREE, CellState.UNKNOWN, CellState.OCCUPIED]]


def test_thresholds_at_the_clamp_bounds_are_rejected() -> None:
    with pytest.raises(InvalidParameterError, match="strictly within"):
        LogOddsModel(min_log_odds=-2.0, free_threshold=-2.0)


def test_a_grid_grows_on_the_same_cells_and_keeps_what_it_knows() -> None:
    g = OccupancyGrid(10, 8, 0.1, (1.0, 2.0))
    g.log_odds[3, 4] = 2.5
    same = g.grown_to(1.2, 2.1, 1.9, 2.7)  # inside already
    assert same is g
    grown = g.grown_to(0.75, 2.0, 2.31, 3.0)  # 0.25 m left (3 cells), 0.31 m right (4 cells), 0.2 m up (2 cells)
    assert grown is not g and grown.origin_m == pytest.approx((0.7, 2.0))
    assert grown.shape == (10, 17)
    assert grown.log_odds[3, 4 + 3] == 2.5 and np.count_nonzero(grown.log_odds != grown.model.prior_log_odds) == 1
    assert grown.world_to_cell(1.45, 2.35) == (3, 7)  # the cell that was (3, 4): the same place
    with pytest.raises(InvalidParameterError):
        g.grown_to(2.0, 2.0, 1.0, 3.0)
    with pytest.raises(InvalidParameterError):
        g.grown_to(0.0, math.nan, 1.0, 3.0)

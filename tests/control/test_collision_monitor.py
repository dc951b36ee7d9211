"""The collision monitor: zones grown from a footprint, stop / slowdown / approach rules, the escape rule, and a
kinematic closed loop (a unicycle braking at a bounded deceleration under the monitor) that stops clear of walls."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import pytest

import mjnav.control.collision_monitor as cm
from mjnav.control import (
    CollisionMonitor,
    CollisionMonitorParams,
    MonitorAction,
    MonitorInputError,
    Zone,
    default_zones,
    offset_polygon,
)
from mjnav.robot import parse_robot_description
from tests.conftest import REPO
from tests.estimation._scans import scan_points

R = 0.18
#: A disc of radius R as the robot description draws it: the circumscribed 32-gon, an edge facing +x and +y.
DISC = (R / math.cos(math.pi / 32)) * np.column_stack(
    (np.cos((np.arange(32) + 0.5) * math.pi / 16), np.sin((np.arange(32) + 0.5) * math.pi / 16))
)
#: The Jackal's 0.508 x 0.430 m rectangle.
RECT = np.array([[-0.254, -0.215], [0.254, -0.215], [0.254, 0.215], [-0.254, 0.215]])
#: One point is enough to act (hand-made cases place single points).
ONE = CollisionMonitorParams(min_points=1)


def _monitor(
    footprint: np.ndarray, params: CollisionMonitorParams = ONE, only: tuple[str, ...] = ()
) -> CollisionMonitor:
    """The default zones of ``footprint`` (only those named in ``only``, if given)."""
    zones = default_zones(footprint, params)
    return CollisionMonitor([z for z in zones if not only or z.name in only], params)


def _wall_x(x: float, half_m: float = 1.0) -> np.ndarray:
    """A wall across the way at x (5 mm spacing), base frame."""
    y = np.arange(-half_m, half_m + 1e-9, 0.005)
    return np.column_stack((np.full_like(y, x), y))


def _wall_y(y: float, half_m: float = 1.0) -> np.ndarray:
    """A wall along the robot's side at y (5 mm spacing)."""
    x = np.arange(-half_m, half_m + 1e-9, 0.005)
    return np.column_stack((x, np.full_like(x, y)))


# ------------------------------------------------------------------------------------------------ zones


def test_offset_polygon_holds_every_point_within_the_margin_and_little_more() -> None:
    grown = offset_polygon(RECT, 0.1)
    zone = Zone("z", MonitorAction.STOP, grown)
    rng = np.random.default_rng(3)
    p = rng.uniform(-0.5, 0.5, (20000, 2))
    dist = np.hypot(np.maximum(np.abs(p[:, 0]) - 0.254, 0.0), np.maximum(np.abs(p[:, 1]) - 0.215, 0.0))
    inside = zone.contains(p)
    assert inside[dist <= 0.1].all()
    assert not inside[dist > 0.1 / math.cos(math.pi / 32) + 1e-9].any()  # circumscribed facets: < 0.5 % more
    assert len(grown) == 32  # 8 facets per right-angle corner


def test_offset_of_the_disc_polygon_is_the_larger_disc_polygon() -> None:
    grown = offset_polygon(DISC, 0.02)
    assert grown.shape == (32, 2)
    np.testing.assert_allclose(np.hypot(grown[:, 0], grown[:, 1]), (R + 0.02) / math.cos(math.pi / 32))
    np.testing.assert_array_equal(offset_polygon(DISC, 0.0), DISC)
    with pytest.raises(ValueError, match="margin_m"):
        offset_polygon(DISC, -0.01)


@pytest.mark.parametrize(
    ("polygon", "message"),
    [
        (RECT[::-1], "convex and counter-clockwise"),  # clockwise
        (np.array([[0, 0], [1, 0], [0.2, 0.2], [0, 1]]), "convex"),  # a dent
        (np.array([[0, 0], [1, 0], [1, 0], [0, 1]]), "repeats a vertex"),
        (np.array([[0, 0], [1, 0]]), "K >= 3"),
        (np.array([[0, 0], [1, np.nan], [0, 1]]), "non-finite"),
        (np.vstack((RECT, RECT)), "convex and counter-clockwise"),  # turns twice
    ],
)
def test_a_zone_polygon_must_be_convex_and_counter_clockwise(polygon: np.ndarray, message: str) -> None:
    with pytest.raises(MonitorInputError, match=message):
        Zone("z", MonitorAction.STOP, polygon)
    with pytest.raises(MonitorInputError):
        default_zones(polygon)


def test_a_lead_stretches_the_zone_along_the_direction_of_travel() -> None:
    zone = Zone("z", MonitorAction.SLOWDOWN, RECT, lead_m=0.5)
    for v, x_min, x_max in ((0.0, -0.254, 0.254), (0.3, -0.254, 0.754), (-0.3, -0.754, 0.254)):
        poly = zone.polygon_for(v)
        assert poly[:, 0].min() == pytest.approx(x_min) and poly[:, 0].max() == pytest.approx(x_max)
        np.testing.assert_allclose(np.abs(poly[:, 1]).max(), 0.215)
    assert zone.contains([[0.6, 0.0]], 0.3)[0] and not zone.contains([[0.6, 0.0]], -0.3)[0]
    np.testing.assert_allclose(zone.depth_m([[0.0, 0.0], [0.3, 0.0]]), [0.215, -0.046])


# ------------------------------------------------------------------------------------------------ stop and slowdown


def test_a_point_in_the_stop_zone_stops_a_command_into_it() -> None:
    wall = _wall_x(R + 0.005)  # inside the 0.01 m stop zone (and the approach zone)
    r = _monitor(DISC).check(0.3, 0.2, wall)
    assert (r.v_mps, r.omega_radps, r.scale) == (0.0, 0.0, 0.0)
    assert r.action is MonitorAction.STOP and r.zone == "stop" and r.limited  # stop outranks approach's 0


def test_a_point_in_the_slowdown_box_ahead_halves_the_command() -> None:
    m = _monitor(DISC)
    ahead = [[0.65, 0.0]]  # in the 0.5 m box ahead; the approach's roll-out meets it at 0.8 s (scale 0.8)
    r = m.check(0.5, 0.1, ahead)
    assert (r.v_mps, r.omega_radps, r.action, r.zone) == (0.25, 0.05, MonitorAction.SLOWDOWN, "slowdown")
    assert r.time_to_collision_s == pytest.approx(0.8)  # reported though slowdown won
    assert m.check(0.2, 0.0, ahead).v_mps == pytest.approx(0.1)
    # Behind the robot it does not slow a forward command, but slows reversing; a spin uses no box.
    assert not m.check(0.5, 0.0, [[-0.65, 0.0]]).limited
    assert m.check(-0.5, 0.0, [[-0.65, 0.0]]).action is MonitorAction.SLOWDOWN
    assert not m.check(0.0, 1.0, ahead).limited


def test_min_points_returns_are_needed_before_a_zone_acts() -> None:
    m = _monitor(DISC, CollisionMonitorParams(min_points=3))
    two = [[0.65, -0.01], [0.65, 0.01], [3.0, 0.0], [3.0, 1.0], [-2.0, 0.0]]  # two in the box ahead, three far
    assert not m.check(0.5, 0.0, two).limited
    assert m.check(0.5, 0.0, [*two, [0.65, 0.0]]).action is MonitorAction.SLOWDOWN
    wall = _wall_x(R + 0.005)  # touching: hundreds of points in the stop zone ...
    assert m.check(0.3, 0.0, wall).action is MonitorAction.STOP
    assert not m.check(0.3, 0.0, np.vstack((wall[:2], _wall_x(2.0)))).limited  # ... or two of them


def test_the_most_restrictive_zone_wins() -> None:
    m = _monitor(DISC)
    # A wall 0.18 m beyond the approach zone's front (0.2 + 0.03 lead): collision on the 4th step, t = 0.3 s.
    r = m.check(0.5, 0.0, _wall_x(0.23 + 0.18))
    assert r.action is MonitorAction.APPROACH
    assert r.scale == pytest.approx(0.3) and r.time_to_collision_s == pytest.approx(0.3)
    r = m.check(0.5, 0.0, _wall_x(0.23 + 0.42))  # approach 0.8, slowdown 0.5
    assert (r.action, r.scale) == (MonitorAction.SLOWDOWN, 0.5)


# ------------------------------------------------------------------------------------------------ approach


def test_a_wall_ahead_gives_the_analytic_time_to_collision_and_v_times_t_over_t() -> None:
    fine = dataclasses.replace(ONE, simulation_step_s=0.01)
    m = _monitor(DISC, fine, only=("approach",))
    gap = 0.4237  # from the approach zone's front (R + 0.02 margin + 0.03 lead) to the wall
    wall = _wall_x(R + 0.05 + gap)
    for v in (0.5, 0.45):
        r = m.check(v, 0.0, wall)
        exact = gap / v  # the front edge (inscribed: facing +x) reaches the wall
        assert exact - 0.01 <= r.time_to_collision_s <= exact
        assert r.v_mps == pytest.approx(v * r.time_to_collision_s / 1.0)
        assert r.action is MonitorAction.APPROACH and r.zone == "approach"
    # Nav2's step (0.1 s): the last collision-free step before 0.8474 s.
    assert _monitor(DISC, ONE, only=("approach",)).check(0.5, 0.0, wall).time_to_collision_s == pytest.approx(0.8)
    # Slower, the collision lies beyond T = 1 s: nothing to limit.
    r = m.check(0.4, 0.0, wall)
    assert not r.limited and math.isinf(r.time_to_collision_s)
    # A command whose first step already reaches the zone stops.
    assert m.check(0.5, 0.0, _wall_x(R + 0.05 + 0.004)).v_mps == 0.0


def test_a_point_beside_the_arc_does_not_limit_and_one_on_it_does() -> None:
    m = _monitor(DISC, only=("approach",))
    assert not m.check(0.5, 0.0, [[0.5, 0.205]]).limited  # 5 mm outside the swept band (R + 0.02)
    assert m.check(0.5, 0.0, [[0.5, 0.195]]).action is MonitorAction.APPROACH
    assert m.check(0.5, 1.0, [[0.5, 0.205]]).action is MonitorAction.APPROACH  # the left arc turns into it
    assert not m.check(0.5, -1.0, [[0.5, 0.205]]).limited  # the right arc turns away


def test_rotation_in_place_is_limited_by_a_rectangle_corner_and_not_by_a_disc() -> None:
    point = [[0.30, 0.0]]  # beyond the rectangle's front edge (0.254 + 0.02) but within its corners' sweep
    # The front edge x = 0.274 reaches the point after acos(0.274 / 0.30) = 0.420 rad: t = 0.42 s at 1 rad/s.
    for w in (1.0, -1.0):
        r = _monitor(RECT).check(0.0, w, point)
        assert r.action is MonitorAction.APPROACH and r.time_to_collision_s == pytest.approx(0.4)
        assert r.omega_radps == pytest.approx(0.4 * w)
        assert not _monitor(DISC).check(0.0, w, point).limited


def test_a_fast_turn_does_not_skip_a_point_between_simulation_steps(monkeypatch: pytest.MonkeyPatch) -> None:
    """At 3 rad/s a step turns the rectangle 0.3 rad: a point near the corner's circle is inside the approach zone
    only between two steps; the sub-sampled roll-out catches it."""
    m = _monitor(RECT, ONE, only=("approach",))
    zone = m.zones[0]
    rho = float(np.hypot(*RECT.T).max())  # on the bare rectangle's corner circle
    theta = np.linspace(0.0, 3.0, 30001)  # the spin's angle over T = 1 s, 1e-4 rad apart
    found = None
    for alpha in np.linspace(0.0, 0.5 * math.pi, 400):
        local = rho * np.column_stack((np.cos(alpha - theta), np.sin(alpha - theta)))  # in the zone's frame
        inside = zone.contains(local)
        if inside.any() and not inside[0] and not inside[::3000].any():  # inside only between the 0.3 rad steps
            found = (rho * np.array([math.cos(alpha), math.sin(alpha)]), float(theta[np.argmax(inside)]) / 3.0)
            break
    assert found is not None
    p, first_s = found
    r = m.check(0.0, 3.0, [p])
    assert r.action is MonitorAction.APPROACH
    step = math.floor(first_s / 0.1) * 0.1
    assert step - 1e-9 <= r.time_to_collision_s <= step + 0.1 + 1e-9
    monkeypatch.setattr(cm, "_SWEEP_STEP_M", 1e9)  # one sample per step (Nav2's): the point is missed
    assert not m.check(0.0, 3.0, [p]).limited


def test_reversing_toward_a_wall_is_limited_as_driving_forward_is() -> None:
    m = _monitor(DISC)
    behind = _wall_x(-(R + 0.05 + 0.4237))
    r = m.check(-0.5, 0.0, behind)
    assert r.time_to_collision_s == pytest.approx(0.8) and r.v_mps == -0.25  # slowdown's box behind: half
    assert _monitor(DISC, only=("approach",)).check(-0.5, 0.0, behind).v_mps == pytest.approx(-0.4)
    assert not m.check(0.5, 0.0, behind).limited


# ------------------------------------------------------------------------------------------------ the escape rule


def test_escape_from_inside_the_stop_zone_is_allowed_and_driving_further_in_is_not() -> None:
    m = _monitor(DISC, only=("stop", "approach"))
    ahead = _wall_x(R + 0.005)  # touching distance, inside both zones
    assert m.check(0.3, 0.0, ahead).action is MonitorAction.STOP
    assert m.check(0.3, 1.0, ahead).action is MonitorAction.STOP  # an arc forward goes in too
    for v, w in ((-0.3, 0.0), (-0.3, 0.8), (0.0, 1.0), (0.0, -1.0)):  # back off, back off turning, turn in place
        r = m.check(v, w, ahead)
        assert not r.limited and (r.v_mps, r.omega_radps) == (v, w)


def test_a_rectangle_beside_a_wall_drives_along_it_but_cannot_turn_its_corners_into_it() -> None:
    beside = _wall_y(0.215 + 0.005)
    rect, disc = _monitor(RECT, only=("stop", "approach")), _monitor(DISC, only=("stop", "approach"))
    for v in (0.5, -0.5):
        assert not rect.check(v, 0.0, beside).limited  # along the wall: the nearest return stays as near
    for w in (1.0, -1.0):  # turning either way swings a corner (front or rear) towards the wall
        assert rect.check(0.0, w, beside).action is MonitorAction.STOP
        assert rect.check(0.3, w, beside).action is MonitorAction.STOP
    disc_beside = _wall_y(R + 0.005)
    assert not disc.check(0.0, 1.0, disc_beside).limited  # a disc turns in place
    assert not disc.check(0.3, -1.0, disc_beside).limited  # and away
    assert disc.check(0.3, 1.0, disc_beside).action is MonitorAction.STOP


def test_a_rectangle_and_a_disc_differ_where_their_shapes_do() -> None:
    point = [[0.6, 0.21]]  # inside the rectangle's swept band (0.215 + 0.02), outside the disc's (0.2)
    assert _monitor(RECT, only=("approach",)).check(0.5, 0.0, point).action is MonitorAction.APPROACH
    assert not _monitor(DISC, only=("approach",)).check(0.5, 0.0, point).limited


# ------------------------------------------------------------------------------------------------ moving points

#: Exact roll-out times for the hand-made moving cases: fine steps, no growth of the zone against moving points.
EXACT = dataclasses.replace(ONE, simulation_step_s=0.01, uncertainty_growth_mps=0.0)


def _segment(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    """Points along a segment, 5 mm apart, base frame."""
    n = max(2, math.ceil(math.hypot(x1 - x0, y1 - y0) / 0.005) + 1)
    return np.column_stack((np.linspace(x0, x1, n), np.linspace(y0, y1, n)))


def _cart(x0: float, y0: float) -> np.ndarray:
    """The returns of a 1.0 x 0.7 m cart's south face (y = y0, x in [x0, x0 + 1]) and west face (x = x0)."""
    return np.vstack((_segment(x0, y0, x0 + 1.0, y0), _segment(x0, y0, x0, y0 + 0.7)))


def _moving(points: np.ndarray, u: tuple[float, float]) -> np.ndarray:
    return np.tile(np.asarray(u, dtype=np.float64), (len(points), 1))


def test_entry_times_follow_each_track_from_when_the_pose_is_held_to_the_horizon() -> None:
    """When moving points would enter a zone held at a pose from a time on (exact, per track)."""
    shape = Zone("z", MonitorAction.APPROACH, offset_polygon(DISC, 0.02))._shapes[0]  # its +x edge at x = 0.2
    point, left = np.array([[0.5, 0.0]]), np.array([[-1.0, 0.0]])
    at_origin = np.zeros((3, 3))
    held_from = np.array([0.0, 0.6, 1.0])  # it enters at 0.3 s; at 0.6 s it is inside; at 1.0 s it has left
    np.testing.assert_allclose(shape.entry_times(point, left, at_origin, held_from, 4.0, 1), [0.3, 0.6, math.inf])
    rect = Zone("r", MonitorAction.APPROACH, RECT)._shapes[0]  # its +x edge at 0.254 m, corners 0.333 m out
    assert rect.entry_times(point, left, at_origin[:1], held_from[:1], 4.0, 1)[0] == pytest.approx(0.246)
    assert rect.entry_times(point, left, at_origin[:1], held_from[:1], 0.2, 1)[0] == math.inf  # after the horizon
    assert shape.entry_times(point, left, at_origin[:1], held_from[:1], 4.0, 2)[0] == math.inf  # one point of two
    turned = np.array([[0.25, 0.0, 0.5 * math.pi]])  # facing +y, 0.25 m ahead: the point reaches its side at 0.05 s
    np.testing.assert_allclose(shape.entry_times(point, left, turned, np.zeros(1), 4.0, 1), [0.05])


def test_a_cart_crossing_ahead_holds_the_robot_by_the_time_to_its_lane() -> None:
    """The cart will reach the robot's way in 2 s, while the robot (at 0.5 m/s) would be in its lane: the time that
    scales the command is that to the first pose the robot could not hold (its zone's front at the lane), not the
    cart's 2 s; a cart seen as static beside the way limits nothing, and one that comes after the robot has
    crossed does not either."""
    m = _monitor(DISC, EXACT, only=("approach",))
    lane = 0.6037  # the cart's near edge; the approach zone reaches 0.23 m ahead (R + 0.02 margin + 0.03 lead)
    cart = _cart(lane, 0.2 + 0.79 * 2.0)
    south = _moving(cart, (0.0, -0.79))
    r = m.check(0.5, 0.0, cart, south)
    exact = (lane - 0.23) / 0.5
    assert r.action is MonitorAction.APPROACH
    assert exact - 0.01 <= r.time_to_collision_s <= exact and r.v_mps == pytest.approx(0.5 * r.time_to_collision_s)
    assert not m.check(0.5, 0.0, cart).limited
    # Reaching the way at 3.9 s, after the zone has left the lane (its rear at lane + 1 m at 3.61 s): no contact.
    later = cart + np.array([0.0, 0.79 * 1.9])
    assert not m.check(0.5, 0.0, later, south).limited
    # Seen by returns 5 cm apart on its south face alone (as at 3 m, its west face edge-on), with min_points 3: the
    # lane still starts at its first return (the contact needs 3 returns, where the robot must stop any one).
    sparse = np.column_stack((lane + 0.05 * np.arange(21), np.full(21, 0.2 + 0.79 * 2.0)))
    r = _monitor(DISC, dataclasses.replace(EXACT, min_points=3), only=("approach",)).check(
        0.5, 0.0, sparse, _moving(sparse, (0.0, -0.79))
    )
    assert exact - 0.01 <= r.time_to_collision_s <= exact
    # The same with the default horizon cut to T = 1 s: the cart's arrival is out of sight.
    short = _monitor(DISC, dataclasses.replace(EXACT, moving_horizon_s=1.0), only=("approach",))
    assert not short.check(0.5, 0.0, cart, south).limited


def test_a_robot_held_at_a_carts_lane_is_not_in_it() -> None:
    """The approach zone's lead (0.03 m) reaches into the cart's lane, the zone without it (the robot standing) does
    not, and the zone grown for the estimate's uncertainty (0.15 m at the cart's arrival in 1.5 s) would: the robot
    is at the lane's edge, not in it, and driving on is held."""
    m = _monitor(DISC, only=("stop", "approach"))
    lane = 0.215  # between the zone's front without the lead (0.2) and with it (0.23)
    cart = _cart(lane, 0.2 + 0.79 * 1.5)
    r = m.check(0.5, 0.0, cart, _moving(cart, (0.0, -0.79)))
    assert r.action is MonitorAction.APPROACH and r.scale == 0.0


def test_a_cart_that_has_passed_or_draws_away_does_not_limit() -> None:
    m = _monitor(DISC, only=("stop", "approach"))
    ahead = _segment(0.5, -0.3, 0.5, 0.3)  # a cart's back 0.27 m beyond the approach zone's front
    assert m.check(0.5, 0.0, ahead).action is MonitorAction.APPROACH  # static: a wall
    assert not m.check(0.5, 0.0, ahead, _moving(ahead, (0.79, 0.0))).limited  # drawing away faster than the robot
    assert m.check(0.5, 0.0, ahead, _moving(ahead, (0.3, 0.0))).action is MonitorAction.APPROACH  # slower: caught up
    passed = _segment(0.3, -0.15, 1.3, -0.15)  # a cart's north face, in the robot's way ...
    assert m.check(0.5, 0.0, passed).action is MonitorAction.APPROACH
    assert not m.check(0.5, 0.0, passed, _moving(passed, (0.0, -0.79))).limited  # ... leaving it


def test_a_cart_coming_at_the_robot_holds_driving_at_it_and_not_backing_away() -> None:
    """Head-on: the cart reaches the robot's zone where it stands in 1.5 s, and a pose ahead more than a step
    sooner from 0.06 m on (0.12 s at 0.5 m/s): driving at it is held to 0.1; backing away or turning in place takes
    the robot nowhere the cart reaches sooner, and passes. Taken as static the face is 2.5 s ahead: beyond T."""
    m = _monitor(DISC, only=("stop", "approach"))
    face = _segment(1.5, -0.35, 1.5, 0.35)
    west = _moving(face, (-0.79, 0.0))
    r = m.check(0.5, 0.0, face, west)
    assert r.action is MonitorAction.APPROACH
    assert r.scale == pytest.approx(0.1) and r.time_to_collision_s == pytest.approx(0.1)
    for v, w in ((-0.5, 0.0), (-0.3, 0.5), (0.0, 1.0)):
        assert not m.check(v, w, face, west).limited
    assert not m.check(0.5, 0.0, face).limited


@pytest.mark.parametrize("seed", range(6))
def test_a_robot_in_a_carts_lane_drives_on_out_of_it(seed: int) -> None:
    """The cart (scanned: 360 beams, 1 cm noise) will reach the robot's side in 1 s, or 0.4 s, standing or driving
    on: driving on (or back) takes the robot nowhere it reaches more than a step sooner, so it passes, though the
    returns' sampling makes the contact a few ms earlier here or there; turning towards the cart brings it more
    than a step sooner, and is limited; away from it, not."""
    rng = np.random.default_rng(seed)
    m = CollisionMonitor.for_footprint(DISC)
    for face_y in (1.0, 0.5):
        outline = [(-0.4, face_y), (0.6, face_y), (0.6, face_y + 0.7), (-0.4, face_y + 0.7)]
        segs = np.array([[*outline[i], *outline[(i + 1) % 4]] for i in range(4)])
        cart = scan_points(segs, (0.0, 0.0, 0.0), rng, 0.01)
        south = _moving(cart, (0.0, -0.79))
        for v in (0.5, -0.5):
            r = m.check(v, 0.0, cart, south)
            assert not r.limited and r.v_mps == v
        if face_y == 1.0:
            r = m.check(0.5, 1.0, cart, south)
            assert r.action is MonitorAction.APPROACH and r.scale < 1.0
            assert not m.check(0.5, -1.0, cart, south).limited


def test_moving_points_do_not_relax_the_static_rules() -> None:
    """Against a wall (static, in the stop zone) with a cart pushing in from behind: forward into the wall is
    stopped although it moves away from the cart, and backing into the cart is stopped too; turning in place
    passes (a disc)."""
    m = _monitor(DISC, only=("stop", "approach"))
    wall, cart = _wall_x(R + 0.005, 0.5), _wall_x(-(R + 0.005), 0.5)
    points = np.vstack((wall, cart))
    u = np.vstack((np.zeros_like(wall), _moving(cart, (0.3, 0.0))))
    assert m.check(0.3, 0.0, points, u).action is MonitorAction.STOP
    assert m.check(-0.3, 0.0, points, u).action is MonitorAction.STOP
    assert not m.check(-0.3, 0.0, wall).limited  # without the cart, backing off the wall is allowed
    assert not m.check(0.0, 1.0, points, u).limited


def test_inside_the_stop_zone_a_command_may_follow_a_cart_that_draws_away() -> None:
    m = _monitor(DISC, only=("stop", "approach"))
    back = _wall_x(R + 0.005, 0.5)  # touching distance
    away = _moving(back, (0.3, 0.0))
    assert not m.check(0.2, 0.0, back, away).limited  # no deeper than now
    assert m.check(0.5, 0.0, back, away).action is MonitorAction.STOP  # deeper than now and than standing
    assert m.check(0.2, 0.0, back).action is MonitorAction.STOP  # static: no closer


def test_zero_velocities_give_what_no_velocities_give() -> None:
    scenes = [
        (DISC, _wall_x(0.41), [(0.5, 0.0), (0.5, 0.1), (-0.5, 0.0)]),
        (DISC, _wall_x(R + 0.005), [(0.3, 0.0), (-0.3, 0.8), (0.0, 1.0)]),
        (DISC, np.array([[0.65, 0.0], [0.65, 0.01], [0.66, 0.0]]), [(0.5, 0.1), (0.2, 0.0)]),
        (RECT, np.array([[0.30, 0.0]]), [(0.0, 1.0), (0.0, -1.0)]),
        (RECT, _wall_y(0.215 + 0.005), [(0.5, 0.0), (0.3, 1.0), (0.0, -1.0)]),
    ]
    for footprint, points, commands in scenes:
        m = _monitor(footprint)
        for v, w in commands:
            assert m.check(v, w, points, np.zeros_like(points)) == m.check(v, w, points)


def test_velocities_must_be_an_array_like_the_points() -> None:
    m = _monitor(DISC)
    wall = _wall_x(0.41)
    for bad in (np.zeros((len(wall), 3)), np.zeros((len(wall) - 1, 2)), np.zeros(len(wall)), [["a", "b"]] * len(wall)):
        with pytest.raises(MonitorInputError, match="velocities"):
            m.check(0.5, 0.0, wall, bad)
    u = np.zeros_like(wall)
    u[3] = np.nan
    with pytest.raises(MonitorInputError, match="finite"):
        m.check(0.5, 0.0, wall, u)
    # A velocity beside a point that is ignored (no return) is ignored with it.
    holes = wall.copy()
    holes[3] = np.nan
    assert m.check(0.5, 0.0, holes, u) == m.check(0.5, 0.0, holes)


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"moving_horizon_s": 0.5}, "moving_horizon_s"),
        ({"moving_horizon_s": math.inf}, "moving_horizon_s"),
        ({"uncertainty_growth_mps": -0.1}, "uncertainty_growth_mps"),
    ],
)
def test_invalid_moving_params_raise_naming_the_field(change: dict[str, float], field: str) -> None:
    with pytest.raises(ValueError, match=f"CollisionMonitorParams.{field}"):
        CollisionMonitorParams(**change)  # type: ignore[arg-type]


# ------------------------------------------------------------------------------------------------ input


def test_non_finite_points_are_ignored_and_a_non_finite_command_is_refused() -> None:
    m = _monitor(DISC)
    wall = _wall_x(0.41)
    noisy = np.vstack((wall, [[np.nan, 0.0], [np.inf, 1.0], [0.3, -np.inf]]))
    assert m.check(0.5, 0.0, noisy) == m.check(0.5, 0.0, wall)
    assert not m.check(0.5, 0.0, [[np.nan, np.nan]]).limited
    assert not m.check(0.5, 0.0, np.zeros((0, 2))).limited
    for v, w in ((math.nan, 0.0), (0.5, math.inf)):
        with pytest.raises(MonitorInputError, match="finite"):
            m.check(v, w, wall)
    with pytest.raises(MonitorInputError, match=r"\(N, 2\)"):
        m.check(0.5, 0.0, np.zeros((4, 3)))
    with pytest.raises(MonitorInputError):
        m.check(0.5, 0.0, [["a", "b"]])


def test_a_standing_command_passes_unchanged() -> None:
    r = _monitor(DISC).check(0.0, 0.0, _wall_x(R + 0.001))
    assert not r.limited and r.zone is None and (r.v_mps, r.omega_radps, r.scale) == (0.0, 0.0, 1.0)


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"stop_margin_m": -0.01}, "stop_margin_m"),
        ({"approach_lead_m": math.inf}, "approach_lead_m"),
        ({"slowdown_ratio": 1.5}, "slowdown_ratio"),
        ({"time_before_collision_s": math.nan}, "time_before_collision_s"),
        ({"simulation_step_s": 0.0}, "simulation_step_s"),
        ({"simulation_step_s": 2.0}, "simulation_step_s"),
        ({"min_points": 0}, "min_points"),
        ({"min_points": 2.5}, "min_points"),
        ({"min_points": True}, "min_points"),
        ({"escape_tolerance_m": -1.0}, "escape_tolerance_m"),
    ],
)
def test_invalid_params_raise_naming_the_field(change: dict[str, float], field: str) -> None:
    with pytest.raises(ValueError, match=f"CollisionMonitorParams.{field}"):
        CollisionMonitorParams(**change)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"action": MonitorAction.NONE}, MonitorInputError),
        ({"action": "brake"}, MonitorInputError),
        ({"name": ""}, MonitorInputError),
        ({"min_points": 0}, MonitorInputError),
        ({"slowdown_ratio": 2.0}, MonitorInputError),
        ({"lead_m": -0.1}, ValueError),
        ({"time_before_collision_s": 0.0}, ValueError),
    ],
)
def test_invalid_zones_raise(kwargs: dict[str, object], error: type[Exception]) -> None:
    args: dict[str, object] = {"name": "z", "action": MonitorAction.SLOWDOWN, "polygon_m": RECT, **kwargs}
    with pytest.raises(error):
        Zone(**args)  # type: ignore[arg-type]


def test_zone_names_are_unique() -> None:
    stop = default_zones(DISC)[0]
    with pytest.raises(MonitorInputError, match="unique"):
        CollisionMonitor([stop, stop])


# ------------------------------------------------------------------------------------------------ closed loop

DIFFBOT = parse_robot_description((REPO / "mjcf" / "diffbot.xml").read_text(encoding="utf-8")).footprint_m


def _inside(poly: np.ndarray, p: np.ndarray) -> np.ndarray:
    e = np.roll(poly, -1, axis=0) - poly
    return np.all(e[:, 0] * (p[:, None, 1] - poly[:, 1]) - e[:, 1] * (p[:, None, 0] - poly[:, 0]) >= 0.0, axis=1)


def _point_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(P, S) distances from points p (P, 2) to segments a→b (S, 2)."""
    ab = b - a
    t = np.clip(((p[:, None] - a) * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
    return np.hypot(*(p[:, None] - a - t[..., None] * ab).transpose(2, 0, 1))


def _clearance(poly: np.ndarray, segs: np.ndarray) -> float:
    """Distance between a convex polygon and wall segments (x0, y0, x1, y1), metres; 0 when they overlap."""
    a, b = segs[:, :2], segs[:, 2:]
    p, q = poly, np.roll(poly, -1, axis=0)

    def side(o: np.ndarray, d: np.ndarray, r: np.ndarray) -> np.ndarray:  # (E, S) orientation of r about o→d
        return (d[:, None, 0] - o[:, None, 0]) * (r[..., 1] - o[:, None, 1]) - (d[:, None, 1] - o[:, None, 1]) * (
            r[..., 0] - o[:, None, 0]
        )

    # Proper crossings; touching and collinear overlaps come out as distance 0 below.
    edges_cross = (side(p, q, a[None]) * side(p, q, b[None]) < 0.0) & (
        side(a, b, p[None]).T * side(a, b, q[None]).T < 0.0
    )
    if edges_cross.any() or _inside(poly, a).any():
        return 0.0
    return min(
        float(_point_segment(poly, a, b).min()),
        float(_point_segment(np.vstack((a, b)), p, q).min()),
    )


def _drive(
    world: Callable[[float], np.ndarray],
    pose: tuple[float, float, float],
    command: tuple[float, float],
    monitor: CollisionMonitor,
    footprint: np.ndarray,
    t_end_s: float,
    decel_mps2: float = 1.0,
    motion: Callable[[float, np.ndarray], np.ndarray] | None = None,
) -> tuple[float, np.ndarray, float]:
    """A unicycle under the monitor: 10 Hz scans (1 cm range noise, seeded), a 20 Hz command held between ticks and
    applied 10 ms late, speed and yaw rate moving towards it at no more than ``decel_mps2`` and 4 rad/s², 5 ms
    steps. With ``motion`` ((time, (M, 2) world points) → their (M, 2) world velocities) the monitor also gets
    each scan point's exact velocity. Returns (smallest clearance between the footprint and the world, final pose,
    final speed)."""
    rng = np.random.default_rng(7)
    h = 0.005
    x, y, th = pose
    u = w = 0.0
    target, pending = (0.0, 0.0), (math.inf, (0.0, 0.0))
    points = np.zeros((0, 2))
    velocities = None
    smallest = math.inf
    for i in range(round(t_end_s / h)):
        t = i * h
        segs = world(t)
        if i % 20 == 0:
            points = scan_points(segs, (x, y, th), rng, 0.01)
            if motion is not None:
                c, s = math.cos(th), math.sin(th)
                rot = np.array([[c, s], [-s, c]])  # base → world, row vectors
                velocities = motion(t, points @ rot + (x, y)) @ rot.T
        if i % 10 == 0:
            r = monitor.check(*command, points, velocities)
            pending = (t + 0.01, (r.v_mps, r.omega_radps))
        if pending[0] <= t + 1e-12:
            target, pending = pending[1], (math.inf, pending[1])
        u += float(np.clip(target[0] - u, -decel_mps2 * h, decel_mps2 * h))
        w += float(np.clip(target[1] - w, -4.0 * h, 4.0 * h))
        x, y, th = x + u * math.cos(th) * h, y + u * math.sin(th) * h, th + w * h
        c, s = math.cos(th), math.sin(th)
        smallest = min(smallest, _clearance(footprint @ np.array([[c, s], [-s, c]]) + (x, y), segs))
    return smallest, np.array([x, y, th]), u


def _wall_world(x: float) -> Callable[[float], np.ndarray]:
    segs = np.array([[x, -20.0, x, 20.0]])
    return lambda t: segs


@pytest.mark.parametrize("decel", [1.0, 1.5])
@pytest.mark.parametrize("heading_deg", [0.0, 30.0, 60.0])
def test_full_speed_toward_a_wall_stops_at_least_5_cm_from_it(decel: float, heading_deg: float) -> None:
    """Teleop at 0.5 m/s toward a wall 1 m ahead, head-on and at an angle (from the wall's normal): the diffbot
    stops, at least 0.05 m from the wall and not far from it."""
    th = math.radians(heading_deg)
    monitor = CollisionMonitor.for_footprint(DIFFBOT)
    t_end = 1.0 / (0.5 * math.cos(th)) + 4.0
    smallest, _, speed = _drive(_wall_world(1.2), (0.0, 0.0, th), (0.5, 0.0), monitor, DIFFBOT, t_end, decel)
    assert speed == 0.0
    assert 0.05 <= smallest <= 0.15


@pytest.mark.parametrize("footprint", [DIFFBOT, RECT], ids=["diffbot", "rectangle"])
def test_reversing_at_full_speed_toward_a_wall_stops_clear(footprint: np.ndarray) -> None:
    monitor = CollisionMonitor.for_footprint(footprint)
    smallest, _, speed = _drive(_wall_world(-1.5), (0.0, 0.0, 0.0), (-0.5, 0.0), monitor, footprint, 6.0)
    assert speed == 0.0 and 0.05 <= smallest <= 0.15


@pytest.mark.parametrize("start_y", [-0.4, -0.6, -0.8])
def test_a_box_crossing_the_path_is_waited_for_and_the_robot_goes_on(start_y: float) -> None:
    """A 10 cm box crossing 1.5 m ahead at 0.3 m/s, in the robot's way as it arrives: the robot stays clear of it,
    and drives on once it has passed (the monitor limits the command; it does not latch). A box that arrives as the
    robot is passing (start_y = -1.0 to -1.2 here) runs into the robot's side: a monitor that can only slow or stop
    the command does not prevent that."""

    def world(t: float) -> np.ndarray:
        cx, cy = 1.5, start_y + 0.3 * t
        c = [(cx - 0.05, cy - 0.05), (cx + 0.05, cy - 0.05), (cx + 0.05, cy + 0.05), (cx - 0.05, cy + 0.05)]
        return np.array([[*c[i], *c[(i + 1) % 4]] for i in range(4)])

    monitor = CollisionMonitor.for_footprint(DIFFBOT)
    smallest, pose, speed = _drive(world, (0.0, 0.0, 0.0), (0.5, 0.0), monitor, DIFFBOT, 8.0)
    assert smallest >= 0.05
    assert pose[0] > 2.5 and speed == pytest.approx(0.5)


#: The crossing cart of the warehouse world: 1.0 m along the robot's way, 0.7 m across it, at its peak speed.
BOX_ALONG_M, BOX_ACROSS_M, BOX_SPEED_MPS = 1.0, 0.7, 0.79
#: The lane's near edge on the robot's way (x), and when the robot's front gets there at 0.5 m/s from rest at x = 0
#: (1 m/s² to full speed: 0.25 s lost), unimpeded.
LANE_X, DIFFBOT_RADIUS = 2.5, 0.19
ROBOT_AT_LANE_S = 0.25 + (LANE_X - DIFFBOT_RADIUS) / 0.5


def _crossing_box(
    arrival_s: float, side: int = 1
) -> tuple[Callable[[float], np.ndarray], Callable[[float, np.ndarray], np.ndarray]]:
    """The box sliding across the robot's way (the line y = 0) at BOX_SPEED_MPS, over the lane x in [LANE_X, LANE_X +
    BOX_ALONG_M], coming from the left (side 1, moving -y) or the right (side -1), its leading face reaching the
    diffbot's side (|y| = 0.19 m) at ``arrival_s``: the world's segments at time t, and (t, points) → velocities
    (the box's for points on its outline, else 0)."""

    def span(t: float) -> tuple[float, float]:
        lead = DIFFBOT_RADIUS + BOX_SPEED_MPS * (arrival_s - t)  # the leading face's distance from the way
        a, b = side * lead, side * (lead + BOX_ACROSS_M)
        return min(a, b), max(a, b)

    def world(t: float) -> np.ndarray:
        lo, hi = span(t)
        c = [(LANE_X, lo), (LANE_X + BOX_ALONG_M, lo), (LANE_X + BOX_ALONG_M, hi), (LANE_X, hi)]
        return np.array([[*c[i], *c[(i + 1) % 4]] for i in range(4)])

    def motion(t: float, p: np.ndarray) -> np.ndarray:
        lo, hi = span(t)
        on = (np.abs(p[:, 0] - (LANE_X + 0.5 * BOX_ALONG_M)) <= 0.5 * BOX_ALONG_M + 0.01) & (
            (p[:, 1] >= lo - 0.01) & (p[:, 1] <= hi + 0.01)
        )
        u = np.zeros_like(p)
        u[on, 1] = -side * BOX_SPEED_MPS
        return u

    return world, motion


def _cross(lead_s: float, side: int = 1, velocities: bool = True) -> tuple[float, np.ndarray, float, float]:
    """Teleop at 0.5 m/s along y = 0 across the box's lane, the box reaching the robot's way ``lead_s`` after the
    robot reaches its lane (negative: before). Returns the loop's (clearance, final pose, final speed) and where the
    robot would have ended unimpeded (x, m)."""
    arrival = ROBOT_AT_LANE_S + lead_s
    t_end = max(arrival, ROBOT_AT_LANE_S) + 5.5  # the box passes in 1.4 s; the robot then crosses in 3.4 s at most
    world, motion = _crossing_box(arrival, side)
    monitor = CollisionMonitor.for_footprint(DIFFBOT)
    smallest, pose, speed = _drive(
        world, (0.0, 0.0, 0.0), (0.5, 0.0), monitor, DIFFBOT, t_end, motion=motion if velocities else None
    )
    return smallest, pose, speed, 0.125 + 0.5 * (t_end - 0.5 - 0.01)  # the first command acts 10 ms late


@pytest.mark.parametrize(
    ("lead_s", "side"),
    [(1.0, 1), (1.0, -1), (0.0, 1), (-1.0, 1), (2.5, 1), (2.875, 1)],
    ids=[
        "robot-1s-first",
        "robot-1s-first-from-right",
        "together",
        "box-1s-first",
        "robot-2.5s-first",
        "robot-2.875s-first",
    ],
)
def test_full_speed_across_a_crossing_carts_lane_waits_at_its_edge_and_goes_on(lead_s: float, side: int) -> None:
    """The warehouse's cart (1.0 x 0.7 m at 0.79 m/s) crossing the way of the diffbot teleoperated at 0.5 m/s, with
    the velocities of its returns: the robot is held before the lane, at least 0.05 m from the cart, and drives on
    once the cart has passed, past the lane at full speed. Arriving 2.5 s ahead of the cart it would be hit (its
    rear leaves the lane 2.76 s after its front enters it); 2.875 s ahead it would clear it by 0.13 m, within the
    zone's margins and growth, and is held as well (a monitor that sees the cart later, with 3 s ahead, slows it
    into the cart's way)."""
    smallest, pose, speed, free_x = _cross(lead_s, side)
    assert smallest >= 0.05
    assert pose[0] > LANE_X + BOX_ALONG_M + DIFFBOT_RADIUS and speed == pytest.approx(0.5)
    assert pose[0] < free_x - 0.25  # it waited (at least 0.5 s)


def test_a_robot_that_crosses_ahead_of_the_cart_is_not_held() -> None:
    """Arriving 3.5 s ahead of the cart the robot clears its lane 0.7 s before it comes: it drives through at full
    speed, never slowed."""
    smallest, pose, speed, free_x = _cross(3.5)
    assert smallest >= 0.05 and speed == 0.5
    assert pose[0] == pytest.approx(free_x, abs=2e-3)  # one tick at 0.9 of full speed would lose 2.5 mm


@pytest.mark.parametrize("lead_s", [1.0, 0.0])
def test_without_velocities_the_crossing_cart_runs_into_the_robot(lead_s: float) -> None:
    """The same runs with the cart's returns taken as static: the cart hits the robot in its lane (the monitor sees
    the cart only once it is in the robot's way)."""
    smallest, _, _, _ = _cross(lead_s, velocities=False)
    assert smallest == 0.0

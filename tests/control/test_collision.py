"""The last-line collision check: time to collision on the commanded arc, point velocities, the safe command."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import pytest

from mjnav.control.collision import (
    CollisionCheckParams,
    TrackingParams,
    facing_returns,
    free_space_violations,
    point_velocities,
    safe_command,
    scan_points,
    time_to_collision,
    track_scan,
)
from tests.estimation._scans import ROOM, raycast

P = CollisionCheckParams(
    robot_radius_m=0.2,
    margin_m=0.0,
    static_horizon_s=0.6,
    moving_horizon_s=4.0,
    step_s=0.05,
    uncertainty_growth_mps=0.0,
)


def _wall(x: float) -> np.ndarray:
    """A wall across the robot's way at x, from y = -1 to 1 (5 cm spacing)."""
    y = np.linspace(-1.0, 1.0, 41)
    return np.column_stack((np.full_like(y, x), y))


def test_time_to_collision_hand_worked() -> None:
    # A point 2.03 m ahead closing at 0.5 m/s while the robot drives at 0.5 m/s: contact (0.2 m) after 1.83 s,
    # first seen on the 0.05 s grid at 1.85 s.
    ttc = time_to_collision(0.5, 0.0, [[2.03, 0.0]], [[-0.5, 0.0]], P)
    assert ttc == pytest.approx(1.85)
    # With the clearance growing 0.1 m per second of prediction: 2.03 − t < 0.2 + 0.1 t from t = 1.664 s (1.7).
    grown = dataclasses.replace(P, uncertainty_growth_mps=0.1)
    assert time_to_collision(0.5, 0.0, [[2.03, 0.0]], [[-0.5, 0.0]], grown) == pytest.approx(1.7)
    # The same point static is 1.83 m of driving away: beyond the 0.6 s static horizon.
    assert math.isinf(time_to_collision(0.5, 0.0, [[2.03, 0.0]], [[0.0, 0.0]], P))
    # A static point 0.42 m ahead is reached after 0.44 s (0.45 on the grid); on a sharp left arc the robot turns
    # away from it.
    assert time_to_collision(0.5, 0.0, [[0.42, 0.0]], [[0.0, 0.0]], P) == pytest.approx(0.45)
    assert math.isinf(time_to_collision(0.5, 2.5, [[0.45, -0.3]], [[0.0, 0.0]], P))
    # Already touching: 0.
    assert time_to_collision(0.0, 0.0, [[0.1, 0.0]], [[0.0, 0.0]], P) == 0.0


def test_point_velocities_from_two_scans() -> None:
    prev = _wall(2.0)
    rng = np.random.default_rng(0)
    moved = prev + np.array([-0.06, 0.0]) + rng.normal(0.0, 0.003, prev.shape)
    vel = point_velocities(moved, prev, 0.1, 0.25)
    assert np.allclose(vel[:, 0], -0.6, atol=0.1) and np.allclose(vel[:, 1], 0.0, atol=0.1)
    # Noise alone (and motion along the wall: the aperture problem) reads as static.
    still = prev + rng.normal(0.0, 0.003, prev.shape) + np.array([0.0, 0.01])
    assert not point_velocities(still, prev, 0.1, 0.25).any()
    assert not point_velocities(moved, np.zeros((0, 2)), 0.1, 0.25).any()


def test_safe_command_brakes_for_a_wall_and_lets_a_free_command_through() -> None:
    assert safe_command(0.5, 0.1, _wall(3.0), np.zeros((41, 2)), P) == (0.5, 0.1, math.inf)
    # 0.25 m from the robot's edge: the fastest speed that does not reach the wall within the 0.6 s horizon.
    v, w, ttc = safe_command(0.5, 0.0, _wall(0.45), np.zeros((41, 2)), P)
    assert (v, w) == (0.375, 0.0) and math.isinf(ttc)
    # 2 cm from it: stop.
    v, w, ttc = safe_command(0.5, 0.3, _wall(0.22), np.zeros((41, 2)), P)
    assert (v, w) == (0.0, 0.0) and math.isinf(ttc)


def test_safe_command_never_drives_on_into_an_obstacle_it_is_already_too_close_to() -> None:
    """The table-corner case: the robot grazes a corner ahead on its right, inside radius + margin, while turning
    towards it. Every candidate 'collides' at once; only one that moves and does not approach may go: here backing
    straight out (a stop would stay stuck there for good); with a wall right behind too, nothing moves."""
    from mjnav.control.collision import _closest_approach

    corner = np.array([[0.1, -0.17], [0.15, -0.15], [0.2, -0.12], [0.05, -0.19]])  # ahead right, within 0.2 m
    still = np.zeros_like(corner)
    assert time_to_collision(0.25, -0.75, corner, still, P) == 0.0
    assert _closest_approach(0.25, -0.75, corner, still, P) < _closest_approach(0.0, 0.0, corner, still, P)
    v, w, ttc = safe_command(0.25, -0.75, corner, still, P)
    assert (v, w, ttc) == (-0.5 * P.max_speed_mps, 0.0, 0.0)
    boxed = np.vstack((corner, [[-0.3, 0.0], [-0.3, 0.1], [-0.3, -0.1]]))  # and a wall 0.3 m behind
    v, w, ttc = safe_command(0.25, -0.75, boxed, np.zeros_like(boxed), P)
    assert (v, w, ttc) == (0.0, 0.0, 0.0)
    # A wall close along the right side, behind the robot's centre: driving on, turning left, moves away: allowed.
    side = np.array([[-0.05, -0.19], [-0.1, -0.2], [-0.15, -0.21], [0.0, -0.2]])
    v, w, ttc = safe_command(0.25, 0.75, side, np.zeros_like(side), P)
    assert (v, w, ttc) == (0.25, 0.75, 0.0)


def test_safe_command_waits_for_a_crossing_obstacle_or_clears_its_way() -> None:
    # A cart's face 1 m wide (x from 0.5 to 1.5) at y = 1.5, coming down at 0.8 m/s across the robot's way.
    face = np.column_stack((np.linspace(0.5, 1.5, 21), np.full(21, 1.5)))
    down = np.tile([0.0, -0.8], (21, 1))
    assert math.isfinite(time_to_collision(0.5, 0.0, face, down, P))
    v, _, ttc = safe_command(0.5, 0.0, face, down, P)
    assert 0.0 <= v < 0.5 and math.isinf(ttc)  # slow down (or wait): the cart passes in front of the robot
    # The robot already stands in the cart's lane: stopping would be hit; backing out (or clearing) is not.
    lane = np.column_stack((np.linspace(-0.5, 0.5, 21), np.full(21, 1.5)))
    v, _, ttc = safe_command(0.2, 0.0, lane, down, P)
    assert v != 0.0 and math.isinf(ttc)
    assert math.isfinite(time_to_collision(0.0, 0.0, lane, down, P))


def test_scan_points_keep_valid_returns_only() -> None:
    pts = scan_points([0.0, math.pi / 2, 0.1, 0.2], [1.0, 2.0, math.inf, 0.05], 0.12, 12.0)
    np.testing.assert_allclose(pts, [[1.0, 0.0], [0.0, 2.0]], atol=1e-12)


def test_params_are_checked() -> None:
    with pytest.raises(ValueError):
        CollisionCheckParams(robot_radius_m=0.0)
    with pytest.raises(ValueError):
        CollisionCheckParams(robot_radius_m=0.2, static_horizon_s=2.0, moving_horizon_s=1.0)


def test_free_space_violations_tell_an_approaching_face_from_a_revealed_wall() -> None:
    # The previous scan, from (1, 0) facing +y, saw a wall 2 m away all round, and nothing at all straight behind.
    n = 360
    ranges = np.full(n, 2.0)
    angles = -math.pi + 2 * math.pi / n * np.arange(n)
    ranges[np.argmin(np.abs(angles - math.pi / 2))] = math.inf  # no return towards -x in the world (beam +90°)
    pose = (1.0, 0.0, math.pi / 2)
    points = np.array([[1.0, 1.5], [1.0, 2.5], [1.0, 2.02], [-0.5, 0.0], [3.5, 0.0], [-2.0, 0.0]])
    got = free_space_violations(points, pose, -math.pi, 2 * math.pi / n, ranges)
    # nearer than the return: violates; behind it, or within the tolerance: does not; where the previous beam saw
    # no return, anything violates.
    assert got.tolist() == [True, False, False, True, False, True]
    # Velocities only where free space was violated.
    vel = point_velocities(points, points - [0.0, -0.1], 0.1, 0.25, neighbours=1, can_move=got)
    assert (vel[:, 1] != 0).tolist() == got.tolist()


def test_grazing_and_edge_returns_do_not_count_as_facing() -> None:
    # A wall at x = 1 seen from the origin: facing near the axis, grazing far along it; an isolated return is an edge.
    y = np.linspace(-6.0, 6.0, 121)
    wall = np.column_stack((np.full_like(y, 1.0), y))
    facing = facing_returns(np.vstack((wall, [[5.0, 0.0]])), max_gap_m=0.3, min_incidence_rad=0.35)
    assert facing[60] and not facing[0] and not facing[-1]  # the ends have one neighbour only
    assert not facing[5]  # at y = -5.5 the beam meets the wall at about 10°
    assert not facing[-1]


def _on_room_walls(points: np.ndarray) -> np.ndarray:
    """The map's walls, as a service passes them (``static``): the room's outer walls, not what stands inside."""
    x, y = points[:, 0], points[:, 1]
    return (x < 0.1) | (x > 9.9) | (y < 0.1) | (y > 5.9)


def _cart(cy: float) -> np.ndarray:
    """A 1.0 m × 0.7 m cart's outline centred at (4.5, cy), as wall segments."""
    x0, x1, y0, y1 = 4.0, 5.0, cy - 0.35, cy + 0.35
    return np.array([(x0, y0, x1, y0), (x1, y0, x1, y1), (x1, y1, x0, y1), (x0, y1, x0, y0)])


def _track_crossing_cart(
    seed: int, scans: int, pose_at: Callable[[float], tuple[float, float, float]], speed_mps: float, atol: float
) -> None:
    """Track a cart crossing the room southwards at ``speed_mps`` (its centre from y = 5.2) past a robot at
    ``pose_at(t)``: no wall return moves; from the third scan on at least 90 % of the cart's returns move, at its
    velocity (within ``atol`` m/s)."""
    rng = np.random.default_rng(seed)
    previous = None
    for k in range(scans):
        t = 0.1 * k
        cy = 5.2 - speed_mps * t
        pose = pose_at(t)
        angles, ranges = raycast(np.concatenate([ROOM[:4], _cart(cy)]), pose, 360, 2 * math.pi, 12.0)
        ranges = ranges + rng.normal(0.0, 0.01, ranges.shape)
        tracked = track_scan(
            t, pose, float(angles[0]), float(angles[1] - angles[0]), ranges, 0.05, 12.0, previous,
            TrackingParams(), static=_on_room_walls,
        )  # fmt: skip
        previous = tracked
        p = tracked.points
        on_cart = (p[:, 0] > 3.95) & (p[:, 0] < 5.05) & (np.abs(p[:, 1] - cy) < 0.4)
        moving = tracked.moving()
        assert not moving[~on_cart].any(), (t, p[~on_cart & moving])
        if k >= 3 and on_cart.sum() >= 5:
            assert moving[on_cart].sum() >= 0.9 * on_cart.sum(), (t, cy, p[on_cart & ~moving])
            velocity = tracked.velocities[on_cart & moving]
            np.testing.assert_allclose(
                velocity, np.tile([0.0, -speed_mps], (len(velocity), 1)), atol=atol, err_msg=f"t = {t}"
            )


@pytest.mark.parametrize("seed", [0, 1])
def test_a_crossing_cart_moves_as_a_whole_and_the_walls_stand_still(seed: int) -> None:
    """A cart crosses the view of a robot driving along at 0.3 m/s: at first only its leading face shows motion
    (its side slides along itself), later only its side and its receding back face are in view. Every return
    of the cart (but for a few edge-on fragments, 10 % at most) moves, at its velocity, from the third scan on."""
    _track_crossing_cart(seed, 90, lambda t: (1.0 + 0.3 * t, 2.5, 0.0), 0.5, atol=0.15)


def test_static_objects_seen_while_driving_do_not_move() -> None:
    """Two scans alone see apparent motion on surfaces seen at a slant (the previous beam nearest in angle ended
    elsewhere on them); an object of a few such returns among many must not move, nor a large one carry a
    velocity along itself. The room's inner box and alcove walls are not in the map (``static``)."""
    rng = np.random.default_rng(3)
    previous = None
    for k in range(40):
        pose = (1.0 + 0.05 * k, 1.0 + 0.03 * k, 0.02 * k)
        angles, ranges = raycast(ROOM, pose, 360, 2 * math.pi, 12.0)
        ranges = ranges + rng.normal(0.0, 0.01, ranges.shape)
        previous = track_scan(
            0.1 * k, pose, float(angles[0]), float(angles[1] - angles[0]), ranges, 0.05, 12.0, previous,
            TrackingParams(), static=_on_room_walls,
        )  # fmt: skip
        assert not previous.moving().any(), (k, previous.points[previous.moving()])


@pytest.mark.e2e
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_cart_passing_close_in_front_keeps_moving(seed: int) -> None:
    """A cart passes 0.55 m in front of a robot waiting at the edge of its lane (the warehouse's cross aisle):
    near the robot the beams are about as far apart (1° at 0.55 m: 1 cm) as the lidar's noise (1 cm), so a
    surface normal from adjacent returns is noise, and the side sliding along itself must not be read as a
    surface that stopped. Every return of the cart (but for a few edge-on fragments) moves at its velocity from
    the third scan on, and none of the walls does."""
    _track_crossing_cart(seed, 60, lambda t: (3.45, 2.5, 0.0), 0.75, atol=0.2)  # its near side passes at x = 4.0

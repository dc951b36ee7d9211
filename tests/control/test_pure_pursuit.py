"""Regulated pure pursuit: single steps on hand-worked geometry and the closed-loop acceptance run."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.control import PathError, PurePursuit, PurePursuitParams
from mjnav.geometry import Pose2D
from tests.control.sim import dense_reference, run, s_curve, start_pose_off_path

STRAIGHT = np.c_[np.linspace(0.0, 10.0, 101), np.zeros(101)]


def test_on_path_goes_straight_at_desired_speed() -> None:
    pp = PurePursuit()
    v, w = pp.compute((1.0, 0.0, 0.0), 0.5, STRAIGHT)
    assert (v, w) == pytest.approx((0.5, 0.0))
    assert pp.status.mode == "tracking"
    assert pp.status.lookahead_point == pytest.approx((1.5, 0.0))


def test_offset_hand_worked_step() -> None:
    # robot 0.3 m left of the x-axis path, speed 0.5 -> L = 0.5: the circle meets the path at x' = 0.4,
    # y' = -0.3, so κ = 2(-0.3)/0.5² = -2.4 > κ_h = 1: v = 0.5/2.4, ω = κ v = -0.5
    pp = PurePursuit()
    v, w = pp.compute((0.0, 0.3, 0.0), 0.5, STRAIGHT)
    assert v == pytest.approx(0.5 / 2.4)
    assert w == pytest.approx(-0.5)
    st = pp.status
    assert st.curvature_invm == pytest.approx(-2.4)
    assert st.lookahead_point == pytest.approx((0.4, 0.0))
    assert st.cross_track_m == pytest.approx(0.3)
    # mirrored: right of the path turns left with the same magnitude
    v2, w2 = PurePursuit().compute(Pose2D(0.0, -0.3, 0.0), 0.5, STRAIGHT)
    assert (v2, w2) == pytest.approx((v, 0.5))


def test_proximity_and_target_speed() -> None:
    pp = PurePursuit()
    assert pp.compute((1.0, 0.0, 0.0), 0.5, STRAIGHT, 0.35)[0] == pytest.approx(0.25)
    assert pp.compute((1.0, 0.0, 0.0), 0.5, STRAIGHT, target_speed_mps=0.3)[0] == pytest.approx(0.3)


def test_rotates_in_place_when_facing_away() -> None:
    pp = PurePursuit()
    v, w = pp.compute((1.0, 0.0, math.pi - 0.2), 0.0, STRAIGHT)  # lookahead point behind-left... turn
    assert v == 0.0
    assert w == pytest.approx(-1.0)  # bearing ≈ -(π - 0.2): clamp(2 α) = -1
    assert pp.status.mode == "rotating"


def test_slows_down_and_stops_at_the_goal() -> None:
    pp = PurePursuit()
    v_far, _ = pp.compute((9.0, 0.0, 0.0), 0.5, STRAIGHT)
    v_near, _ = pp.compute((9.7, 0.0, 0.0), 0.5, STRAIGHT)
    assert v_far == pytest.approx(0.5)
    assert v_near == pytest.approx(0.5 * 0.3 / 0.6)
    assert not pp.goal_reached
    assert pp.compute((9.95, 0.02, 0.0), 0.1, STRAIGHT) == (0.0, 0.0)
    assert pp.goal_reached and pp.status.mode == "reached"
    assert pp.compute((9.0, 0.0, 0.0), 0.5, STRAIGHT) == (0.0, 0.0)  # latched
    pp.reset()
    assert not pp.goal_reached
    assert pp.compute((9.0, 0.0, 0.0), 0.5, STRAIGHT)[0] > 0.0


def test_goal_near_start_of_a_loop_is_not_reached_early() -> None:
    a = np.linspace(0.0, 2 * math.pi - 0.05, 200)
    loop = np.c_[np.cos(a), np.sin(a)] * 2.0
    pp = PurePursuit()
    pp.compute((2.0, 0.0, math.pi / 2), 0.5, loop)
    assert not pp.goal_reached  # the end is 0.1 m away but the remaining path is ~12 m


def test_forward_search_does_not_jump_back_on_a_hairpin() -> None:
    # out along y = 0 and back along y = 0.3: the robot on the return leg must not snap to the out leg
    out = np.c_[np.linspace(0.0, 5.0, 51), np.zeros(51)]
    back = np.c_[np.linspace(5.0, 0.0, 51), np.full(51, 0.3)]
    hairpin = np.r_[out, [[5.15, 0.15]], back]
    pp = PurePursuit()
    pp.compute((0.5, 0.0, 0.0), 0.5, hairpin)
    for x in np.linspace(0.6, 4.9, 40):  # drive along the out leg
        pp.compute((x, 0.0, 0.0), 0.5, hairpin)
    for x in np.linspace(5.1, 2.0, 40):  # and back along the return leg
        pp.compute((x, 0.3, math.pi), 0.5, hairpin)
    assert pp.closest_index > 52
    assert pp.status.cross_track_m == pytest.approx(0.0, abs=1e-9)


def test_a_pose_corrected_backwards_along_the_path_is_found_on_it_again() -> None:
    """Issue 30: SLAM moved the pose 1.2 m back along a corridor; the forward-only search, starting at the segment
    the robot had reached, measured those 1.2 m as an offset from the path, and the controller stopped "off the
    path" on a free route for good."""
    line = np.c_[np.linspace(0.0, 10.0, 101), np.zeros(101)]
    pp = PurePursuit()
    for x in np.linspace(0.0, 5.0, 26):
        pp.compute((x, 0.0, 0.0), 0.5, line)
    assert pp.closest_index >= 49  # the segment ending at x = 5
    pp.compute((3.85, 0.02, 0.0), 0.5, line)
    assert pp.closest_index == 38 and pp.status.cross_track_m == pytest.approx(0.02, abs=1e-9)


def test_same_path_contents_keep_state_new_path_restarts() -> None:
    pp = PurePursuit()
    pp.compute((6.05, 0.0, 0.0), 0.5, STRAIGHT)  # first call: whole-path search
    assert pp.closest_index == 60
    pp.compute((6.05, 0.0, 0.0), 0.5, STRAIGHT.copy())  # equal contents, new object: same state
    assert pp.closest_index == 60
    longer = np.c_[np.linspace(-5.0, 10.0, 151), np.zeros(151)]  # a different path: restart, whole search
    pp.compute((6.05, 0.0, 0.0), 0.5, longer)
    assert pp.closest_index == 110  # a kept index 60 with a 2 m window would stop near 80


def test_acceptance_s_curve_from_0p4_m_off() -> None:
    path = s_curve()
    r = run(PurePursuit(), path, start_pose_off_path(0.4), dense_reference())
    assert r.reached
    assert r.final_goal_distance <= 0.15
    settled = r.times >= 10.0
    assert r.cross_track.max() > 0.3  # it really started off the path
    assert r.cross_track[settled].max() <= 0.10
    assert np.all(r.commands[:, 0] >= 0.0)


def test_acceptance_mirrored_s_curve() -> None:
    path = s_curve(sign=-1.0)
    start = start_pose_off_path(0.4, sign=-1.0)
    r = run(PurePursuit(), path, start, dense_reference(-1.0))
    assert r.reached and r.final_goal_distance <= 0.15
    assert r.cross_track[r.times >= 10.0].max() <= 0.10


def test_bad_input() -> None:
    pp = PurePursuit()
    with pytest.raises(PathError):
        pp.compute((0, 0, 0), 0.5, [[0.0, 0.0]])
    with pytest.raises(PathError):
        pp.compute((0, 0, 0), 0.5, [[0.0, 0.0], [math.nan, 1.0]])
    with pytest.raises(PathError):
        pp.compute((0, 0, 0), 0.5, np.zeros((4, 3)))
    with pytest.raises(ValueError, match="pose"):
        pp.compute((0, math.nan, 0), 0.5, STRAIGHT)
    with pytest.raises(ValueError, match="pose"):
        pp.compute((0, 0), 0.5, STRAIGHT)
    with pytest.raises(ValueError, match="speed"):
        pp.compute((0, 0, 0), math.inf, STRAIGHT)
    with pytest.raises(ValueError, match="max_lookahead_m"):
        PurePursuitParams(min_lookahead_m=2.0, max_lookahead_m=1.0)


def test_repeated_points_are_harmless() -> None:
    dup = np.r_[STRAIGHT[:1], STRAIGHT[:30], STRAIGHT[29:30], STRAIGHT[30:]]  # repeats at the start and middle
    pp = PurePursuit()
    assert pp.compute((2.95, 0.1, 0.0), 0.5, dup) == pytest.approx(
        PurePursuit().compute((2.95, 0.1, 0.0), 0.5, STRAIGHT)
    )
    k = pp.closest_index
    pp.compute((2.95, 0.1, 0.0), 0.5, dup.copy())  # equal contents: state kept
    assert pp.closest_index == k
    with pytest.raises(PathError, match="distinct"):
        PurePursuit().compute((0, 0, 0), 0.5, [[1.0, 1.0], [1.0, 1.0]])


def test_goal_inside_the_lookahead_circle_steers_with_the_actual_distance() -> None:
    # The goal (0.3, 0.2) is 0.36 m away, inside L = 0.5: it is the lookahead point, and κ = 2y'/d² uses its
    # actual distance d (2·0.2/0.13 ≈ 3.08), not the nominal L (2·0.2/0.25 = 1.6), or the robot would swing wide.
    pp = PurePursuit(PurePursuitParams(min_lookahead_m=0.5, max_lookahead_m=1.0, rotate_threshold_rad=1.0))
    path = np.array([[-1.0, 0.0], [0.0, 0.0], [0.3, 0.2]])
    pp.compute((0.0, 0.0, 0.0), 0.0, path)
    status = pp.status
    assert status.lookahead_point == pytest.approx((0.3, 0.2))
    assert status.lookahead_m == pytest.approx(math.hypot(0.3, 0.2))
    assert status.curvature_invm == pytest.approx(2 * 0.2 / (0.3**2 + 0.2**2))


def _chord_distance(start: tuple[float, float], end: tuple[float, float], points: np.ndarray) -> float:
    """Smallest distance from ``points`` to the segment start → end."""
    a, seg = np.asarray(start), np.asarray(end) - np.asarray(start)
    t = np.clip((points - a) @ seg / (seg @ seg), 0.0, 1.0)
    return float(np.min(np.hypot(*(points - a - t[:, None] * seg).T)))


def test_lookahead_shortens_until_its_chord_clears_the_obstacles() -> None:
    """Around a wall corner the chord to a long lookahead point cuts the corner; with the scan's points the
    lookahead shrinks until the chord keeps the clearance."""
    # An L path: along x to (1, 0), then up along y; the wall's corner sits just inside the bend at (0.8, 0.25).
    path = np.array([[x, 0.0] for x in np.arange(0.0, 1.0, 0.05)] + [[1.0, y] for y in np.arange(0.0, 2.0, 0.05)])
    corner = np.array([[0.8, 0.25], [0.75, 0.25], [0.8, 0.3]])
    params = PurePursuitParams(min_lookahead_m=0.3, max_lookahead_m=1.0, lookahead_gain_s=2.0)
    pose = (0.5, 0.0, 0.0)
    free = PurePursuit(params)
    free.compute(pose, 0.5, path)
    assert free.status.lookahead_m == pytest.approx(1.0, abs=0.01)
    assert _chord_distance((0.5, 0.0), free.status.lookahead_point, corner) < 0.2  # it cuts the corner
    pp = PurePursuit(params)
    pp.compute(pose, 0.5, path, obstacles_xy=corner, chord_clearance_m=0.2)
    assert pp.status.lookahead_m < 0.75
    assert _chord_distance((0.5, 0.0), pp.status.lookahead_point, corner) >= 0.2
    # obstacles far from every chord change nothing
    far = PurePursuit(params)
    far.compute(pose, 0.5, path, obstacles_xy=np.array([[5.0, 5.0]]), chord_clearance_m=0.2)
    assert far.status.lookahead_point == pytest.approx(free.status.lookahead_point)

"""Service logic stepped by hand (no processes): the planner's goal bookkeeping and replanning policy, the
smoother's clearance box, the controller's goal states. Each service runs on a real in-process Zenoh bus."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from mjnav.bus import Bus, NoReply, RemoteError, wait_until
from mjnav.geometry import Pose2D
from mjnav.mapping import CellState
from mjnav.msgs import msg_class, ros
from mjnav.services.controller import ControllerService
from mjnav.services.mapper import MapperService
from mjnav.services.planner import PlannerService
from mjnav.services.smoother import SmootherService
from tests.services.harness import Harness

STATUS = msg_class("mjnav_msgs/msg/GoalStatus")
FEEDBACK = msg_class("mjnav_msgs/msg/ControllerFeedback")
RES = 0.1  # costmap resolution, metres; origin (0, 0); 40 x 40 cells
Peer = Callable[..., Bus]


def _costmap(t: float, cells: np.ndarray) -> object:
    return ros.occupancy_grid(t, "map", cells, RES, (0.0, 0.0))


def _free() -> np.ndarray:
    return np.zeros((40, 40), dtype=np.int8)


def _status(t: float, goal_id: int, state: int) -> object:
    goal = ros.pose_stamped(t, "map", Pose2D(0.0, 0.0, 0.0))
    return STATUS(header=ros.header(t, "map"), goal_id=goal_id, state=state, error_code=0, error_text="", goal=goal)


def _clear_scan(t: float) -> object:
    """A 360° scan with no return (open space all round)."""
    n = 90
    return ros.laser_scan(
        t, "laser", angle_min_rad=-math.pi, angle_increment_rad=2 * math.pi / n, scan_time_s=0.1,
        range_min_m=0.05, range_max_m=12.0, ranges_m=np.full(n, np.inf),
    )  # fmt: skip


def _scanning(h: Harness) -> Callable[..., None]:
    """``h.step`` with a fresh clear scan before each step (the controller does not move without one)."""

    def step(t: float, expect: dict[str, int] | None = None) -> None:
        h.send("scan", _clear_scan(t))
        h.step(t, expect)

    return step


def _feedback(t: float, goal_id: int, state: int, text: str = "") -> object:
    return FEEDBACK(header=ros.header(t, "map"), goal_id=goal_id, state=state, distance_remaining_m=-1.0, text=text)


def _reports(h: Harness) -> list[tuple[int, int]]:
    """(goal id, state) of every controller_feedback received so far."""
    return [(f.goal_id, f.state) for f in h.received["controller_feedback"]]


def _states(h: Harness) -> list[tuple[int, int, int]]:
    """(goal id, state, error code) of every goal_status received so far."""
    return [(s.goal_id, s.state, s.error_code) for s in h.received["goal_status"]]


def _plan_cells(h: Harness) -> np.ndarray:
    """The newest plan, as (row, col) cells."""
    pts = ros.path_points(h.received["plan"][-1])
    return np.floor(pts[:, ::-1] / RES).astype(int)


@pytest.fixture
def planner(peer: Peer) -> Harness:
    """Planner on a free 4 x 4 m costmap, robot at (0.55, 2.05)."""
    h = Harness(PlannerService, peer, ("goal_status", "plan"), pose_source="ground_truth", replan_period_s=2.0)
    h.send("costmap", _costmap(0.0, _free()))
    h.send("ground_truth", ros.pose_stamped(0.0, "map", Pose2D(0.55, 2.05, 0.0)))
    return h


@pytest.mark.e2e
def test_planner_accepts_plans_and_supersedes_goals(planner: Harness) -> None:
    planner.send("goal", ros.pose_stamped(0.0, "map", Pose2D(3.45, 2.05, 0.0)))
    planner.step(0.0, {"goal_status": 3, "plan": 1})
    assert _states(planner) == [
        (1, STATUS.STATE_ACCEPTED, 0),
        (1, STATUS.STATE_PLANNING, 0),
        (1, STATUS.STATE_FOLLOWING, 0),
    ]
    cells = _plan_cells(planner)
    assert tuple(cells[0]) == (20, 5) and tuple(cells[-1]) == (20, 34)
    assert np.all(cells[:, 0] == 20)  # straight along the free row
    # A second goal ends the first one (canceled, superseded) and gets the next id.
    planner.send("goal", ros.pose_stamped(0.1, "map", Pose2D(0.55, 3.45, 0.0)))
    planner.step(0.2, {"goal_status": 7, "plan": 3})
    assert _states(planner)[3:] == [
        (1, STATUS.STATE_CANCELED, 0),
        (2, STATUS.STATE_ACCEPTED, 0),
        (2, STATUS.STATE_PLANNING, 0),
        (2, STATUS.STATE_FOLLOWING, 0),
    ]
    assert "superseded by goal 2" in planner.received["goal_status"][3].error_text
    assert len(planner.received["plan"][1].poses) == 0  # the canceled goal's plan is withdrawn
    # Cancel ends the current goal; a later step publishes nothing more for it.
    planner.send("cancel", msg_class("std_msgs/msg/Empty")())
    planner.step(0.4, {"goal_status": 8, "plan": 4})
    assert _states(planner)[-1] == (2, STATUS.STATE_CANCELED, 0)
    assert planner.service.goal is None


def test_planner_refuses_goals_it_cannot_serve(planner: Harness) -> None:
    walls = _free()
    walls[10:30, 25] = 100  # a closed box around the goal (3.0, 2.0)
    walls[10:30, 35] = 100
    walls[10, 25:36] = 100
    walls[29, 25:36] = 100
    planner.send("costmap", _costmap(0.1, walls))
    cases = [
        (Pose2D(3.05, 2.05, 0.0), "map", STATUS.ERROR_NO_PATH),
        (Pose2D(2.55, 2.05, 0.0), "map", STATUS.ERROR_GOAL_OCCUPIED),
        (Pose2D(20.0, 2.0, 0.0), "map", STATUS.ERROR_OUTSIDE_MAP),  # 16 m beyond the 4 x 4 m costmap
        (Pose2D(1.0, 1.0, 0.0), "odom", STATUS.ERROR_INVALID_GOAL),
    ]
    for i, ((pose, frame, error), total) in enumerate(zip(cases, (3, 6, 9, 11), strict=True)):
        planner.send("goal", ros.pose_stamped(0.2, frame, pose))
        planner.step(0.2 + i, {"goal_status": total})  # accepted (planning) failed
        last = planner.received["goal_status"]
        assert planner.service.goal is None
        assert (last[-1].goal_id, last[-1].state, last[-1].error_code) == (i + 1, STATUS.STATE_FAILED, error)
        if error == STATUS.ERROR_NO_PATH:  # metres first, the planner's cells in parentheses
            assert "m to (3.05, 2.05) m (cells" in last[-1].error_text, last[-1].error_text


@pytest.mark.e2e
def test_planner_replans_when_blocked_and_switches_only_to_a_clearly_cheaper_route(planner: Harness) -> None:
    # A wall with a gap at the top forces a detour.
    detour = _free()
    detour[0:35, 20] = 100
    planner.send("costmap", _costmap(0.1, detour))
    planner.send("goal", ros.pose_stamped(0.1, "map", Pose2D(3.45, 2.05, 0.0)))
    planner.step(0.2, {"plan": 1})
    first = _plan_cells(planner)
    assert first[:, 0].max() >= 35  # over the wall's end
    # The same map again, before the replan period: nothing new.
    planner.send("costmap", _costmap(0.5, detour))
    planner.step(0.6)
    # The wall opens at the bottom (a much shorter route): taken at the periodic check, not before.
    opened = detour.copy()
    opened[15:25, 20] = 0
    planner.send("costmap", _costmap(1.0, opened))
    planner.step(1.1)
    assert len(planner.received["plan"]) == 1  # the current route is still valid: no switch yet
    planner.send("costmap", _costmap(2.3, opened))
    planner.step(2.3, {"plan": 2})
    assert _plan_cells(planner)[:, 0].max() < 30
    # A costmap that blocks the current route is replanned at once, whatever the period.
    blocked = opened.copy()
    blocked[15:25, 20] = 100
    blocked[0:10, 20] = 0
    planner.send("costmap", _costmap(2.5, blocked))
    planner.step(2.5, {"plan": 3})
    third = _plan_cells(planner)
    assert not np.any(blocked[third[:, 0], third[:, 1]] >= 99)
    # A route only slightly cheaper (less than the 10 % improvement) is not worth a switch.
    planner.send("costmap", _costmap(5.0, blocked))
    planner.step(5.0)
    assert len(planner.received["plan"]) == 3
    # The controller's arrival ends the goal as reached, stamped when the robot arrived, and withdraws the plan.
    goal_id = planner.service.goal.goal_id
    planner.send("controller_feedback", _feedback(5.1, goal_id, FEEDBACK.STATE_ARRIVED))
    planner.step(5.2, {"plan": 4})
    assert planner.service.goal is None and len(planner.received["plan"][-1].poses) == 0
    reached = planner.received["goal_status"][-1]
    assert (reached.goal_id, reached.state, ros.seconds(reached.header.stamp)) == (goal_id, STATUS.STATE_REACHED, 5.1)


@pytest.mark.e2e
def test_smoother_keeps_every_point_inside_its_clearance_box(peer: Peer) -> None:
    h = Harness(SmootherService, peer, ("path",), max_deviation_m=0.3, margin_m=0.03)
    cells = _free()
    cells[22:40, 20] = 100  # an obstacle above a path that zigzags just below it
    cells[21, 19:22] = 99  # its inscribed band
    h.send("costmap", _costmap(0.0, cells))
    xs = np.linspace(0.5, 3.5, 31)
    plan = np.c_[xs, 1.95 + 0.08 * (-1.0) ** np.arange(31)]
    h.send("plan", ros.path_msg(0.0, "map", plan))
    h.step(0.0, {"path": 1})
    out = ros.path_points(h.received["path"][-1])
    pts = h.service.smooth(plan)
    np.testing.assert_allclose(out, pts)
    # Every point moved at most min(max deviation, clearance − margin)/√2 per coordinate from the resampled plan.
    from mjnav.smoothing import resample

    reference = resample(plan, h.service.config.spacing_m)
    allowed = np.minimum(0.3, h.service.allowed_deviation(reference) / math.sqrt(2))
    assert out.shape == reference.shape
    assert np.all(np.abs(out - reference) <= allowed[:, None] + 1e-9)
    # Near the obstacle the box is tighter than the 0.3 m cap, and the smooth path stays out of the inscribed band.
    near = np.abs(reference[:, 0] - 2.05) < 0.2
    assert np.all(allowed[near] < 0.3)
    rows, cols = np.floor(out[:, 1] / RES).astype(int), np.floor(out[:, 0] / RES).astype(int)
    assert np.all(cells[rows, cols] < 99)
    # Without a costmap no point may move at all.
    h.close()  # its costmap is latched: a smoother started later would get it
    bare = Harness(SmootherService, peer, ("path",))
    np.testing.assert_allclose(bare.service.smooth(plan), resample(plan, bare.service.config.spacing_m))


@pytest.mark.e2e
def test_controller_goal_states(peer: Peer) -> None:
    """The controller follows the goal the planner's newest status names and reports to the planner, which owns
    the goal: it never publishes goal_status itself."""
    h = Harness(
        ControllerService, peer, ("cmd_vel", "controller_feedback", "goal_status"), pose_source="ground_truth",
        pose_timeout_s=0.5,
    )  # fmt: skip
    step = _scanning(h)
    line = np.c_[np.linspace(0.0, 3.0, 31), np.zeros(31)]
    # No goal: zero command, no report.
    h.send("ground_truth", ros.pose_stamped(0.0, "map", Pose2D(0.0, 0.0, 0.0)))
    step(0.0, {"cmd_vel": 1})
    assert h.received["cmd_vel"][-1].linear.x == 0.0 and not h.received["controller_feedback"]
    # Following goal 1 with its path: drives, and says so once.
    h.send("goal_status", _status(1.0, 1, STATUS.STATE_FOLLOWING))
    h.send("path", ros.path_msg(1.0, "map", line))
    h.send("ground_truth", ros.pose_stamped(1.0, "map", Pose2D(0.0, 0.0, 0.0)))
    step(1.0, {"cmd_vel": 2, "controller_feedback": 1})
    assert h.received["cmd_vel"][-1].linear.x > 0.0
    assert _reports(h) == [(1, FEEDBACK.STATE_FOLLOWING)]
    # A pose older than pose_timeout_s: stop, and tell the planner why.
    step(1.6, {"cmd_vel": 3, "controller_feedback": 2})
    assert h.received["cmd_vel"][-1].linear.x == 0.0
    halted = h.received["controller_feedback"][-1]
    assert (halted.state, halted.text) == (FEEDBACK.STATE_HALTED, "no recent pose")
    # An old path is still the goal's path (nobody re-sends it): with a fresh pose the robot drives on.
    h.send("ground_truth", ros.pose_stamped(4.1, "map", Pose2D(0.5, 0.0, 0.0)))
    step(4.1, {"cmd_vel": 4, "controller_feedback": 3})
    assert h.received["cmd_vel"][-1].linear.x > 0.0 and _reports(h)[-1] == (1, FEEDBACK.STATE_FOLLOWING)
    # Driving on to the goal: stop there and report the arrival, once.
    for i, x in enumerate((1.0, 1.5, 2.0, 2.5)):
        h.send("ground_truth", ros.pose_stamped(4.21 + 0.01 * i, "map", Pose2D(x, 0.0, 0.0)))
        step(4.21 + 0.01 * i)
    h.send("ground_truth", ros.pose_stamped(4.3, "map", Pose2D(2.97, 0.0, 0.0)))
    step(4.3, {"cmd_vel": 9, "controller_feedback": 4})
    arrived = h.received["controller_feedback"][-1]
    assert (arrived.goal_id, arrived.state, ros.seconds(arrived.header.stamp)) == (1, FEEDBACK.STATE_ARRIVED, 4.3)
    assert h.received["cmd_vel"][-1].linear.x == 0.0 and h.service.goal is None
    # A late status of the finished goal does not revive it.
    h.send("goal_status", _status(4.35, 1, STATUS.STATE_FOLLOWING))
    h.send("ground_truth", ros.pose_stamped(4.4, "map", Pose2D(1.0, 0.0, 0.0)))
    step(4.4, {"cmd_vel": 10})
    assert h.received["cmd_vel"][-1].linear.x == 0.0 and h.service.goal is None
    # Goal 2 follows; then the planner fails it: the controller stops at once.
    h.send("goal_status", _status(4.5, 2, STATUS.STATE_FOLLOWING))
    h.send("path", ros.path_msg(4.5, "map", line))
    h.send("ground_truth", ros.pose_stamped(4.5, "map", Pose2D(1.0, 0.0, 0.0)))
    step(4.5, {"cmd_vel": 11})
    assert h.received["cmd_vel"][-1].linear.x > 0.0
    h.send("goal_status", _status(4.55, 2, STATUS.STATE_FAILED))
    step(4.6, {"cmd_vel": 12})
    assert h.received["cmd_vel"][-1].linear.x == 0.0 and h.service.goal is None
    # Goal 3 with the robot far from its path: stop and wait for a new plan.
    h.send("goal_status", _status(4.7, 3, STATUS.STATE_FOLLOWING))
    h.send("path", ros.path_msg(4.7, "map", line))
    h.send("ground_truth", ros.pose_stamped(4.7, "map", Pose2D(1.0, 1.5, 0.0)))
    step(4.7, {"cmd_vel": 13})
    assert h.received["cmd_vel"][-1].linear.x == 0.0 and h.service.goal is not None
    # controller_feedback is latched (an advanced subscriber on this side): it may arrive after the cmd_vel.
    off = "off the path: waiting for a new plan"
    assert wait_until(lambda: h.received["controller_feedback"][-1].text == off, 10.0)
    assert [f for f in _reports(h) if f[1] == FEEDBACK.STATE_ARRIVED] == [(1, FEEDBACK.STATE_ARRIVED)]
    own = [m for m in h.received["goal_status"] if m.header.stamp.sec * 10**9 + m.header.stamp.nanosec != 0]
    assert len(own) == 5  # only the test's own statuses: the controller publishes none


def test_controller_stops_without_a_recent_scan(peer: Peer) -> None:
    h = Harness(ControllerService, peer, ("cmd_vel",), pose_source="ground_truth", scan_timeout_s=0.5)
    line = np.c_[np.linspace(0.0, 3.0, 31), np.zeros(31)]
    h.send("goal_status", _status(1.0, 1, STATUS.STATE_FOLLOWING))
    h.send("path", ros.path_msg(1.0, "map", line))
    h.send("ground_truth", ros.pose_stamped(1.0, "map", Pose2D(0.0, 0.0, 0.0)))
    h.step(1.0, {"cmd_vel": 1})  # no scan yet
    assert h.received["cmd_vel"][-1].linear.x == 0.0
    h.send("scan", _clear_scan(1.0))
    h.send("ground_truth", ros.pose_stamped(1.1, "map", Pose2D(0.0, 0.0, 0.0)))
    h.step(1.1, {"cmd_vel": 2})
    assert h.received["cmd_vel"][-1].linear.x > 0.0
    h.send("ground_truth", ros.pose_stamped(1.7, "map", Pose2D(0.0, 0.0, 0.0)))
    h.step(1.7, {"cmd_vel": 3})  # the scan is 0.7 s old
    assert h.received["cmd_vel"][-1].linear.x == 0.0


def _send_slam_pose(h: Harness, t: float, map_to_odom: Pose2D, odom: Pose2D, tf_t: float | None = None) -> None:
    """What the navigation services read on ``pose_source = slam``: SLAM's map → odom and the sim's odometry
    (odom → base_link), both on tf."""
    tf_stamp = t if tf_t is None else tf_t
    h.send("tf", ros.tf_message(ros.transform_stamped(tf_stamp, "map", "odom", map_to_odom)))
    h.send("tf", ros.tf_message(ros.transform_stamped(t, "odom", "base_link", odom)))


def test_controller_on_slam_composes_map_to_odom_with_fresh_odometry(peer: Peer) -> None:
    """On SLAM the pose is map→odom (tf) ∘ the newest odometry, as fresh as the odometry; a silent SLAM (stale
    map→odom) stops the robot although odometry keeps coming."""
    h = Harness(ControllerService, peer, ("cmd_vel",), pose_source="slam", pose_timeout_s=0.5)
    # The path runs along y = 1 in map; odom's origin sits at (0, 1) in map, so the robot is on the path heading
    # along it only when the two are composed (on odometry alone it is 1 m off and turns towards it).
    line = np.c_[np.linspace(0.0, 3.0, 31), np.ones(31)]
    h.send("goal_status", _status(1.0, 1, STATUS.STATE_FOLLOWING))
    h.send("path", ros.path_msg(1.0, "map", line))
    h.send("scan", _clear_scan(1.0))
    _send_slam_pose(h, 1.0, map_to_odom=Pose2D(0.0, 1.0, 0.0), odom=Pose2D(0.2, 0.0, 0.0), tf_t=0.95)
    h.step(1.0, {"cmd_vel": 1})
    cmd = h.received["cmd_vel"][-1]
    assert cmd.linear.x > 0.0 and abs(cmd.angular.z) < 1e-6
    # The same odometry with map → odom 0.3 m to the left of the path: the robot steers right, back onto it.
    h.send("scan", _clear_scan(1.1))
    _send_slam_pose(h, 1.1, map_to_odom=Pose2D(0.0, 1.3, 0.0), odom=Pose2D(0.25, 0.0, 0.0))
    h.step(1.1, {"cmd_vel": 2})
    assert h.received["cmd_vel"][-1].angular.z < -0.05
    # SLAM goes silent: odometry alone is not a pose in map; once map → odom is older than pose_timeout_s, stop.
    h.send("scan", _clear_scan(1.7))
    h.send("tf", ros.tf_message(ros.transform_stamped(1.7, "odom", "base_link", Pose2D(0.3, 0.0, 0.0))))
    h.step(1.7, {"cmd_vel": 3})
    assert h.received["cmd_vel"][-1].linear.x == 0.0


def test_controller_slows_on_a_degraded_localisation_and_stops_on_a_lost_one(peer: Peer) -> None:
    """Issue 30: on SLAM's pose the controller follows SLAM's localization_health: WARN caps the speed at
    degraded_speed_scale of max_speed_mps on the same arc, ERROR stops the robot and says why; for want of returns
    (open space) it drives on at its speed, degraded or lost, saying so; OK again drives on."""
    h = Harness(
        ControllerService, peer, ("cmd_vel", "controller_feedback"), pose_source="slam", pose_timeout_s=0.5,
        max_speed_mps=0.5, degraded_speed_scale=0.4,
    )  # fmt: skip
    line = np.c_[np.linspace(0.0, 6.0, 61), np.ones(61)]
    h.send("goal_status", _status(1.0, 1, STATUS.STATE_FOLLOWING))
    h.send("path", ros.path_msg(1.0, "map", line))
    t, count = 1.0, 0

    def drive(level: int, message: str, values: dict[str, str] | None = None) -> object:
        nonlocal t, count
        h.send("localization_health", ros.diagnostic_status(level, "slam", message, values or {}))
        for _ in range(10):  # a few steps: the speed ramps up
            t += 0.05
            h.send("scan", _clear_scan(t))
            _send_slam_pose(h, t, map_to_odom=Pose2D(0.0, 1.0, 0.0), odom=Pose2D(0.2, 0.0, 0.0))
            count += 1
            h.step(t, {"cmd_vel": count})
        return h.received["cmd_vel"][-1]

    assert drive(0, "localised").linear.x == pytest.approx(0.5)
    assert drive(1, "12 lidar returns, fewer than 30; 3 scan(s) in a row").linear.x == pytest.approx(0.2)
    assert wait_until(lambda: h.received["controller_feedback"][-1].text == "slowed: localisation degraded", 10.0)
    assert drive(2, "12 lidar returns, fewer than 30; 30 scan(s) in a row, 2.0 m").linear.x == 0.0
    lost = "localisation lost: waiting for SLAM to localise again"
    assert wait_until(lambda: h.received["controller_feedback"][-1].text == lost, 10.0)
    # Lost with matches that fail stops; for want of returns (open space) it drives on at its speed on odometry.
    assert drive(2, "the scan did not match the map; 30 scan(s)", {"starved": "0"}).linear.x == 0.0
    assert drive(2, "0 lidar returns, fewer than 30; 300 scan(s)", {"starved": "1"}).linear.x == pytest.approx(0.5)
    open_space = "localisation on odometry in open space (too few lidar returns)"
    assert wait_until(lambda: h.received["controller_feedback"][-1].text == open_space, 10.0)
    assert drive(1, "3 lidar returns, fewer than 30; 3 scan(s)", {"starved": "1"}).linear.x == pytest.approx(0.5)
    assert drive(0, "localised").linear.x == pytest.approx(0.5)


def _step_report(t: float, participant: str, due: float) -> object:
    """mjnav_msgs/LockstepReady: ``participant`` finished its step at ``t``, the next is due at ``due``."""
    return msg_class("mjnav_msgs/msg/LockstepReady")(
        header=ros.header(t, ""), participant=participant, ready_until=ros.time_msg(due)
    )


def test_controller_stops_when_a_service_its_inputs_come_from_stops_stepping(peer: Peer) -> None:
    """Issue 31: the path and the goal's status only come when they change, so their producers' step reports bound
    their freshness: a planner whose due step is more than upstream_grace_s of sim time late (dead, hung, left out
    of the lockstep) stops the robot, saying so; its next report lets it drive on. A smoother never heard from is
    not waited for."""
    h = Harness(
        ControllerService, peer, ("cmd_vel", "controller_feedback"), pose_source="ground_truth",
        pose_timeout_s=100.0, upstream_grace_s=0.15,
    )  # fmt: skip
    scanning = _scanning(h)
    sent = 0

    def speed(t: float) -> float:
        nonlocal sent
        h.send("ground_truth", ros.pose_stamped(t, "map", Pose2D(0.0, 0.0, 0.0)))
        sent += 1
        scanning(t, {"cmd_vel": sent})
        return float(h.received["cmd_vel"][-1].linear.x)

    line = np.c_[np.linspace(0.0, 6.0, 61), np.zeros(61)]
    h.send("goal_status", _status(0.0, 1, STATUS.STATE_FOLLOWING))
    h.send("path", ros.path_msg(0.0, "map", line))
    h.send("lockstep", _step_report(0.0, "planner", 0.2), service="planner")
    t = 0.0
    for _ in range(7):  # the planner's step was due at 0.2 s: within the grace up to 0.35 s
        t += 0.05
        assert speed(t) > 0.0, t
    t += 0.05  # 0.4 s: 0.2 s late
    assert speed(t) == 0.0
    waiting = "waiting for planner (not stepping)"
    assert wait_until(lambda: h.received["controller_feedback"][-1].text == waiting, 10.0)
    h.send("lockstep", _step_report(t, "planner", t + 0.2), service="planner")  # a restarted planner reports
    t += 0.05
    assert speed(t) > 0.0


@pytest.mark.e2e
def test_controller_reports_no_progress(peer: Peer) -> None:
    """Nav2's progress checker: no 0.25 m of motion in 20 s and the controller gives the goal up, telling the
    planner (which fails it with ERROR_TIMEOUT)."""
    h = Harness(
        ControllerService, peer, ("cmd_vel", "controller_feedback"), pose_source="ground_truth",
        progress_timeout_s=20.0, progress_radius_m=0.25, pose_timeout_s=100.0,
    )  # fmt: skip
    step = _scanning(h)
    line = np.c_[np.linspace(0.0, 3.0, 31), np.zeros(31)]
    h.send("goal_status", _status(0.0, 1, STATUS.STATE_FOLLOWING))
    h.send("path", ros.path_msg(0.0, "map", line))
    for t, x in ((0.0, 0.0), (10.0, 0.2), (19.9, 0.1), (25.0, 0.3), (44.0, 0.4)):
        h.send("ground_truth", ros.pose_stamped(t, "map", Pose2D(x, 0.0, 0.0)))
        step(t)
        assert h.service.goal is not None, f"goal given up at {t} s"  # moved 0.3 m at 25 s: progress
    h.send("ground_truth", ros.pose_stamped(45.1, "map", Pose2D(0.45, 0.0, 0.0)))
    step(45.1)  # 20.1 s within 0.25 m of (0.3, 0)
    assert wait_until(lambda: _reports(h)[-1] == (1, FEEDBACK.STATE_NO_PROGRESS), 10.0), _reports(h)
    assert "no progress" in h.received["controller_feedback"][-1].text and h.service.goal is None
    # The stop goes out in the same step; it may arrive after the (latched) feedback.
    assert wait_until(lambda: h.received["cmd_vel"][-1].linear.x == 0.0, 10.0)


@pytest.mark.e2e
def test_controller_does_not_creep_behind_a_cart_that_has_crossed_its_way(peer: Peer) -> None:
    """Proximity heuristic and moving obstacles: a cart (1.0 m x 0.7 m) crosses the robot's way 0.5 m ahead at
    0.8 m/s and has just left it; its near corner is 0.31 m from the robot's edge, in the front sector. Parked
    there, the cart slows the robot (v = v_max · 0.31 / d_prox); moving away, it does not: the robot resumes
    v_max (the collision check, which predicts the cart, finds the way clear)."""
    from tests.estimation._scans import raycast

    room = np.array([(-3, -4, 6, -4), (6, -4, 6, 4), (6, 4, -3, 4), (-3, 4, -3, -4)], dtype=float)
    line = np.c_[np.linspace(0.0, 3.0, 31), np.zeros(31)]

    def cart(cy: float) -> np.ndarray:
        x0, x1, y0, y1 = 0.5, 1.5, cy - 0.35, cy + 0.35
        return np.array([(x0, y0, x1, y0), (x1, y0, x1, y1), (x1, y1, x0, y1), (x0, y1, x0, y0)])

    def speed_with_cart(centres_y: list[float]) -> float:
        """The controller's speed after one scan (at 10 Hz) per cart position; the robot stands at the origin,
        heading along its path (+x)."""
        h = Harness(
            ControllerService,
            peer,
            ("cmd_vel",),
            pose_source="ground_truth",
            max_speed_mps=0.5,
            proximity_distance_m=0.5,
        )  # fmt: skip (the robot's radius, 0.19 m, from its description)
        h.send("goal_status", _status(0.0, 1, STATUS.STATE_FOLLOWING))
        h.send("path", ros.path_msg(0.0, "map", line))
        for k, cy in enumerate(centres_y):
            t = 0.1 * k
            angles, ranges = raycast(np.concatenate([room, cart(cy)]), (0.0, 0.0, 0.0), 360, 2 * math.pi, 12.0)
            h.send("ground_truth", ros.pose_stamped(t, "map", Pose2D(0.0, 0.0, 0.0)))
            h.send("scan", ros.laser_scan(
                t, "laser", angle_min_rad=float(angles[0]), angle_increment_rad=float(angles[1] - angles[0]),
                scan_time_s=0.1, range_min_m=0.05, range_max_m=12.0, ranges_m=ranges,
            ))  # fmt: skip
            h.step(t, {"cmd_vel": k + 1})
        return float(h.received["cmd_vel"][-1].linear.x)

    parked = speed_with_cart([-0.42] * 5)
    crossing = speed_with_cart([1.5 - 0.08 * k for k in range(25)])  # 0.8 m/s southwards, last at y = -0.42
    assert parked == pytest.approx(0.5 * 0.31 / 0.5, abs=0.01)
    assert crossing == pytest.approx(0.5)


@pytest.mark.e2e
def test_planner_withdraws_the_plan_on_a_stale_costmap_and_resumes_on_a_fresh_one(planner: Harness) -> None:
    planner.send("goal", ros.pose_stamped(0.0, "map", Pose2D(3.45, 2.05, 0.0)))
    planner.step(0.0, {"goal_status": 3, "plan": 1})
    planner.step(3.5, {"plan": 2})  # the costmap (0.0) is 3.5 s old: withdrawn
    assert len(planner.received["plan"][-1].poses) == 0 and planner.service.goal is not None
    planner.step(4.0)
    assert len(planner.received["plan"]) == 2  # withdrawn once, and no heartbeat re-sends the old plan
    planner.send("costmap", _costmap(4.1, _free()))
    planner.step(4.2, {"plan": 3, "goal_status": 4})
    assert len(planner.received["plan"][-1].poses) > 0
    assert _states(planner)[-1] == (1, STATUS.STATE_FOLLOWING, 0)


@pytest.mark.e2e
def test_the_planner_ends_a_goal_on_the_controllers_report(planner: Harness) -> None:
    planner.send("goal", ros.pose_stamped(0.0, "map", Pose2D(3.45, 2.05, 0.0)))
    planner.step(0.0, {"goal_status": 3, "plan": 1})
    # A report about another goal, and a halt, change nothing.
    planner.send("controller_feedback", _feedback(0.1, 7, FEEDBACK.STATE_ARRIVED))
    planner.send("controller_feedback", _feedback(0.2, 1, FEEDBACK.STATE_HALTED, "no recent pose"))
    planner.step(0.4)
    assert planner.service.goal is not None and len(planner.received["goal_status"]) == 3
    planner.send("controller_feedback", _feedback(0.5, 1, FEEDBACK.STATE_NO_PROGRESS, "no progress: moved less"))
    planner.step(0.6, {"plan": 2, "goal_status": 4})
    assert planner.service.goal is None and len(planner.received["plan"][-1].poses) == 0
    failed = planner.received["goal_status"][-1]
    assert (failed.goal_id, failed.state, failed.error_code) == (1, STATUS.STATE_FAILED, STATUS.ERROR_TIMEOUT)
    assert failed.error_text == "no progress: moved less" and ros.seconds(failed.header.stamp) == 0.5


@pytest.mark.e2e
def test_a_goal_beyond_what_the_robot_has_seen_is_planned_through_unknown_space(planner: Harness) -> None:
    """The costmap covers what the robot has seen so far; a goal 1.5 m beyond it (behind a wall the lidar has not
    looked past yet) is planned to through unknown cells, not refused."""
    planner.send("goal", ros.pose_stamped(0.0, "map", Pose2D(5.5, 2.05, 0.0)))
    planner.step(0.0, {"goal_status": 3, "plan": 1})
    assert _states(planner)[-1] == (1, STATUS.STATE_FOLLOWING, 0)
    pts = ros.path_points(planner.received["plan"][-1])
    assert pts[-1] == pytest.approx((5.5, 2.05), abs=RES) and pts[:, 0].max() > 4.0


def test_a_robot_off_its_route_gets_a_new_one_from_where_it_is(planner: Harness) -> None:
    """Issue 30: SLAM corrected the pose 1.1 m across the route; the route itself was still free, so the planner
    kept it, and the controller (stopped beyond its lost_distance_m) waited until no progress failed the goal."""
    planner.send("goal", ros.pose_stamped(0.0, "map", Pose2D(3.45, 2.05, 0.0)))
    planner.step(0.1, {"plan": 1})
    planner.send("ground_truth", ros.pose_stamped(0.2, "map", Pose2D(1.5, 2.45, 0.0)))  # 0.4 m off: keeps it
    planner.send("costmap", _costmap(0.2, _free()))
    planner.step(0.3)
    assert len(planner.received["plan"]) == 1
    planner.send("ground_truth", ros.pose_stamped(0.4, "map", Pose2D(1.5, 3.15, 0.0)))  # 1.1 m off
    planner.send("costmap", _costmap(0.4, _free()))
    planner.step(0.5, {"plan": 2})
    assert ros.path_points(planner.received["plan"][-1])[0] == pytest.approx((1.55, 3.15), abs=RES)


def test_the_planner_notices_the_robot_cycling_and_makes_unknown_space_dearer(peer: Peer) -> None:
    """Issue 30: a route through unknown space inside a thick wall keeps looking shortest; when the robot is back
    where it was after driving a loop, with no shorter route, the planner raises the goal's unknown cost, says
    so, and plans afresh (here: over the wall's known end)."""
    h = Harness(
        PlannerService, peer, ("goal_status", "plan"), pose_source="ground_truth",
        cycle_distance_m=3.0, cycle_unknown_factor=10.0,
    )  # fmt: skip
    wall = _free()
    wall[0:35, 15:25] = 100
    wall[10:20, 15:25] = -1  # a stretch of the wall's inside nobody has seen: looks like a way through
    h.send("costmap", _costmap(0.0, wall))
    h.send("ground_truth", ros.pose_stamped(0.0, "map", Pose2D(0.55, 1.55, 0.0)))
    h.send("goal", ros.pose_stamped(0.0, "map", Pose2D(3.45, 1.55, 0.0)))
    h.step(0.1, {"plan": 1})
    first = _plan_cells(h)
    assert (wall[first[:, 0], first[:, 1]] < 0).any()  # through the unknown stretch
    t = 0.2
    for x, y in [(0.55, 1.55), (1.2, 1.55), (1.2, 3.0), (0.55, 3.0)]:  # a 4.2 m loop back to the start
        h.send("ground_truth", ros.pose_stamped(t, "map", Pose2D(x, y, 0.0)))
        h.step(t)
        t += 0.1
    assert len(h.received["plan"]) == 1 and h.service.goal.cycles == 0  # nowhere twice yet
    h.send("ground_truth", ros.pose_stamped(t, "map", Pose2D(0.6, 1.6, 0.0)))
    h.step(t, {"plan": 2})
    assert h.service.goal.cycles == 1 and h.service.goal.unknown_factor == 10.0
    assert any(s.error_text.startswith("cycling: back at (0.6, 1.6)") for s in h.received["goal_status"])
    second = _plan_cells(h)
    assert not (wall[second[:, 0], second[:, 1]] < 0).any() and second[:, 0].max() >= 35  # over the wall's end


def test_the_planner_carries_its_route_over_to_a_grown_costmap(planner: Harness) -> None:
    """The costmap grows with what the robot explores: the same route, re-indexed, is neither lost nor replanned."""
    planner.send("goal", ros.pose_stamped(0.0, "map", Pose2D(3.45, 2.05, 0.0)))
    planner.step(0.0, {"goal_status": 3, "plan": 1})
    before = ros.path_points(planner.received["plan"][-1])
    grown = np.full((60, 70), -1, dtype=np.int8)
    grown[10:50, 20:60] = _free()  # the same 4 x 4 m, now with 1 m unknown below and 2 m to the left
    planner.send("costmap", ros.occupancy_grid(0.5, "map", grown, RES, (-2.0, -1.0)))
    planner.step(0.6)
    assert len(planner.received["plan"]) == 1  # nothing to replan: the route is the same
    np.testing.assert_allclose(
        planner.service.goal.frame.cells_to_world(planner.service.goal.cells)[-len(before) :], before
    )


@pytest.mark.e2e
def test_a_restarted_planner_resumes_its_goal_under_the_same_id(
    peer: Peer, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MJNAV_STATE_DIR", str(tmp_path))
    first = Harness(PlannerService, peer, ("goal_status", "plan"), pose_source="ground_truth")
    first.send("costmap", _costmap(0.0, _free()))
    first.send("ground_truth", ros.pose_stamped(0.0, "map", Pose2D(0.55, 2.05, 0.0)))
    first.send("goal", ros.pose_stamped(0.0, "map", Pose2D(3.45, 2.05, 0.0)))
    first.send("goal", ros.pose_stamped(0.0, "map", Pose2D(3.45, 1.05, 0.0)))  # goal 2 supersedes goal 1
    first.step(0.0, {"goal_status": 6, "plan": 2})
    # A new process (same state directory) takes over: goal 2, same target, same id; the next goal gets id 3.
    first.service.bus.close()  # the first process is gone (its subscriptions must not answer for the second's)
    second = Harness(PlannerService, peer, ("goal_status", "plan"), pose_source="ground_truth")
    assert second.service.goal is not None and second.service.goal.goal_id == 2
    assert (second.service.goal.pose.x, second.service.goal.pose.y) == (3.45, 1.05)
    second.send("costmap", _costmap(0.1, _free()))
    second.send("ground_truth", ros.pose_stamped(0.1, "map", Pose2D(1.0, 2.05, 0.0)))
    second.step(0.2, {"plan": 1, "goal_status": 1})  # the plan goes out before its status
    assert _states(second)[-1] == (2, STATUS.STATE_FOLLOWING, 0)
    second.send("goal", ros.pose_stamped(0.3, "map", Pose2D(2.0, 2.05, 0.0)))
    second.step(0.3, {"goal_status": 4})
    assert [s[:2] for s in _states(second)[1:4]] == [(2, STATUS.STATE_CANCELED), (3, STATUS.STATE_ACCEPTED),
                                                     (3, STATUS.STATE_PLANNING)]  # fmt: skip
    # Once the goal ended, a third process starts without one.
    second.send("cancel", msg_class("std_msgs/msg/Empty")())
    second.step(0.4, {"goal_status": 6})
    second.service.bus.close()
    third = Harness(PlannerService, peer, ("goal_status",), pose_source="ground_truth")
    assert third.service.goal is None and third.service.next_id == 4


@pytest.mark.e2e
def test_a_restarted_mapper_resumes_the_map_and_save_map_stays_in_maps_dir(
    peer: Peer, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MJNAV_STATE_DIR", str(tmp_path / "state"))
    (tmp_path / "state").mkdir()
    maps = tmp_path / "maps"
    first = Harness(
        MapperService,
        peer,
        ("map",),
        map_source="scan",
        pose_source="ground_truth",
        checkpoint_period_s=1.0,
        maps_dir=str(maps),
    )
    scan = ros.laser_scan(
        0.0, "laser", angle_min_rad=-math.pi, angle_increment_rad=2 * math.pi / 90, scan_time_s=0.1,
        range_min_m=0.05, range_max_m=12.0, ranges_m=np.full(90, 2.0),
    )  # fmt: skip
    for k in range(5):  # a cell needs several scans to cross a threshold; until then no map goes out
        t = 0.25 * k  # the last step, t = 1.0, checkpoints (checkpoint_period_s)
        scan.header = ros.header(t, "laser")  # type: ignore[attr-defined]
        first.send("ground_truth", ros.pose_stamped(t, "map", Pose2D(0.0, 0.0, 0.0)))
        first.send("scan", scan)
        first.step(t)
    assert wait_until(lambda: len(first.received["map"]) >= 1, 10.0)
    known = np.count_nonzero(first.service.grid.log_odds)
    assert known > 1000
    first.service.bus.close()
    second = Harness(MapperService, peer, ("map",), map_source="scan", pose_source="ground_truth", maps_dir=str(maps))
    np.testing.assert_array_equal(second.service.grid.log_odds, first.service.grid.log_odds)
    # save_map: relative paths land in maps_dir; anything outside it is refused and nothing is written.
    string = msg_class("std_msgs/msg/String")
    # The new queryable takes a moment to become known to the caller's session: ask until it answers.
    replies: list[object] = []

    def saved() -> bool:
        try:
            replies.append(second.world.call("save_map", string(data="run1/rooms.yaml"), timeout_s=1.0))
        except NoReply:
            return False
        return True

    assert wait_until(saved, 30.0)
    reply = json.loads(replies[-1].data)  # type: ignore[attr-defined]
    assert Path(reply["yaml"]) == maps / "run1" / "rooms.yaml" and (maps / "run1" / "rooms.yaml").exists()
    for bad in (str(tmp_path / "evil.yaml"), "../evil.yaml", "run1/../../evil.yaml"):
        with pytest.raises(RemoteError, match="maps_dir"):
            second.world.call("save_map", string(data=bad), timeout_s=10.0)
    assert not (tmp_path / "evil.yaml").exists()


@pytest.mark.e2e
def test_the_mapper_publishes_no_all_unknown_costmap_and_the_first_known_one_at_once(peer: Peer) -> None:
    """No costmap before a cell is known (the planner would route straight through unknown space and the robot
    set off on that route); the first goes out in the step a cell becomes known, the later ones on the
    ``publish_rate_hz`` grid (k / rate), so the planner's steps see them as before."""
    h = Harness(
        MapperService, peer, ("costmap",), map_source="scan", pose_source="ground_truth", publish_rate_hz=2.0,
        checkpoint_period_s=0.0,
    )  # fmt: skip
    for k in range(12):  # t = 0.0 .. 1.1
        t = 0.1 * k
        h.send("ground_truth", ros.pose_stamped(t, "map", Pose2D(0.0, 0.0, 0.0)))
        h.send("scan", ros.laser_scan(
            t, "laser", angle_min_rad=-math.pi, angle_increment_rad=2 * math.pi / 90, scan_time_s=0.1,
            range_min_m=0.05, range_max_m=12.0, ranges_m=np.full(90, 2.0),
        ))  # fmt: skip
        h.step(t)
    assert wait_until(lambda: len(h.received["costmap"]) >= 3, 10.0)
    costmaps = h.received["costmap"]
    stamps = [round(ros.seconds(m.header.stamp), 3) for m in costmaps]
    assert len(stamps) == 3 and 0.0 < stamps[0] < 0.5, stamps  # not at t = 0 (one scan knows no cell) nor at 0.5
    assert (np.asarray(costmaps[0].data) != -1).any()
    assert stamps[1:] == [0.5, 1.0], stamps  # then on the grid


def _ring_scan(t: float, centre: Pose2D, radius: float) -> object:
    """The scan of a robot at ``centre`` (map) inside a circular wall of ``radius`` around the origin, 360 beams."""
    n = 360
    a = -math.pi + 2 * math.pi * np.arange(n) / n
    heading = centre.theta + a
    # Ray from (cx, cy) along heading meets |p| = radius at s = -b + sqrt(b² - c).
    b = centre.x * np.cos(heading) + centre.y * np.sin(heading)
    c = centre.x**2 + centre.y**2 - radius**2
    ranges = -b + np.sqrt(b * b - c)
    return ros.laser_scan(
        t, "laser", angle_min_rad=-math.pi, angle_increment_rad=2 * math.pi / n, scan_time_s=0.1,
        range_min_m=0.05, range_max_m=12.0, ranges_m=ranges,
    )  # fmt: skip


def test_slam_waits_for_initialpose_then_publishes_pose_map_and_tf(peer: Peer) -> None:
    """No pose before initialpose (and the service says what it waits for); from it on, pose = map→odom ∘
    odometry in the map frame, the map, map→odom on tf."""
    from mjnav.services.slam import SlamService

    h = Harness(SlamService, peer, ("pose", "map", "tf", "localization_health"))
    start = Pose2D(1.0, 0.5, 0.3)
    h.send("odom", ros.odometry(0.0, Pose2D(0.0, 0.0, 0.0), 0.0, 0.0))
    h.send("scan", _ring_scan(0.0, start, 4.0))
    h.step(0.0)
    assert h.service.starved().startswith("initialpose on robot0/initialpose")
    assert h.received["pose"] == [] and h.received["map"] == []  # not started: no initial pose yet
    cov = np.diag([0.01, 0.01, 0.003])
    h.send("initialpose", ros.pose_with_covariance_stamped(0.05, "map", start, cov))
    h.send("odom", ros.odometry(0.1, Pose2D(0.0, 0.0, 0.0), 0.0, 0.0))
    h.send("scan", _ring_scan(0.1, start, 4.0))
    h.step(0.1, {"pose": 1, "map": 1, "tf": 1})
    est = ros.pose_of(h.received["pose"][-1])
    assert math.hypot(est.x - start.x, est.y - start.y) < 0.02 and abs(est.theta - start.theta) < 0.01
    tf = h.received["tf"][-1].transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id) == ("map", "odom")
    assert h.service.starved() == ""
    # The robot drives 0.3 m along its heading: odometry says so, the scans agree; pose follows.
    moved = Pose2D(start.x + 0.3 * math.cos(0.3), start.y + 0.3 * math.sin(0.3), 0.3)
    h.send("odom", ros.odometry(0.2, Pose2D(0.3, 0.0, 0.0), 0.0, 0.0))
    h.send("scan", _ring_scan(0.2, moved, 4.0))
    h.step(0.2, {"pose": 2})
    est = ros.pose_of(h.received["pose"][-1])
    assert math.hypot(est.x - moved.x, est.y - moved.y) < 0.03
    grid_cells, frame = ros.grid_frame(h.received["map"][0])
    on_wall = frame.values_at(grid_cells, np.array([[3.98, 0.0], [0.0, 3.98], [-3.98, 0.0]]), outside=-1)
    assert np.all(on_wall >= 65)  # the ring wall is in the map, where it is
    health = h.received["localization_health"]
    assert wait_until(lambda: len(health) == 2, 10.0)  # one per scan used
    assert health[-1].level == 0 and ros.diagnostic_values(health[-1])["returns"] == "360"
    # Out into a hall whose walls are beyond the lidar's range: no returns. Degraded after 3 such scans, lost
    # after 10 m on odometry alone (1.25 m per scan here), and the status says so.
    hall = ros.laser_scan(
        0.0, "laser", angle_min_rad=-math.pi, angle_increment_rad=2 * math.pi / 360, scan_time_s=0.1,
        range_min_m=0.05, range_max_m=12.0, ranges_m=np.full(360, np.inf),
    )  # fmt: skip
    for i in range(1, 10):
        t = 0.2 + 0.1 * i
        h.send("odom", ros.odometry(t, Pose2D(0.3 + 1.25 * i, 0.0, 0.0), 0.0, 0.0))
        hall.header.stamp = ros.time_msg(t)
        h.send("scan", hall)
        h.step(t, {"localization_health": 2 + i})
    assert ros.diagnostic_values(health[1])["degenerate"] == "1"  # a ring pins no heading
    assert [m.level for m in health[1:]] == [0, 0, 0, 1, 1, 1, 1, 1, 2, 2]
    assert health[-1].message.startswith("0 lidar returns, fewer than 30")
    assert h.service.starved() == "scans it can localise with (lost: the reason is on robot0/localization_health)"


@pytest.mark.e2e
@pytest.mark.parametrize("use_gyro", [True, False])
def test_slam_takes_its_heading_from_the_gyro(peer: Peer, use_gyro: bool) -> None:
    """The wheels report a 0.2 rad turn the gyro does not see (a wrong wheel separation); the scans cannot tell
    (the robot stands at the centre of a round room). With the gyro SLAM's heading stays; without, it turns."""
    from mjnav.services.slam import SlamService

    h = Harness(SlamService, peer, ("pose",), use_gyro=use_gyro, initial_pose=(0.0, 0.0, 0.0))
    centre = Pose2D(0.0, 0.0, 0.0)
    for k in range(3):
        t = 0.1 * k
        for i in range(1, 11 if k and use_gyro else 1):
            h.send("imu", ros.imu(t - 0.1 + 0.01 * i, "imu", (0, 0, 0, 1), (0.0, 0.0, 0.0), (0.0, 0.0, 9.81)))
        h.send("odom", ros.odometry(t, Pose2D(0.0, 0.0, 0.1 * k), 0.0, 1.0))
        h.send("scan", _ring_scan(t, centre, 4.0))
        h.step(t, {"pose": k + 1})
    heading = ros.pose_of(h.received["pose"][-1]).theta
    assert heading == pytest.approx(0.0 if use_gyro else 0.2, abs=0.01)


@pytest.mark.e2e
def test_costmap_from_slams_map_with_the_newest_scan_as_obstacle_layer(peer: Peer) -> None:
    h = Harness(
        MapperService,
        peer,
        ("costmap",),
        map_source="slam",
        resolution_m=0.1,
    )
    static = np.zeros((40, 40), dtype=np.int8)
    static[:, 30] = 100  # a wall at x = 3.0..3.1 in SLAM's map (same frame here)
    h.send("map", _costmap(0.0, static))
    _send_slam_pose(h, 0.0, map_to_odom=Pose2D(0.5, 2.0, 0.0), odom=Pose2D(0.5, 0.0, 0.0))  # robot at (1, 2)
    # A box 1 m ahead (x = 2.0) that the map does not have yet: the newest scan's returns mark it.
    scan = ros.laser_scan(
        0.0, "laser", angle_min_rad=-0.1, angle_increment_rad=0.05, scan_time_s=0.1, range_min_m=0.05,
        range_max_m=12.0, ranges_m=np.full(5, 1.0),
    )  # fmt: skip
    h.send("scan", scan)
    h.step(0.0, {"costmap": 1})
    cost, frame = ros.grid_frame(h.received["costmap"][-1])
    wall, box, robot = frame.values_at(cost, np.array([[3.05, 2.05], [2.05, 2.05], [1.05, 2.05]]), outside=-2)
    assert wall == 100 and box == 100  # the map's wall; the scanned box (x = 2.0, y = 2.0)
    assert robot == 0  # the robot's own cell: free


@pytest.mark.e2e
def test_a_cart_crossing_the_view_leaves_no_trail_in_the_costmap_and_a_parked_one_is_marked(peer: Peer) -> None:
    """Scan mode: a cart drives across in front of the robot at 0.5 m/s, then parks. Its returns only clear while
    it moves (the planner would otherwise route around every place it has been), and mark once it stands."""
    from tests.estimation._scans import raycast

    h = Harness(
        MapperService, peer, ("map",), map_source="scan", pose_source="ground_truth", resolution_m=0.05,
        checkpoint_period_s=0.0,
    )  # fmt: skip
    room = np.array([(0, 0, 10, 0), (10, 0, 10, 6), (10, 6, 0, 6), (0, 6, 0, 0)], dtype=float)
    robot = (1.0, 3.0, 0.0)

    def cart(cy: float) -> np.ndarray:
        x0, x1, y0, y1 = 4.0, 5.0, cy - 0.35, cy + 0.35
        return np.array([(x0, y0, x1, y0), (x1, y0, x1, y1), (x1, y1, x0, y1), (x0, y1, x0, y0)])

    def scan_at(t: float, cy: float) -> None:
        angles, ranges = raycast(np.concatenate([room, cart(cy)]), robot, 360, 2 * math.pi, 12.0)
        h.send("ground_truth", ros.pose_stamped(t, "map", Pose2D(*robot)))
        h.send("scan", ros.laser_scan(
            t, "laser", angle_min_rad=float(angles[0]), angle_increment_rad=float(angles[1] - angles[0]),
            scan_time_s=0.1, range_min_m=0.05, range_max_m=12.0, ranges_m=ranges,
        ))  # fmt: skip
        h.step(t)

    def occupied(y0: float, y1: float) -> int:
        """Occupied cells of the cart's lane (x = 4..5 m, and a cell either side) between y0 and y1."""
        states = h.service.grid.states()
        r0, c0 = h.service.frame.world_to_cell(3.925, y0 + 0.025)
        r1, c1 = h.service.frame.world_to_cell(5.075, y1 + 0.025)
        return int((states[r0:r1, c0:c1] == 100).sum())

    for k in range(60):  # from y = 5.0 to 2.0 at 0.5 m/s
        scan_at(0.1 * k, 5.0 - 0.05 * k)
    assert occupied(0.5, 5.5) == 0
    for k in range(60, 66):  # parked at y = 2.0
        scan_at(0.1 * k, 2.0)
    assert occupied(1.6, 2.4) > 10  # its west face and corners, marked
    assert occupied(2.5, 5.5) == 0


@pytest.mark.e2e
def test_services_that_start_late_get_the_goal_and_its_plan_from_the_transport(planner: Harness, peer: Peer) -> None:
    """Nobody re-sends: a smoother that starts after the plan went out gets it from the planner's latched plan, and
    a controller that starts after that gets the goal's status and the path from the latched topics, and drives."""
    planner.send("goal", ros.pose_stamped(0.0, "map", Pose2D(3.45, 2.05, 0.0)))
    planner.step(0.0, {"goal_status": 3, "plan": 1})
    smoother = Harness(SmootherService, peer, ("path",))
    assert wait_until(lambda: smoother.service.plan.latest() is not None, 10.0)
    smoother.step(0.1, {"path": 1})
    controller = Harness(ControllerService, peer, ("cmd_vel",), pose_source="ground_truth")
    controller.send("ground_truth", ros.pose_stamped(0.2, "map", Pose2D(0.55, 2.05, 0.0)))
    controller.send("scan", _clear_scan(0.2))
    assert wait_until(lambda: controller.service.path_sub.latest() is not None, 10.0)
    controller.step(0.2, {"cmd_vel": 1})
    assert controller.service.goal is not None and controller.service.goal.goal_id == 1
    assert controller.received["cmd_vel"][-1].linear.x > 0.0


@pytest.mark.e2e
def test_the_mapper_grows_its_grid_with_what_the_robot_sees(peer: Peer) -> None:
    """Down a 40 m corridor the grid follows the robot: it holds every cell a scan touched (returns, and free beams
    up to their range), keeps what it knew, stays on the same cells, and is the corridor's size, not the lidar's
    range around the whole drive."""
    from tests.estimation._scans import raycast

    walls = np.array([(-1, -1, 41, -1), (-1, 1, 41, 1), (-1, -1, -1, 1), (41, -1, 41, 1)], dtype=float)
    h = Harness(MapperService, peer, (), pose_source="ground_truth", checkpoint_period_s=0.0, grow_margin_m=1.0)
    first_origin = None
    for k in range(44):  # four scans at the start (a cell needs three hits to be occupied), then 1 m per scan
        t, x = 0.1 * k, max(0.0, k - 3.0)
        angles, ranges = raycast(walls, (x, 0.0, 0.0), 360, 2 * math.pi, 12.0)
        h.send("ground_truth", ros.pose_stamped(t, "map", Pose2D(x, 0.0, 0.0)))
        h.send("scan", ros.laser_scan(
            t, "laser", angle_min_rad=float(angles[0]), angle_increment_rad=float(angles[1] - angles[0]),
            scan_time_s=0.1, range_min_m=0.05, range_max_m=12.0, ranges_m=ranges,
        ))  # fmt: skip
        h.step(t)
        grid = h.service.grid
        x0, x1, y0, y1 = grid.extent_m
        assert x0 <= -1.0 and x1 >= min(x + 12.0, 41.0) and y0 <= -1.0 and y1 >= 1.0, (k, grid.extent_m)
        first_origin = first_origin or grid.origin_m
        shift = (np.asarray(grid.origin_m) - first_origin) / grid.resolution_m
        assert np.allclose(shift, np.round(shift), atol=1e-6)  # the same cells
        if k == 3:
            states = h.service.grid.states()
            wall = [h.service.frame.world_to_cell(0.0, y) for y in (-1.02, -0.98)]  # the line y = -1 at x = 0
            assert CellState.OCCUPIED in [states[c] for c in wall]
    x0, x1, y0, y1 = h.service.grid.extent_m
    assert x1 - x0 <= 42.0 + 2 * 1.0 + 0.2 and y1 - y0 <= 2.0 + 2 * 1.0 + 0.2  # the corridor, the margins, a cell
    states = h.service.grid.states()
    wall = [h.service.frame.world_to_cell(0.0, y) for y in (-1.02, -0.98)]  # the wall line y = -1 at x = 0
    assert CellState.OCCUPIED in [states[c] for c in wall]  # seen at the start, kept through every growth
    h.close()

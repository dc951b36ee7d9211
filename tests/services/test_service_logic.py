"""Service logic stepped by hand (no processes): the planner's goal bookkeeping and replanning policy, the
smoother's clearance box, the controller's goal states. Each service runs on a real in-process Zenoh bus."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from mjnav.bus import Bus
from mjnav.geometry import Pose2D
from mjnav.msgs import msg_class, ros
from mjnav.services.controller import ControllerService
from mjnav.services.planner import PlannerService
from mjnav.services.smoother import SmootherService
from tests.services.harness import Harness

STATUS = msg_class("mjnav_msgs/msg/GoalStatus")
RES = 0.1  # costmap resolution, metres; origin (0, 0); 40 x 40 cells
Peer = Callable[..., Bus]


def _costmap(t: float, cells: np.ndarray) -> object:
    return ros.occupancy_grid(t, "map", cells, RES, (0.0, 0.0))


def _free() -> np.ndarray:
    return np.zeros((40, 40), dtype=np.int8)


def _status(t: float, goal_id: int, state: int) -> object:
    goal = ros.pose_stamped(t, "map", Pose2D(0.0, 0.0, 0.0))
    return STATUS(header=ros.header(t, "map"), goal_id=goal_id, state=state, error_code=0, error_text="", goal=goal)


def _states(h: Harness) -> list[tuple[int, int, int]]:
    """(goal id, state, error code) of every goal_status received so far."""
    return [(s.goal_id, s.state, s.error_code) for s in h.received["goal_status"]]


def _plan_cells(h: Harness) -> np.ndarray:
    """The newest plan, as (row, col) cells."""
    pts = ros.path_points(h.received["plan"][-1])
    return np.floor(pts[:, ::-1] / RES).astype(int)


@pytest.fixture
def planner(peer: Peer) -> Harness:
    """Planner on a free 4 x 4 m costmap, robot at (0.55, 2.05): no heartbeats within the tests' time span."""
    h = Harness(PlannerService, peer, ("goal_status", "plan"), replan_period_s=2.0, heartbeat_period_s=100.0)
    h.send("costmap", _costmap(0.0, _free()))
    h.send("ground_truth", ros.pose_stamped(0.0, "map", Pose2D(0.55, 2.05, 0.0)))
    return h


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
        (Pose2D(9.0, 2.0, 0.0), "map", STATUS.ERROR_OUTSIDE_MAP),
        (Pose2D(1.0, 1.0, 0.0), "odom", STATUS.ERROR_INVALID_GOAL),
    ]
    for i, ((pose, frame, error), total) in enumerate(zip(cases, (3, 6, 9, 11), strict=True)):
        planner.send("goal", ros.pose_stamped(0.2, frame, pose))
        planner.step(0.2 + i, {"goal_status": total})  # accepted (planning) failed
        last = planner.received["goal_status"]
        assert planner.service.goal is None
        assert (last[-1].goal_id, last[-1].state, last[-1].error_code) == (i + 1, STATUS.STATE_FAILED, error)


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
    # The controller's "reached" ends the goal and withdraws the plan.
    goal_id = planner.service.goal.goal_id
    planner.send("goal_status", _status(5.1, goal_id, STATUS.STATE_REACHED))
    planner.step(5.2, {"plan": 4})
    assert planner.service.goal is None and len(planner.received["plan"][-1].poses) == 0


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
    bare = Harness(SmootherService, peer, ("path",))
    np.testing.assert_allclose(bare.service.smooth(plan), resample(plan, bare.service.config.spacing_m))


def test_controller_goal_states(peer: Peer) -> None:
    h = Harness(ControllerService, peer, ("cmd_vel", "goal_status"), path_timeout_s=3.0, pose_timeout_s=0.5)
    line = np.c_[np.linspace(0.0, 3.0, 31), np.zeros(31)]
    # No goal: zero command.
    h.send("ground_truth", ros.pose_stamped(0.0, "map", Pose2D(0.0, 0.0, 0.0)))
    h.step(0.0, {"cmd_vel": 1})
    assert h.received["cmd_vel"][-1].linear.x == 0.0
    # Following goal 1 with its path: drives.
    h.send("goal_status", _status(1.0, 1, STATUS.STATE_FOLLOWING))
    h.send("path", ros.path_msg(1.0, "map", line))
    h.send("ground_truth", ros.pose_stamped(1.0, "map", Pose2D(0.0, 0.0, 0.0)))
    h.step(1.0, {"cmd_vel": 2})
    assert h.received["cmd_vel"][-1].linear.x > 0.0
    # A pose older than pose_timeout_s: stop.
    h.step(1.6, {"cmd_vel": 3})
    assert h.received["cmd_vel"][-1].linear.x == 0.0
    # A path older than path_timeout_s (no re-send from the planner): stop, even with a fresh pose.
    h.send("ground_truth", ros.pose_stamped(4.1, "map", Pose2D(0.5, 0.0, 0.0)))
    h.step(4.1, {"cmd_vel": 4})
    assert h.received["cmd_vel"][-1].linear.x == 0.0
    h.send("path", ros.path_msg(4.2, "map", line))
    h.step(4.2, {"cmd_vel": 5})
    assert h.received["cmd_vel"][-1].linear.x > 0.0
    # Driving on to the goal: stop there and report reached, once.
    for i, x in enumerate((1.0, 1.5, 2.0, 2.5)):
        h.send("ground_truth", ros.pose_stamped(4.21 + 0.01 * i, "map", Pose2D(x, 0.0, 0.0)))
        h.step(4.21 + 0.01 * i)
    h.send("ground_truth", ros.pose_stamped(4.3, "map", Pose2D(2.97, 0.0, 0.0)))
    h.step(4.3, {"cmd_vel": 10, "goal_status": 2})  # the test's "following", the controller's "reached"
    reached = h.received["goal_status"][-1]
    assert (reached.goal_id, reached.state) == (1, STATUS.STATE_REACHED)
    # A late heartbeat of the finished goal does not revive it.
    h.send("goal_status", _status(4.35, 1, STATUS.STATE_FOLLOWING))
    h.send("ground_truth", ros.pose_stamped(4.4, "map", Pose2D(1.0, 0.0, 0.0)))
    h.step(4.4, {"cmd_vel": 11})
    assert h.received["cmd_vel"][-1].linear.x == 0.0 and h.service.goal is None
    # Goal 2 follows; then the planner fails it: the controller stops at once.
    h.send("goal_status", _status(4.5, 2, STATUS.STATE_FOLLOWING))
    h.send("path", ros.path_msg(4.5, "map", line))
    h.send("ground_truth", ros.pose_stamped(4.5, "map", Pose2D(1.0, 0.0, 0.0)))
    h.step(4.5, {"cmd_vel": 12})
    assert h.received["cmd_vel"][-1].linear.x > 0.0
    h.send("goal_status", _status(4.55, 2, STATUS.STATE_FAILED))
    h.step(4.6, {"cmd_vel": 13})
    assert h.received["cmd_vel"][-1].linear.x == 0.0 and h.service.goal is None
    # Goal 3 with the robot far from its path: stop and wait for a new plan.
    h.send("goal_status", _status(4.7, 3, STATUS.STATE_FOLLOWING))
    h.send("path", ros.path_msg(4.7, "map", line))
    h.send("ground_truth", ros.pose_stamped(4.7, "map", Pose2D(1.0, 1.5, 0.0)))
    h.step(4.7, {"cmd_vel": 14})
    assert h.received["cmd_vel"][-1].linear.x == 0.0 and h.service.goal is not None
    assert [s.goal_id for s in h.received["goal_status"] if s.state == STATUS.STATE_REACHED] == [1]

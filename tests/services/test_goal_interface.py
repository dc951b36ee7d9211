"""The goal interface without processes: the planner's ``navigate`` endpoint (accept with an id, typed rejections,
none lost in a burst, kept across a restart), delivery receipts on the event topics, and the controller's final
turn to the goal's yaw."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from mjnav.bus import Bus, NotDelivered, wait_until
from mjnav.geometry import Pose2D
from mjnav.msgs import from_dict, msg_class, ros
from mjnav.services.controller import ControllerService, goal_yaw_error
from mjnav.services.planner import PlannerService
from tests.services.harness import Harness

STATUS = msg_class("mjnav_msgs/msg/GoalStatus")
FEEDBACK = msg_class("mjnav_msgs/msg/ControllerFeedback")
REQUEST = msg_class("mjnav_msgs/msg/NavigateRequest")
RES = 0.1  # costmap resolution, metres; origin (0, 0); 40 x 40 cells
Peer = Callable[..., Bus]


def _costmap(t: float, cells: np.ndarray) -> object:
    return ros.occupancy_grid(t, "map", cells, RES, (0.0, 0.0))


def _request(x: float, y: float, frame: str = "map") -> object:
    return REQUEST(goal=ros.pose_stamped(0.0, frame, Pose2D(x, y, 0.0)))


def _planner(peer: Peer) -> Harness:
    """Planner on a 4 x 4 m costmap with a wall at x = 2.0-2.2 m, robot at (0.55, 2.05)."""
    h = Harness(
        PlannerService,
        peer,
        ("goal_status", "plan"),
        pose_source="ground_truth",
        replan_period_s=2.0,
    )
    cells = np.zeros((40, 40), dtype=np.int8)
    cells[:30, 20:22] = 100
    h.send("costmap", _costmap(0.0, cells))
    h.send("ground_truth", ros.pose_stamped(0.0, "map", Pose2D(0.55, 2.05, 0.0)))
    return h


@pytest.mark.e2e
def test_navigate_accepts_with_the_id_its_statuses_carry(peer: Peer) -> None:
    h = _planner(peer)
    reply = h.world.call("navigate", _request(3.45, 3.55))
    assert (reply.accepted, reply.goal_id, reply.error_code) == (True, 1, 0)
    h.step(0.0, {"goal_status": 3, "plan": 1})
    states = [(s.goal_id, s.state) for s in h.received["goal_status"]]
    assert states == [(1, STATUS.STATE_ACCEPTED), (1, STATUS.STATE_PLANNING), (1, STATUS.STATE_FOLLOWING)]
    assert len(h.received["plan"][-1].poses) > 0


@pytest.mark.e2e
@pytest.mark.parametrize(
    ("x", "y", "frame", "code", "words"),
    [
        (1.0, 1.0, "odom", "ERROR_INVALID_GOAL", "'odom' is not 'map'"),
        (15.5, 1.0, "map", "ERROR_OUTSIDE_MAP", "outside the costmap, x 0.00..4.00 m, y 0.00..4.00 m: 11.50 m beyond"),
        (-10.5, 1.0, "map", "ERROR_OUTSIDE_MAP", "(-10.50, 1.00) m"),
        (2.05, 1.0, "map", "ERROR_GOAL_OCCUPIED", "in an obstacle"),
    ],
)
def test_navigate_rejects_with_a_typed_reason(
    peer: Peer, x: float, y: float, frame: str, code: str, words: str
) -> None:
    h = _planner(peer)
    reply = h.world.call("navigate", _request(x, y, frame))
    assert not reply.accepted and reply.goal_id == 0
    assert reply.error_code == getattr(STATUS, code) and words in reply.error_text
    h.step(0.0)
    assert h.service.goal is None and h.service.next_id == 1  # nothing accepted, no id spent


@pytest.mark.e2e
def test_a_hundred_goals_in_a_row_none_lost(peer: Peer) -> None:
    """Requests between two steps all get distinct ids and each is accepted in order (the newer supersedes)."""
    h = _planner(peer)
    ids = []
    for i in range(100):
        reply = h.world.call("navigate", _request(0.55 + 0.01 * i, 3.05))
        assert reply.accepted
        ids.append(reply.goal_id)
        if i % 10 == 9:
            h.step(0.01 * i)
    assert ids == list(range(1, 101))
    h.step(2.0)

    def ids_in(state: int) -> list[int]:
        return [s.goal_id for s in h.received["goal_status"] if s.state == state]

    assert wait_until(lambda: len(ids_in(STATUS.STATE_CANCELED)) >= 99, 10.0)
    assert ids_in(STATUS.STATE_ACCEPTED) == ids and ids_in(STATUS.STATE_CANCELED) == ids[:-1]
    assert h.service.goal is not None and h.service.goal.goal_id == 100


@pytest.mark.e2e
def test_an_accepted_goal_survives_a_restart_before_the_next_step(
    peer: Peer, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MJNAV_STATE_DIR", str(tmp_path))
    first = _planner(peer)
    reply = first.world.call("navigate", _request(3.45, 3.55))
    assert reply.accepted
    first.service.bus.close()  # the process dies before stepping
    second = _planner(peer)
    assert second.service.goal is not None and second.service.goal.goal_id == reply.goal_id
    assert second.service.next_id == reply.goal_id + 1


@pytest.mark.e2e
def test_event_topics_confirm_delivery_to_the_named_subscribers(peer: Peer) -> None:
    h = _planner(peer)
    goal = ros.pose_stamped(0.0, "map", Pose2D(3.45, 3.55, 0.0))
    receipts = h.world.put_confirmed("goal", [goal] * 20, timeout_s=10.0)
    assert receipts["planner"] == 20
    h.step(0.0)

    def accepted() -> list[int]:
        return [s.goal_id for s in h.received["goal_status"] if s.state == STATUS.STATE_ACCEPTED]

    assert wait_until(lambda: len(accepted()) >= 20, 10.0) and accepted() == list(range(1, 21))
    assert h.world.put_confirmed("cancel", [from_dict("std_msgs/msg/Empty")], timeout_s=10.0)["planner"] == 1
    h.step(0.2)
    assert wait_until(lambda: h.received["goal_status"][-1].state == STATUS.STATE_CANCELED, 10.0)
    assert h.received["goal_status"][-1].state == STATUS.STATE_CANCELED and h.service.goal is None


@pytest.mark.e2e
def test_a_lost_receipt_is_recovered_by_a_resend_that_is_delivered_once(peer: Peer) -> None:
    """A receipt lost on the way back (here the planner's first one is dropped) gets the event sent again with the
    same request id; the planner confirms the repeat but queues it once: three goals, three accepted."""
    h = _planner(peer)
    bus = h.service.bus
    send_receipt = bus._send_receipt
    dropped: list[str] = []

    def lose_the_first(key: str, request: bytes) -> None:
        if not dropped:
            dropped.append(key)
            return
        send_receipt(key, request)

    bus._send_receipt = lose_the_first  # type: ignore[method-assign]
    goal = ros.pose_stamped(0.0, "map", Pose2D(3.45, 3.55, 0.0))
    assert h.world.put_confirmed("goal", [goal] * 3, timeout_s=10.0)["planner"] == 3
    assert dropped == ["robot0/goal"]
    h.step(0.0)

    def accepted() -> list[int]:
        return [s.goal_id for s in h.received["goal_status"] if s.state == STATUS.STATE_ACCEPTED]

    assert wait_until(lambda: len(accepted()) >= 3, 10.0)
    h.step(0.2)
    assert accepted() == [1, 2, 3]


@pytest.mark.e2e
def test_an_event_nobody_named_receives_fails_loudly(peer: Peer) -> None:
    listener = peer()  # a subscriber that is not the planner (like the viewer) must not count as delivery
    listener.subscribe("goal")
    sender = peer()
    with pytest.raises(NotDelivered, match="planner 0/1") as err:
        sender.put_confirmed("goal", [ros.pose_stamped(0.0, "map", Pose2D(1.0, 1.0, 0.0))], timeout_s=1.0)
    assert err.value.missing == ["planner"]


def _following(t: float, goal_id: int, goal: object) -> object:
    return STATUS(header=ros.header(t, "map"), goal_id=goal_id, state=STATUS.STATE_FOLLOWING, error_code=0,
                  error_text="", goal=goal)  # fmt: skip


def _clear_scan(t: float) -> object:
    n = 90
    return ros.laser_scan(
        t, "laser", angle_min_rad=-math.pi, angle_increment_rad=2 * math.pi / n, scan_time_s=0.1,
        range_min_m=0.05, range_max_m=12.0, ranges_m=np.full(n, np.inf),
    )  # fmt: skip


def _at(h: Harness, t: float, pose: Pose2D, expect: dict[str, int]) -> object:
    """Step the controller at ``t`` with the robot at ``pose``; returns the newest cmd_vel."""
    h.send("scan", _clear_scan(t))
    h.send("ground_truth", ros.pose_stamped(t, "map", pose))
    h.step(t, expect)
    return h.received["cmd_vel"][-1]


def _arrivals(h: Harness) -> list[int]:
    """Goal ids of the controller's arrival reports so far."""
    return [f.goal_id for f in h.received["controller_feedback"] if f.state == FEEDBACK.STATE_ARRIVED]


@pytest.mark.e2e
def test_the_controller_turns_in_place_to_the_goal_yaw_then_reports_reached(peer: Peer) -> None:
    h = Harness(ControllerService, peer, ("cmd_vel", "controller_feedback"), pose_source="ground_truth",
                goal_tolerance_m=0.1, yaw_goal_tolerance_rad=0.05)  # fmt: skip
    line = np.c_[np.linspace(0.0, 2.0, 21), np.zeros(21)]
    goal = ros.pose_stamped(0.0, "map", Pose2D(2.0, 0.0, math.radians(120.0)))
    h.send("goal_status", _following(1.0, 1, goal))
    h.send("path", ros.path_msg(1.0, "map", line))
    assert _at(h, 1.0, Pose2D(1.0, 0.0, 0.0), {"cmd_vel": 1}).linear.x > 0  # driving along the path
    # At the position (within 0.1 m): turn in place, the shorter way (left), not reached yet.
    cmd = _at(h, 1.1, Pose2D(1.95, 0.02, 0.0), {"cmd_vel": 2})
    assert cmd.linear.x == 0.0 and cmd.angular.z == pytest.approx(1.0)  # clamped to rotate_max_radps
    # Turning drifts the centre a little beyond the xy tolerance: the goal stays latched, still only turning.
    cmd = _at(h, 1.2, Pose2D(1.88, 0.03, math.radians(110.0)), {"cmd_vel": 3})
    assert cmd.linear.x == 0.0 and cmd.angular.z == pytest.approx(1.5 * math.radians(10.0), rel=1e-6)
    cmd = _at(h, 1.3, Pose2D(1.88, 0.03, math.radians(115.0)), {"cmd_vel": 4})
    assert cmd.angular.z == pytest.approx(0.2)  # rotate_min_radps near the end
    assert not _arrivals(h)
    # Within 0.05 rad (2.9°) of 120°: stop, arrived (the planner reports it reached).
    cmd = _at(h, 1.4, Pose2D(1.88, 0.03, math.radians(122.0)), {"cmd_vel": 5})
    assert (cmd.linear.x, cmd.angular.z) == (0.0, 0.0)
    assert wait_until(lambda: _arrivals(h) == [1], 10.0)
    # Across ±180°: goal yaw 170°, heading -170° → turn right by 20°, not left by 340°.
    assert goal_yaw_error(ros.pose_msg(Pose2D(0, 0, math.radians(170.0))), math.radians(-170.0)) == pytest.approx(
        math.radians(-20.0)
    )


def test_a_goal_without_orientation_is_reached_with_any_heading(peer: Peer) -> None:
    h = Harness(ControllerService, peer, ("cmd_vel", "controller_feedback"), pose_source="ground_truth")
    line = np.c_[np.linspace(0.0, 2.0, 21), np.zeros(21)]
    goal = from_dict("geometry_msgs/msg/PoseStamped", {"header": {"frame_id": "map"},
                     "pose": {"position": {"x": 2.0}, "orientation": {"w": 0.0}}})  # fmt: skip
    h.send("goal_status", _following(1.0, 1, goal))
    h.send("path", ros.path_msg(1.0, "map", line))
    cmd = _at(h, 1.0, Pose2D(1.95, 0.0, 2.5), {"cmd_vel": 1})
    assert (cmd.linear.x, cmd.angular.z) == (0.0, 0.0)
    assert wait_until(lambda: _arrivals(h) == [1], 10.0)

"""A navigation mission driven over the bus: send goals, watch their status, and score the run.

:class:`MissionClient` is what ``mjnav demo`` (and the end-to-end tests) use: it publishes goals like any Zenoh
client would, waits on ``goal_status``, and measures the run from the sim's own topics — driven length from
``ground_truth``, clearance from ``scan``, collisions from ``sim_status`` — all in sim time.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from mjnav.bus import Bus
from mjnav.geometry import Pose2D
from mjnav.jsonsafe import json_safe
from mjnav.msgs import msg_class, ros

_STATUS = msg_class("mjnav_msgs/msg/GoalStatus")
_FINAL = {_STATUS.STATE_REACHED: "reached", _STATUS.STATE_FAILED: "failed", _STATUS.STATE_CANCELED: "canceled"}


@dataclass
class GoalOutcome:
    """How one goal ended.

    Attributes:
        goal: (x, y) in the map frame, metres.
        goal_id: the planner's id for it (0 when never accepted).
        result: ``reached``, ``failed``, ``canceled`` or ``timeout``.
        error_code: GoalStatus error code (0 = none).
        error_text: the planner's reason.
        time_s: sim seconds from sending the goal to its end.
        path_length_m: distance driven meanwhile (ground truth).
        start: robot position (x, y) when the goal was sent.
    """

    goal: tuple[float, float]
    goal_id: int = 0
    result: str = "timeout"
    error_code: int = 0
    error_text: str = ""
    time_s: float = 0.0
    path_length_m: float = 0.0
    start: tuple[float, float] = (math.nan, math.nan)


@dataclass
class _Track:
    length_m: float = 0.0
    last: Pose2D | None = None
    min_range_m: float = math.inf
    statuses: list[Any] = field(default_factory=list)


class MissionClient:
    """Sends goals and measures the run on a :class:`~mjnav.bus.Bus` (any namespace)."""

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self._lock = threading.Condition()
        self._track = _Track()
        self.clock = bus.subscribe("clock")
        self.sim_status = bus.subscribe("sim_status")
        self.truth = bus.subscribe("ground_truth", callback=self._on_truth)
        bus.subscribe("scan", callback=self._on_scan)
        bus.subscribe("goal_status", callback=self._on_status)
        self.goal_pub = bus.publisher("goal")
        self.cancel_pub = bus.publisher("cancel")

    # ----------------------------------------------------------------------------------------- measurements

    def _on_truth(self, msg: Any) -> None:
        pose = ros.pose2d(msg.pose)
        with self._lock:
            t = self._track
            if t.last is not None:
                t.length_m += t.last.distance_to(pose)
            t.last = pose

    def _on_scan(self, msg: Any) -> None:
        r = np.asarray(msg.ranges, dtype=np.float64)
        ok = np.isfinite(r) & (r >= msg.range_min)
        if ok.any():
            m = float(r[ok].min())
            with self._lock:
                self._track.min_range_m = min(self._track.min_range_m, m)

    def _on_status(self, msg: Any) -> None:
        with self._lock:
            self._track.statuses.append(msg)
            self._lock.notify_all()

    def now(self) -> float:
        """Latest sim time, seconds (NaN before the first clock)."""
        msg = self.clock.latest()
        return math.nan if msg is None else ros.seconds(msg.clock)

    def driven_m(self) -> float:
        """Distance driven since the client started, metres (ground truth)."""
        with self._lock:
            return self._track.length_m

    def min_range_m(self) -> float:
        """Smallest valid lidar range seen, metres (inf when none)."""
        with self._lock:
            return self._track.min_range_m

    def collisions(self) -> int:
        """Collisions counted by the sim so far (0 before its first status)."""
        msg = self.sim_status.latest()
        return 0 if msg is None else int(msg.collisions)

    def robot_pose(self) -> Pose2D | None:
        """Latest true pose, or None before the first."""
        msg = self.truth.latest()
        return None if msg is None else ros.pose2d(msg.pose)

    # ----------------------------------------------------------------------------------------------- goals

    def run_goal(self, x: float, y: float, *, timeout_s: float, wall_timeout_s: float = math.inf) -> GoalOutcome:
        """Send goal (x, y) and wait until it is reached, fails, or ``timeout_s`` of sim time pass (then cancel).

        ``wall_timeout_s`` bounds the wait in wall time too (a stalled sim must not hang the caller).
        """
        outcome = GoalOutcome(goal=(x, y))
        pose = self.robot_pose()
        if pose is not None:
            outcome.start = (pose.x, pose.y)
        with self._lock:
            seen = len(self._track.statuses)
        length0, t0 = self.driven_m(), self.now()
        if not self.goal_pub.wait_for_subscribers(10.0):
            raise RuntimeError(f"nobody subscribes to {self.bus.key('goal')}: is the planner running?")
        self.goal_pub.put(ros.pose_stamped(t0 if math.isfinite(t0) else 0.0, "map", Pose2D(x, y, 0.0)))
        wall_deadline = time.monotonic() + wall_timeout_s
        with self._lock:
            while True:
                for msg in self._track.statuses[seen:]:
                    if outcome.goal_id == 0 and msg.state == _STATUS.STATE_ACCEPTED:
                        outcome.goal_id = int(msg.goal_id)
                    if msg.goal_id == outcome.goal_id and msg.state in _FINAL:
                        outcome.result = _FINAL[msg.state]
                        outcome.error_code = int(msg.error_code)
                        outcome.error_text = msg.error_text
                        break
                seen = len(self._track.statuses)
                if outcome.result != "timeout":
                    break
                now = self.now()
                if (math.isfinite(now) and math.isfinite(t0) and now - t0 >= timeout_s) or (
                    time.monotonic() >= wall_deadline
                ):
                    self.cancel_pub.put(msg_class("std_msgs/msg/Empty")())
                    break
                self._lock.wait(0.1)
        outcome.time_s = self.now() - t0
        outcome.path_length_m = self.driven_m() - length0
        return outcome


@dataclass
class MissionSummary:
    """The figures ``mjnav demo --json`` prints (see README)."""

    reached: bool
    collisions: int
    time_s: float
    path_length_m: float
    optimal_length_m: float
    v_max_mps: float
    min_clearance_m: float
    goals: list[dict[str, Any]]

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dict: top-level figures rounded to 0.1 mm / 0.1 ms, non-finite floats as None."""
        d = asdict(self)
        for k, v in d.items():
            if isinstance(v, float) and math.isfinite(v):
                d[k] = round(v, 4)
        return json_safe(d)

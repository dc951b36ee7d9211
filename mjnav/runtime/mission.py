"""A navigation mission driven over the bus: send goals, watch their status, and score the run.

:class:`MissionClient` is what ``mjnav demo`` (and the end-to-end tests) use: it publishes goals like any Zenoh
client would, waits on ``goal_status``, and measures the run from the sim's own topics — driven length from
``ground_truth``, clearance from ``scan``, collisions from ``sim_status`` — all in sim time.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from mjnav.bus import Bus
from mjnav.geometry import Pose2D, PoseHistory
from mjnav.jsonsafe import json_safe
from mjnav.msgs import msg_class, ros
from mjnav.runtime.participant import LockstepParticipant

_STATUS = msg_class("mjnav_msgs/msg/GoalStatus")
_FINAL = {_STATUS.STATE_REACHED: "reached", _STATUS.STATE_FAILED: "failed", _STATUS.STATE_CANCELED: "canceled"}
#: A goal the planner reports reached counts as reached only when the robot's true position is this close to it
#: (metres; the controller stops within its goal tolerance of where the robot *believes* it is): farther, the
#: localisation was wrong and the result is ``mislocalized``.
ARRIVAL_TOLERANCE_M = 0.5


@dataclass
class GoalOutcome:
    """How one goal ended.

    Attributes:
        goal: (x, y) in the map frame, metres.
        goal_id: the planner's id for it (0 when never accepted).
        result: ``reached``, ``failed``, ``canceled``, ``timeout`` or ``mislocalized`` (the planner reported it
            reached, but the true position was more than :data:`ARRIVAL_TOLERANCE_M` from it).
        true_distance_m: the robot's true distance from the goal when the goal ended (NaN without a true pose).
        error_code: GoalStatus error code (0 = none).
        error_text: the planner's reason.
        time_s: sim seconds from sending the goal to its end (the stamp of its final status: for a goal reached,
            when the robot arrived).
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
    true_distance_m: float = math.nan


@dataclass
class _Track:
    length_m: float = 0.0
    last: Pose2D | None = None
    min_range_m: float = math.inf
    min_clearance_m: float = math.inf  # footprint-to-obstacle distance at the true poses (with a clearance model)
    overlaps: int = 0  # times the footprint went from clear to overlapping an obstacle
    overlapping: bool = False
    statuses: list[Any] = field(default_factory=list)
    truth: PoseHistory = field(default_factory=lambda: PoseHistory(horizon_s=2.0))
    ate_sq_sum: float = 0.0  # Σ |estimated − true position|², over every estimate received while measuring
    ate_n: int = 0
    measuring: bool = False  # a run_goals job is active: the figures accumulate only then (sim time decides)
    collisions_at_end: int | None = None  # the sim's count when the last job ended
    map_at_end: Any = None  # the newest ``map`` when the last job ended


@dataclass
class _Job:
    """Goals being run: sent, watched and ended inside the client's lockstep steps."""

    pending: list[tuple[float, float]]
    timeout_s: float
    outcomes: list[GoalOutcome] = field(default_factory=list)
    current: GoalOutcome | None = None
    t0: float = math.nan
    length0: float = 0.0
    seen: int = 0
    done: bool = False
    final_pose: Pose2D | None = None
    started: tuple[float, float] | None = None  # (sim, wall) when the first goal left
    ended: tuple[float, float] | None = None  # (sim, wall) when the last goal ended


class MissionClient(LockstepParticipant):
    """Sends goals and measures the run on a :class:`~mjnav.bus.Bus` (any namespace).

    From its first :meth:`run_goals` on, the client is a lockstep participant called ``name``: it steps every
    ``period_s`` of sim time, in the clock's callback, and sends goals, cancels and ends them only in those steps,
    reporting each on ``lockstep`` like a service. With the sim in lockstep and the client among its
    ``lockstep_participants`` (sim time then starts when the first goals are handed over), a mission is repeatable
    to the last bit: goals leave at the same sim times, and everything it measures — driven length, clearance,
    collisions, the final pose — is read from messages committed at the same clock ticks.
    """

    def __init__(
        self,
        bus: Bus,
        *,
        name: str = "mission",
        period_s: float = 0.05,
        initial_pose: Pose2D | None = None,
        initial_sigma: tuple[float, float] = (0.05, 0.05),
        clearance: Callable[[float, float], float] | None = None,
    ) -> None:
        """``initial_pose``: sent on ``initialpose`` (σ ``initial_sigma`` = (m, rad)) in the client's first step,
        before the first goal, as an operator tells the robot where it starts (what SLAM starts from).
        ``clearance``: footprint-to-obstacle distance (m) of the robot at a true position (x, y), e.g.
        :meth:`mjnav.sim.truth.FootprintClearance.clearance_m`; evaluated at every ``truth`` pose while goals run
        (:meth:`min_clearance_m`, :meth:`overlaps`)."""
        self._clearance = clearance
        self._init_participant(bus, name, period_s)
        self._initial: Any = None
        if initial_pose is not None:
            sxy, syaw = initial_sigma
            self._initial = (initial_pose, np.diag([sxy**2, sxy**2, syaw**2]))
        self._track = _Track()
        self._job: _Job | None = None
        #: True pose when the last :meth:`run_goals` ended (None before).
        self.final_pose: Pose2D | None = None
        #: Sim seconds per wall second from the first goal's start to the last goal's end (NaN before).
        self.achieved_rtf = math.nan
        self.sim_status = bus.subscribe("sim_status")
        self.truth = bus.subscribe("truth", callback=self._on_truth)
        bus.subscribe("pose", callback=self._on_estimate)
        self.map = bus.subscribe("map")
        self.initial_pub = bus.publisher("initialpose")
        bus.subscribe("scan", callback=self._on_scan)
        bus.subscribe("goal_status", callback=self._on_status)
        self.goal_pub = bus.publisher("goal")
        self.cancel_pub = bus.publisher("cancel")
        self.clock = self._subscribe_clock()

    # ----------------------------------------------------------------------------------------- measurements

    def _on_truth(self, msg: Any) -> None:
        pose = ros.pose2d(msg.pose)
        with self._lock:
            t = self._track
            t.truth.add(ros.seconds(msg.header.stamp), pose)
            if t.last is not None and t.measuring:
                t.length_m += t.last.distance_to(pose)
            t.last = pose
            if self._clearance is not None and t.measuring:
                c = self._clearance(pose.x, pose.y)
                t.min_clearance_m = min(t.min_clearance_m, c)
                if c < 0.0 and not t.overlapping:
                    t.overlaps += 1
                t.overlapping = c < 0.0

    def _on_estimate(self, msg: Any) -> None:
        """Absolute trajectory error of SLAM's ``pose`` against the true pose at its stamp."""
        stamp = ros.seconds(msg.header.stamp)
        est = ros.pose_of(msg)
        with self._lock:
            true = self._track.truth.at(stamp)
            if true is not None and self._track.measuring:
                self._track.ate_sq_sum += (est.x - true.x) ** 2 + (est.y - true.y) ** 2
                self._track.ate_n += 1

    def ate_rms_m(self) -> float:
        """RMS position error of every SLAM ``pose`` received while goals ran against the truth at its stamp,
        metres (NaN without)."""
        with self._lock:
            t = self._track
            return math.sqrt(t.ate_sq_sum / t.ate_n) if t.ate_n else math.nan

    def _on_scan(self, msg: Any) -> None:
        r = np.asarray(msg.ranges, dtype=np.float64)
        ok = np.isfinite(r) & (r >= msg.range_min)
        if ok.any():
            m = float(r[ok].min())
            with self._lock:
                if self._track.measuring:
                    self._track.min_range_m = min(self._track.min_range_m, m)

    def _on_status(self, msg: Any) -> None:
        with self._lock:
            self._track.statuses.append(msg)

    def now(self) -> float:
        """Latest sim time, seconds (NaN before the first clock)."""
        with self._lock:
            return self._now

    def driven_m(self) -> float:
        """Distance driven while goals ran, metres (ground truth)."""
        with self._lock:
            return self._track.length_m

    def min_range_m(self) -> float:
        """Smallest valid lidar range seen while goals ran, metres (inf when none)."""
        with self._lock:
            return self._track.min_range_m

    def min_clearance_m(self) -> float:
        """Smallest footprint-to-obstacle distance at the true poses received while goals ran, metres (NaN without
        a ``clearance`` model or before any pose); negative: the footprint overlapped an obstacle."""
        with self._lock:
            c = self._track.min_clearance_m
            return c if math.isfinite(c) else math.nan

    def overlaps(self) -> int:
        """How many times the footprint went from clear to overlapping an obstacle while goals ran."""
        with self._lock:
            return self._track.overlaps

    def final_map(self) -> Any:
        """The newest ``map`` (``nav_msgs/OccupancyGrid``) when the last :meth:`run_goals` ended, whenever this is
        called (sim time may go on after the job); the newest one before that; None without a map."""
        with self._lock:
            if not self._track.measuring and self._track.map_at_end is not None:
                return self._track.map_at_end
        return self.map.latest()

    def collisions(self) -> int:
        """Collisions counted by the sim: while goals run, so far; after, at the end of the last goal (0 before
        the sim's first status)."""
        with self._lock:
            if not self._track.measuring and self._track.collisions_at_end is not None:
                return self._track.collisions_at_end
        msg = self.sim_status.latest()
        return 0 if msg is None else int(msg.collisions)

    def robot_pose(self) -> Pose2D | None:
        """Latest true pose, or None before the first."""
        with self._lock:
            return self._track.last

    # ----------------------------------------------------------------------------------------------- goals

    def _step(self, t: float) -> None:
        """One lockstep step (under the lock): end the current goal if its status says so, then send the next."""
        if self._initial is not None:
            self.initial_pub.put(ros.pose_with_covariance_stamped(t, "map", *self._initial))
            self._initial = None
        job = self._job
        if job is None or job.done:
            return
        track = self._track
        current = job.current
        if current is not None:
            ended = t
            for msg in track.statuses[job.seen :]:
                if current.goal_id == 0 and msg.state == _STATUS.STATE_ACCEPTED:
                    current.goal_id = int(msg.goal_id)
                if msg.goal_id == current.goal_id and msg.state in _FINAL:
                    current.result = _FINAL[msg.state]
                    current.error_code = int(msg.error_code)
                    current.error_text = msg.error_text
                    ended = ros.seconds(msg.header.stamp)  # when it ended (the robot arrived), not when heard
                    break
            job.seen = len(track.statuses)
            if current.result == "timeout" and t - job.t0 >= job.timeout_s:
                self.cancel_pub.put(msg_class("std_msgs/msg/Empty")())
            elif current.result == "timeout":
                return
            current.time_s = ended - job.t0
            current.path_length_m = track.length_m - job.length0
            if track.last is not None:
                current.true_distance_m = math.hypot(track.last.x - current.goal[0], track.last.y - current.goal[1])
                if current.result == "reached" and current.true_distance_m > ARRIVAL_TOLERANCE_M:
                    current.result = "mislocalized"
                    current.error_text = (
                        f"reported reached, but the robot is {current.true_distance_m:.2f} m from the goal "
                        f"(more than {ARRIVAL_TOLERANCE_M:g} m): its localisation was wrong"
                    )
            job.outcomes.append(current)
            job.current = None
            if current.result != "reached":
                job.pending.clear()
        if not job.pending:
            job.done = True
            job.final_pose = track.last
            job.ended = (t, time.monotonic())
            self._stop_measuring()
            return
        if job.started is None:
            job.started = (t, time.monotonic())
        x, y = job.pending.pop(0)
        outcome = GoalOutcome(goal=(x, y))
        if track.last is not None:
            outcome.start = (track.last.x, track.last.y)
        job.current, job.t0, job.length0, job.seen = outcome, t, track.length_m, len(track.statuses)
        self.goal_pub.put(ros.position_goal(t, "map", x, y))  # any final heading: demo goals are positions

    def run_goals(
        self, goals: list[tuple[float, float]], *, timeout_s: float, wall_timeout_s: float = math.inf
    ) -> list[GoalOutcome]:
        """Run goals (x, y) in order, each until reached, failed, or ``timeout_s`` of sim time (then canceled);
        stops after the first goal not reached. Returns the outcomes of the goals run.

        Goals are sent in the client's own steps (sim time), so the outcome does not depend on when this is
        called or how fast the machine is. ``wall_timeout_s`` bounds the wait in wall time (a stalled sim must not
        hang the caller): the goal in progress then ends as ``timeout``.

        Raises:
            RuntimeError: nobody subscribes to the goal topic (no planner) within 10 s.
        """
        if not self.goal_pub.wait_for_subscribers(10.0):
            raise RuntimeError(f"nobody subscribes to {self.bus.key('goal')}: is the planner running?")
        job = _Job(pending=list(goals), timeout_s=timeout_s)
        deadline = time.monotonic() + wall_timeout_s
        with self._lock:
            self._job = job
            self._track.measuring = True
        self._participate()  # the first goal leaves at the first clock from here on
        with self._lock:
            while not job.done:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    if job.current is not None:
                        self.cancel_pub.put(msg_class("std_msgs/msg/Empty")())
                        job.current.time_s = self._now - job.t0
                        job.current.path_length_m = self._track.length_m - job.length0
                        job.outcomes.append(job.current)
                    job.done = True
                    job.final_pose = self._track.last
                    self._stop_measuring()
                    break
                self._lock.wait(min(remaining, 0.5))
            self._job = None
        self.final_pose = job.final_pose
        if job.started is not None and job.ended is not None and job.ended[1] > job.started[1]:
            self.achieved_rtf = (job.ended[0] - job.started[0]) / (job.ended[1] - job.started[1])
        return job.outcomes

    def _stop_measuring(self) -> None:
        """(Under the lock.) The job ended: freeze the figures at this sim time, whenever the caller reads them."""
        msg = self.sim_status.latest()
        self._track.collisions_at_end = 0 if msg is None else int(msg.collisions)
        self._track.map_at_end = self.map.latest()
        self._track.measuring = False

    def run_goal(self, x: float, y: float, *, timeout_s: float, wall_timeout_s: float = math.inf) -> GoalOutcome:
        """Send goal (x, y) and wait until it is reached, fails, or ``timeout_s`` of sim time pass (then cancel)."""
        outcomes = self.run_goals([(x, y)], timeout_s=timeout_s, wall_timeout_s=wall_timeout_s)
        return outcomes[0] if outcomes else GoalOutcome(goal=(x, y))


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
    seed: int | None = None
    lockstep: bool = True
    final_pose: list[float] | None = None
    wall_s: float = math.nan
    achieved_rtf: float = math.nan
    pose_source: str = ""
    known_map: bool = False
    ate_rms_m: float = math.nan
    loop_closures: int | None = None
    map_accuracy: list[float] | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dict: top-level figures rounded to 0.1 mm / 0.1 ms, non-finite floats as None."""
        d = asdict(self)
        for k, v in d.items():
            if isinstance(v, float) and math.isfinite(v):
                d[k] = round(v, 4)
        return json_safe(d)

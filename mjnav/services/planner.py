"""The planner service: ``goal`` → ``plan`` on the ``costmap``, with goal status and replanning.

A goal (``geometry_msgs/PoseStamped`` in ``map``) is accepted, planned with the configured algorithm from the robot's
pose, and published as ``plan`` (``nav_msgs/Path``, cell centres). ``goal_status`` reports accepted → planning →
following, or failed with a typed reason (start/goal occupied, outside the map, no path). While a goal is active
the planner replans when a new costmap blocks the current path, and periodically when a cheaper route appeared;
the goal fails when it becomes unreachable or occupied.

Goals come two ways: on the ``goal`` topic (fire and forget, like RViz's 2D Goal Pose), or as a request on the
``navigate`` endpoint (like Nav2's NavigateToPose action), which is answered at once — accepted with the goal id its
``goal_status`` messages will carry, or rejected with a typed code (frame not ``map``, outside the costmap, in an
obstacle). Goals, cancels and navigate requests take effect at the planner's next step in the order they arrived
(requests are staged by sim time like messages: :meth:`mjnav.bus.Bus.defer`,
:class:`mjnav.runtime.simtime.SimTimeGate`); a newer goal supersedes the active one.

The planner owns every goal: it alone publishes ``goal_status``. The controller reports on ``controller_feedback``;
its arrival ends the goal as reached (stamped when the robot arrived), its "no progress" as failed with
``ERROR_TIMEOUT``; ``cancel`` ends a goal as canceled. ``plan`` and ``goal_status`` are latched, so a smoother or
controller that (re)starts later gets the current ones from the transport, with no periodic re-send. Unknown space
is traversable at an extra cost (see :mod:`mjnav.planning.costmap`). A costmap older than ``costmap_timeout_s`` is
not planned on: the plan is withdrawn (the robot stops) until a fresh one arrives. The costmap may grow between two
plans (it follows what the robot explores); the current route is carried over to the new grid.

The active goal and the next goal id are checkpointed in the run's state directory, so a planner restarted mid-goal
(``mjnav up`` restarts crashed and hung services) resumes the same goal under the same id.
"""

from __future__ import annotations

import json
import math
import threading
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from mjnav.geometry import Pose2D
from mjnav.mapping.frame import GridFrame
from mjnav.msgs import decode, encode, msg_class, ros
from mjnav.planning import (
    ALGORITHMS,
    GoalOccupied,
    NoPathFound,
    OutsideMap,
    PlanningError,
    StartOccupied,
    path_cost,
    plan_grid,
)
from mjnav.planning.costmap import INSCRIBED, clear_disc, planning_grid
from mjnav.runtime import Service
from mjnav.runtime.checkpoint import Checkpoint
from mjnav.runtime.pose import PoseInput

_STATUS = "mjnav_msgs/msg/GoalStatus"
_GOAL = "geometry_msgs/msg/PoseStamped"
_NAVIGATE_REPLY = "mjnav_msgs/msg/NavigateResponse"


@dataclass(frozen=True)
class PlannerConfig:
    """Planner settings (``services/planner.toml``).

    Attributes:
        rate_hz: loop rate (sim time).
        algorithm: any of :data:`mjnav.planning.ALGORITHMS` (``jps`` falls back to ``astar`` — it takes no cost grid).
        heuristic, connectivity, weights: passed to :func:`~mjnav.planning.plan_grid`.
        pose_source: ``slam`` (SLAM's ``map → odom`` ∘ odometry, :mod:`mjnav.runtime.pose`), ``ground_truth``
            or ``odom`` (the plan is in ``map``; odom drifts).
        cost_weight: relative extra cost of crossing a cell at cost 98 (1 = twice its length; keeps paths off walls).
            At 2 the maze's plan rounded a wall's end 0.22 m from it, where the controller's check stops the
            robot (seed 0: stuck); at 4 it keeps the smoother's 0.3 m.
        unknown_cost: relative extra cost of crossing an unknown cell.
        start_clearance_m: free a disc of this radius around the robot before planning (it may stand in the
            inscribed band after passing close to a wall).
        replan_period_s: how often (sim s) a cheaper route is looked for while following.
        improvement: switch to a new route only when it is cheaper than this fraction of the remaining one.
        unknown_margin_m: the costmap covers what the robot has seen; a goal (or the robot, or the route) up to this
            far outside it is planned to through unknown space (the grid grown with unknown cells); a goal further
            out fails with ``ERROR_OUTSIDE_MAP``.
        costmap_timeout_s: a costmap stamped longer ago than this (sim s) is stale: not planned on, and the plan is
            withdrawn until a fresh one arrives (the mapper publishes at 2 Hz).
        off_route_m: a robot further than this from its route (SLAM corrected its pose across it, or the
            controller swerved around something) gets a new route from where it is at the next costmap, as for
            a blocked one; below the controller's ``lost_distance_m`` (1 m), beyond which it stops and waits for
            one. Before, the planner kept a route it found valid and the controller waited for 20 s of no
            progress (issue 30, the wall map).
        cycle_distance_m: the robot is cycling when it is back at a place (a :data:`PLACE_M` square) it passed
            at least this far of driving ago, and its route from there is no shorter than it was then (by
            :data:`PROGRESS_M`): each route it tried through unknown space turned out closed, and the next one
            looks just as short (issue 30: 258 m of shuttling along a wall with a gap 3 m further on). The goal's
            unknown space then costs ``cycle_unknown_factor`` times more, and the planner plans afresh, so known
            routes win over the next guess. 0 = never.
        cycle_unknown_factor: how much dearer unknown space becomes for the goal at each cycle (> 1; at most
            :data:`MAX_UNKNOWN_FACTOR` times ``unknown_cost`` in all).
        seed: seed of the potential field's random escapes.
    """

    rate_hz: float = 5.0
    algorithm: str = "astar"
    heuristic: str = "octile"
    connectivity: int = 8
    weights: tuple[float, float] = (1.0, 1.0)
    pose_source: Literal["slam", "ground_truth", "odom"] = "slam"
    cost_weight: float = 4.0
    unknown_cost: float = 0.5
    start_clearance_m: float = 0.25
    replan_period_s: float = 2.0
    improvement: float = 0.9
    unknown_margin_m: float = 10.0
    costmap_timeout_s: float = 3.0
    off_route_m: float = 0.6
    cycle_distance_m: float = 10.0
    cycle_unknown_factor: float = 4.0
    seed: int = 0

    def __post_init__(self) -> None:
        if self.algorithm not in ALGORITHMS:
            raise ValueError(f"algorithm must be one of {list(ALGORITHMS)}, got {self.algorithm!r}")
        if self.connectivity not in (4, 8):
            raise ValueError(f"connectivity must be 4 or 8, got {self.connectivity}")
        if not 0 < self.improvement <= 1:
            raise ValueError(f"improvement must be in (0, 1], got {self.improvement}")
        if not self.costmap_timeout_s > 0:
            raise ValueError(f"costmap_timeout_s must be > 0, got {self.costmap_timeout_s}")
        if not self.unknown_margin_m >= 0:
            raise ValueError(f"unknown_margin_m must be >= 0, got {self.unknown_margin_m}")
        if not self.off_route_m > 0:
            raise ValueError(f"off_route_m must be > 0, got {self.off_route_m}")
        if not self.cycle_distance_m >= 0:
            raise ValueError(f"cycle_distance_m must be >= 0, got {self.cycle_distance_m}")
        if not self.cycle_unknown_factor > 1:
            raise ValueError(f"cycle_unknown_factor must be > 1, got {self.cycle_unknown_factor}")


_ERRORS: list[tuple[type[PlanningError], str]] = [
    (StartOccupied, "ERROR_START_OCCUPIED"),
    (GoalOccupied, "ERROR_GOAL_OCCUPIED"),
    (OutsideMap, "ERROR_OUTSIDE_MAP"),
    (NoPathFound, "ERROR_NO_PATH"),
]


#: Side of the squares (metres) the planner remembers the robot passing through, to notice it cycling.
PLACE_M = 1.0
#: A route from a place shorter by at least this (metres) than at the last pass there is progress.
PROGRESS_M = 1.0
#: The most a goal's cycles multiply ``unknown_cost`` by.
MAX_UNKNOWN_FACTOR = 256.0


@dataclass
class _Goal:
    goal_id: int
    msg: Any
    pose: Pose2D
    cells: Any = None  # (N, 2) current plan cells, in the grid of ``frame``
    frame: GridFrame | None = None  # the costmap grid the plan's cells index
    last_plan_t: float = -math.inf
    following: bool = False
    path_msg: Any = None
    withdrawn: bool = False  # the plan was withdrawn (stale costmap) and must be sent again
    unknown_factor: float = 1.0  # multiplies unknown_cost for this goal; raised at each cycle
    cycles: int = 0
    driven_m: float = 0.0
    last_xy: tuple[float, float] | None = None
    # Place (PLACE_M square) -> (driven_m, route length from there) at the robot's last pass through it.
    places: dict[tuple[int, int], tuple[float, float]] = field(default_factory=dict)


class PlannerService(Service[PlannerConfig]):
    """Plans on the costmap for each goal and keeps the plan valid."""

    name = "planner"
    config_class = PlannerConfig
    #: Read from ``self.config`` at every use: ``mjnav param set planner KEY VALUE`` changes them while running.
    runtime_settable = frozenset({"algorithm", "heuristic", "cost_weight", "unknown_cost", "replan_period_s"})

    def configure(self) -> None:
        # Goals, cancels and accepted navigate requests, in arrival order: ("goal", msg, id or 0) / ("cancel", …).
        self._lock = threading.Lock()  # guards _inbox, next_id, _unstepped and the checkpoint file
        self._inbox: list[tuple[str, Any, int]] = []
        self._unstepped: tuple[int, Any] | None = None  # the newest navigate goal accepted but not yet stepped
        self.goals = self.bus.subscribe("goal", callback=lambda msg: self._post("goal", msg, 0))
        self.cancels = self.bus.subscribe("cancel", callback=lambda _msg: self._post("cancel", None, 0))
        self.costmap = self.bus.subscribe("costmap")
        self.feedback = self.bus.subscribe("controller_feedback")
        self.pose_in = PoseInput(self.bus, self.config.pose_source)
        self.plan_pub = self.bus.publisher("plan")
        self.status_pub = self.bus.publisher("goal_status")
        self.status_cls = msg_class(_STATUS)
        self.feedback_cls = msg_class("mjnav_msgs/msg/ControllerFeedback")
        self.rng = np.random.default_rng(self.config.seed)
        self.goal: _Goal | None = None
        self.next_id = 1
        self._restore()
        self.bus.serve("navigate", self._on_navigate)
        # Load the compiled search kernels now, not when the first goal arrives.
        free = np.zeros((4, 4), dtype=bool)
        plan_grid(
            free,
            (0, 0),
            (3, 3),
            algorithm=self.config.algorithm,
            heuristic=self.config.heuristic,
            connectivity=self.config.connectivity,
            weights=self.config.weights,
            cost=None if self.config.algorithm == "jps" else np.zeros((4, 4)),
            rng=self.rng,
        )

    def activate(self) -> None:
        # Also called again when the sim clock restarts: keep the goal, forget everything timed.
        self.grid_stamp = -1.0
        self.pose_in.reset()
        if self.goal is not None:
            self.goal.cells = None
            self.goal.last_plan_t = -math.inf

    def starved(self) -> str:
        if self.goal is None:
            return ""
        if self.costmap.latest() is None:
            return f"the costmap on {self.costmap.key} (goal {self.goal.goal_id} waits for it)"
        if self.pose_in.latest() is None:
            return f"the robot's pose ({self.pose_in.describe()})"
        return ""

    # ----------------------------------------------------------------------------------------------- status

    def _status(self, now: float, goal: _Goal, state: str, error: str = "ERROR_NONE", text: str = "") -> None:
        """Publish the goal's status, stamped ``now`` (for an end the controller reported: when it happened)."""
        cls = self.status_cls
        self.status_pub.put(
            cls(
                header=ros.header(now, "map"),
                goal_id=goal.goal_id,
                state=getattr(cls, f"STATE_{state}"),
                error_code=getattr(cls, error),
                error_text=text,
                goal=goal.msg,
            )
        )
        if state in ("FAILED", "CANCELED"):
            self.log.info("goal %d %s %s", goal.goal_id, state.lower(), text)

    def _end(
        self, now: float, state: str, error: str = "ERROR_NONE", text: str = "", stamp: float | None = None
    ) -> None:
        """End the active goal: its final status (stamped ``stamp``, default ``now``) and an empty plan."""
        assert self.goal is not None
        self._status(now if stamp is None else stamp, self.goal, state, error, text)
        self.plan_pub.put(ros.path_msg(now, "map", np.zeros((0, 2))))
        self.goal = None
        self._save()

    # ----------------------------------------------------------------------------------------------- loop

    # ----------------------------------------------------------------------------------------------- inputs

    def _post(self, kind: str, msg: Any, goal_id: int) -> None:
        with self._lock:
            self._inbox.append((kind, msg, goal_id))

    def _on_navigate(self, request: Any) -> Any:
        """Answer a ``navigate`` request (in Zenoh's thread): accept with a fresh goal id, or reject with a code."""
        reply = msg_class(_NAVIGATE_REPLY)
        goal = request.goal
        rejection = self._check_goal(goal)
        if rejection is not None:
            code, text = rejection
            self.log.info("navigate request refused: %s", text)
            return reply(accepted=False, goal_id=0, error_code=getattr(self.status_cls, code), error_text=text)
        with self._lock:
            goal_id = self.next_id
            self.next_id += 1
            self._unstepped = (goal_id, goal)
        self._save()  # accepted means kept: a planner restarted before its next step resumes this goal
        self.bus.defer(lambda: self._post("goal", goal, goal_id))
        return reply(accepted=True, goal_id=goal_id, error_code=self.status_cls.ERROR_NONE, error_text="")

    def _check_goal(self, goal: Any) -> tuple[str, str] | None:
        """(GoalStatus error name, reason) when ``goal`` cannot be served on the newest costmap, else None."""
        if goal.header.frame_id not in ("", "map"):
            return "ERROR_INVALID_GOAL", f"goal frame {goal.header.frame_id!r} is not 'map'"
        costmap_msg = self.costmap.latest()
        if costmap_msg is None:
            return None  # nothing known yet: the first plan decides
        cells, frame = ros.grid_frame(costmap_msg)
        x, y = goal.pose.position.x, goal.pose.position.y
        outside = self._too_far_outside(frame, x, y)
        if outside is not None:
            return "ERROR_OUTSIDE_MAP", outside
        row, col = frame.world_to_cell(x, y)
        if frame.contains(row, col) and cells[row, col] >= INSCRIBED:
            return "ERROR_GOAL_OCCUPIED", (
                f"goal ({x:.2f}, {y:.2f}) m is in an obstacle or closer to one than the robot's radius "
                f"(cost {cells[row, col]} at cell ({row}, {col}))"
            )
        return None

    def _too_far_outside(self, frame: GridFrame, x: float, y: float) -> str | None:
        """Why goal (x, y) is out of reach of planning on the costmap ``frame`` (further than ``unknown_margin_m``
        outside it), or None."""
        x0, x1, y0, y1 = _extent(frame)
        beyond = math.hypot(max(x0 - x, 0.0, x - x1), max(y0 - y, 0.0, y - y1))
        if beyond <= self.config.unknown_margin_m:
            return None
        return (
            f"goal ({x:.2f}, {y:.2f}) m lies outside the costmap, x {x0:.2f}..{x1:.2f} m, y {y0:.2f}..{y1:.2f} m: "
            f"{beyond:.2f} m beyond it, more than planner.unknown_margin_m = {self.config.unknown_margin_m:g} m"
        )

    # ----------------------------------------------------------------------------------------------- loop

    def _on_feedback(self, now: float) -> None:
        """The controller's reports on the active goal: arrived ends it as reached, no progress as failed."""
        fb = self.feedback_cls
        for msg in self.feedback.drain():
            if self.goal is None or msg.goal_id != self.goal.goal_id:
                continue  # an earlier goal's, or one this planner does not own (restarted meanwhile)
            stamp = ros.seconds(msg.header.stamp)
            if msg.state == fb.STATE_ARRIVED:
                self.log.info("goal %d reached", msg.goal_id)
                self._end(now, "REACHED", stamp=stamp)
            elif msg.state == fb.STATE_NO_PROGRESS:
                self.log.warning("goal %d: %s", msg.goal_id, msg.text)
                self._end(now, "FAILED", "ERROR_TIMEOUT", msg.text, stamp=stamp)
            elif msg.state == fb.STATE_HALTED:
                self.log.debug("goal %d: the controller halted: %s", msg.goal_id, msg.text)

    def step(self, now: float) -> None:
        self._on_feedback(now)
        with self._lock:
            inbox, self._inbox = self._inbox, []
        for kind, msg, goal_id in inbox:
            if kind == "cancel":
                if self.goal is not None:
                    self._end(now, "CANCELED", text="canceled by request")
            else:
                self._accept(now, msg, goal_id)
        if self.goal is not None:
            self._plan(now)

    def _send(self, now: float, goal: _Goal) -> None:
        self.plan_pub.put(goal.path_msg)
        self._status(now, goal, "FOLLOWING")

    def _accept(self, now: float, msg: Any, goal_id: int = 0) -> None:
        """Make ``msg`` the active goal under ``goal_id`` (0: a goal from the topic, given the next id)."""
        with self._lock:
            if not goal_id:
                goal_id = self.next_id
                self.next_id += 1
            if self._unstepped is not None and self._unstepped[0] == goal_id:
                self._unstepped = None
        if self.goal is not None:
            self._end(now, "CANCELED", text=f"superseded by goal {goal_id}")
        goal = _Goal(goal_id, msg, ros.pose2d(msg.pose))
        self.goal = goal
        self._save()
        self._status(now, goal, "ACCEPTED")
        if msg.header.frame_id not in ("", "map"):
            self._end(now, "FAILED", "ERROR_INVALID_GOAL", f"goal frame {msg.header.frame_id!r} is not 'map'")
            return
        self.log.info("goal %d: (%.2f, %.2f)", goal.goal_id, goal.pose.x, goal.pose.y)
        self._status(now, goal, "PLANNING")

    def _plan(self, now: float) -> None:
        goal = self.goal
        assert goal is not None
        costmap_msg = self.costmap.latest()
        self.pose_in.update()
        latest = self.pose_in.latest()
        if costmap_msg is None or latest is None:
            return  # planning starts with the first costmap and pose
        stamp = ros.seconds(costmap_msg.header.stamp)
        if now - stamp > self.config.costmap_timeout_s:
            if not goal.withdrawn:
                self.log.warning(
                    "goal %d: the costmap is %.1f s old (limit %.1f s): plan withdrawn until a fresh one arrives",
                    goal.goal_id, now - stamp, self.config.costmap_timeout_s,
                )  # fmt: skip
                self.plan_pub.put(ros.path_msg(now, "map", np.zeros((0, 2))))
                goal.withdrawn = True
            return
        if goal.withdrawn:
            goal.withdrawn = False
            goal.cells = None  # plan afresh on the fresh costmap
        robot = latest[1]
        self._watch_cycles(now, goal, robot)
        fresh = stamp != self.grid_stamp
        if goal.cells is not None and not fresh:
            return
        cells, frame = ros.grid_frame(costmap_msg)
        outside = self._too_far_outside(frame, goal.pose.x, goal.pose.y)
        if outside is not None:
            self._end(now, "FAILED", "ERROR_OUTSIDE_MAP", outside)
            return
        # The robot, the goal and the current route may lie in unknown space beyond what the costmap covers yet:
        # plan on the costmap grown (on the same cells) with unknown cells around them.
        route = None if goal.cells is None or goal.frame is None else goal.frame.cells_to_world(goal.cells)
        points = [(robot.x, robot.y), (goal.pose.x, goal.pose.y), *([] if route is None else route)]
        cells, frame = _padded(cells, frame, np.asarray(points, dtype=np.float64), self.config.start_clearance_m)
        if route is not None and goal.frame != frame:
            # The costmap grew: the same route, indexed in the new grid (same cells, shifted).
            goal.cells, goal.frame = frame.world_to_cells(route), frame
        occupied, cost = planning_grid(
            cells, cost_weight=self.config.cost_weight, unknown_cost=self.config.unknown_cost * goal.unknown_factor
        )
        start = frame.world_to_cell(robot.x, robot.y)
        target = frame.world_to_cell(goal.pose.x, goal.pose.y)
        if frame.contains(*start) and not cells[start] >= 100:
            occupied = clear_disc(occupied, start, self.config.start_clearance_m / frame.resolution_m)
        remaining = None if goal.cells is None else self._remaining(goal.cells, start)
        blocked_path = remaining is not None and bool(occupied[remaining[:, 0], remaining[:, 1]].any())
        if remaining is not None and not blocked_path:
            off_m = float(np.hypot(*(remaining - np.asarray(start)).T).min()) * frame.resolution_m
            blocked_path = off_m > self.config.off_route_m  # replan from where the robot is, and take it
        periodic = now - goal.last_plan_t >= self.config.replan_period_s
        if remaining is not None and not blocked_path and not periodic:
            self.grid_stamp = stamp
            return
        self.grid_stamp = stamp
        algorithm = self.config.algorithm if self.config.algorithm != "jps" else "astar"
        try:
            plan = plan_grid(
                occupied,
                start,
                target,
                algorithm=algorithm,
                heuristic=self.config.heuristic,
                connectivity=self.config.connectivity,
                weights=self.config.weights,
                cost=cost,
                rng=self.rng,
            )
        except PlanningError as exc:
            error = next((code for cls, code in _ERRORS if isinstance(exc, cls)), "ERROR_INTERNAL")
            # In metres first (what the operator gave), the planner's cells in parentheses.
            where = (
                f"from ({robot.x:.2f}, {robot.y:.2f}) m to ({goal.pose.x:.2f}, {goal.pose.y:.2f}) m "
                f"(cells {start} -> {target}, {frame.resolution_m:g} m each)"
            )
            self._end(now, "FAILED", error, f"{where}: {exc}")
            return
        goal.last_plan_t = now
        # On a periodic check keep the current route unless the new one is clearly cheaper.
        if (
            remaining is not None
            and not blocked_path
            and plan.cost >= self.config.improvement * path_cost(remaining, cost)
        ):
            return
        goal.cells, goal.frame = plan.cells, frame
        goal.path_msg = ros.path_msg(now, "map", frame.cells_to_world(plan.cells))
        goal.following = True
        self._send(now, goal)
        self.log.debug(
            "goal %d: plan of %d cells, cost %.1f (%d expanded)",
            goal.goal_id,
            len(plan.cells),
            plan.cost,
            plan.expanded,
        )

    def _watch_cycles(self, now: float, goal: _Goal, robot: Pose2D) -> None:
        """Notice the robot cycling (see ``cycle_distance_m``) and make unknown space dearer for the goal."""
        cfg = self.config
        if goal.last_xy is not None:
            goal.driven_m += math.hypot(robot.x - goal.last_xy[0], robot.y - goal.last_xy[1])
        goal.last_xy = (robot.x, robot.y)
        if cfg.cycle_distance_m <= 0 or goal.cells is None or goal.frame is None:
            return
        start = goal.frame.world_to_cell(robot.x, robot.y)
        route = goal.frame.cells_to_world(self._remaining(goal.cells, start))
        length = float(np.hypot(*np.diff(route, axis=0).T).sum()) if len(route) > 1 else 0.0
        place = (math.floor(robot.x / PLACE_M), math.floor(robot.y / PLACE_M))
        before = goal.places.get(place)
        goal.places[place] = (goal.driven_m, length)
        if before is None or goal.driven_m - before[0] < cfg.cycle_distance_m or length < before[1] - PROGRESS_M:
            return
        factor = min(goal.unknown_factor * cfg.cycle_unknown_factor, MAX_UNKNOWN_FACTOR)
        goal.cycles += 1
        text = (
            f"cycling: back at ({robot.x:.1f}, {robot.y:.1f}) after {goal.driven_m - before[0]:.1f} m with a route "
            f"of {length:.1f} m (was {before[1]:.1f} m): unknown space now costs "
            f"{cfg.unknown_cost * factor:g} (was {cfg.unknown_cost * goal.unknown_factor:g}); planning afresh"
        )
        self.log.warning("goal %d: %s", goal.goal_id, text)
        goal.unknown_factor = factor
        goal.places.clear()
        goal.cells = None
        self._status(now, goal, "PLANNING", text=text)

    # ----------------------------------------------------------------------------------------- checkpoint

    def _goal_checkpoint(self) -> Checkpoint | None:
        """The goal's checkpoint in the run's state directory (None without one)."""
        return None if self.state_dir is None else Checkpoint(self.state_dir / "planner-goal.json", 1, self.log)

    def _save(self) -> None:
        """Checkpoint the next goal id and the active goal (:class:`Checkpoint`: atomic, checksummed, the previous
        one kept)."""
        store = self._goal_checkpoint()
        if store is None:
            return
        with self._lock:
            state: dict[str, Any] = {"next_id": self.next_id, "goal": None}
            active = self._unstepped or (None if self.goal is None else (self.goal.goal_id, self.goal.msg))
            if active is not None:  # an accepted navigate request not yet stepped supersedes the active goal
                state["goal"] = {"goal_id": active[0], "cdr": encode(active[1], _GOAL).hex()}
            store.save(json.dumps(state).encode("utf-8"))

    def _restore(self) -> None:
        """Resume from the checkpoint a previous planner process of this run left, if any (a bad one is logged, set
        aside and the previous one used, or none: :meth:`Checkpoint.load`)."""
        store = self._goal_checkpoint()
        saved = None if store is None else store.load(self._decode_goal)
        if saved is None:
            return
        self.next_id, self.goal = saved
        if self.goal is not None:
            self.log.info(
                "resuming goal %d (%.2f, %.2f) after a restart", self.goal.goal_id, self.goal.pose.x, self.goal.pose.y
            )

    @staticmethod
    def _decode_goal(payload: bytes) -> tuple[int, _Goal | None]:
        """(next goal id, the active goal or None) from a checkpoint's payload (JSON; the goal as CDR in hex).

        Raises:
            ValueError, KeyError, TypeError: not such a payload.
        """
        state = json.loads(payload.decode("utf-8"))
        next_id, saved = int(state["next_id"]), state["goal"]
        if next_id < 1:
            raise ValueError(f"next goal id {next_id}")
        if saved is None:
            return next_id, None
        msg = decode(bytes.fromhex(saved["cdr"]), _GOAL)
        goal_id = int(saved["goal_id"])
        if not 0 < goal_id < next_id:
            raise ValueError(f"goal id {goal_id}, next goal id {next_id}")
        return next_id, _Goal(goal_id, msg, ros.pose2d(msg.pose))

    @staticmethod
    def _remaining(cells: Any, start: tuple[int, int]) -> Any:
        """The part of a plan from the cell nearest the robot on."""
        d = np.abs(cells - np.asarray(start)).max(axis=1)
        return cells[int(np.argmin(d)) :]


def _extent(frame: GridFrame) -> tuple[float, float, float, float]:
    """(x_min, x_max, y_min, y_max) a grid covers, metres (an unrotated grid: the costmaps mjnav makes)."""
    (ox, oy), (h, w), res = frame.origin_m, frame.shape, frame.resolution_m
    return ox, ox + w * res, oy, oy + h * res


def _padded(cells: Any, frame: GridFrame, points: Any, margin_m: float) -> tuple[Any, GridFrame]:
    """The grid extended with unknown cells (-1), on the same cells, until every point of ``points`` ((N, 2),
    metres) lies at least ``margin_m`` inside it; the grid itself when they already do."""
    (ox, oy), (h, w), res = frame.origin_m, frame.shape, frame.resolution_m
    lo = (np.min(points, axis=0) - margin_m - (ox, oy)) / res
    hi = (np.max(points, axis=0) + margin_m - (ox, oy)) / res
    c0, r0 = min(0, math.floor(lo[0])), min(0, math.floor(lo[1]))
    c1, r1 = max(w, math.ceil(hi[0])), max(h, math.ceil(hi[1]))
    if (c0, r0, c1, r1) == (0, 0, w, h):
        return cells, frame
    grown = np.full((r1 - r0, c1 - c0), -1, dtype=cells.dtype)
    grown[-r0 : -r0 + h, -c0 : -c0 + w] = cells
    return grown, GridFrame(res, (ox + c0 * res, oy + r0 * res), grown.shape)

"""``mjnav goal`` (send a goal with confirmed delivery, follow it, or follow waypoints) and ``mjnav cancel``."""

from __future__ import annotations

import argparse
import json
import math
import os
import queue
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: Exit codes of ``mjnav goal`` / ``mjnav cancel`` (documented in their --help).
EXIT_REACHED = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_UNREACHABLE = 3

_WAYPOINTS_HELP = (
    "Waypoint file: one waypoint per line, 'X Y' or 'X Y YAW_DEG' in the map frame (metres, degrees; spaces or "
    "commas between numbers); blank lines and text after '#' are ignored. Waypoints are driven in order, each to "
    "REACHED before the next is sent (Nav2's waypoint follower); the first one that fails or is canceled stops "
    "the run."
)
_EXIT_HELP = (
    "Exit status: 0 when the goal (every waypoint) was reached — or, without --wait, accepted; 1 when it was "
    "rejected, failed, canceled or --timeout passed (the reason is printed); 2 for bad arguments; 3 when no planner "
    "answered (no router, or the stack is not running)."
)


@dataclass(frozen=True)
class Waypoint:
    """A goal pose in the map frame: x, y in metres, yaw in degrees (None: any final heading)."""

    x: float
    y: float
    yaw_deg: float | None = None


def read_waypoints(path: Path) -> list[Waypoint]:
    """Waypoints of a file in the format of ``mjnav goal --waypoints`` (see its help).

    Raises:
        ValueError: unreadable file, a malformed line (named by number), or no waypoint at all.
    """
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"cannot read waypoints: {exc}") from None
    points = []
    for number, line in enumerate(text.splitlines(), start=1):
        fields = line.split("#", 1)[0].replace(",", " ").split()
        if not fields:
            continue
        try:
            values = [float(f) for f in fields]
        except ValueError:
            raise ValueError(f"{path}:{number}: expected 'X Y [YAW_DEG]' numbers, got {line.strip()!r}") from None
        if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
            raise ValueError(f"{path}:{number}: expected 'X Y [YAW_DEG]' (2 or 3 finite numbers), got {line.strip()!r}")
        points.append(Waypoint(values[0], values[1], values[2] if len(values) == 3 else None))
    if not points:
        raise ValueError(f"{path}: no waypoints")
    return points


def register(sub: Any) -> None:
    """Add ``goal`` and ``cancel``."""
    from mjnav.bus import add_bus_arguments

    p = sub.add_parser(
        "goal",
        help="send a navigation goal (delivery confirmed) and follow it",
        description=(
            "Send a goal to the planner's navigate endpoint (<ns>/navigate, like Nav2's NavigateToPose): it answers "
            "at once, accepted with a goal id or rejected with a typed reason (ERROR_OUTSIDE_MAP, "
            "ERROR_GOAL_OCCUPIED, ERROR_INVALID_GOAL). With --wait the status transitions on <ns>/goal_status are "
            "printed until the goal ends; Ctrl-C then cancels it. Coordinates may be negative (mjnav goal -3 2.5). "
            "Without --yaw the robot may end with any heading; with it, it turns in place at the goal."
        ),
        epilog=_WAYPOINTS_HELP + " " + _EXIT_HELP,
    )
    p.add_argument("x", nargs="?", type=float, metavar="X", help="goal x, metres")
    p.add_argument("y", nargs="?", type=float, metavar="Y", help="goal y, metres")
    p.add_argument("--yaw", type=float, metavar="DEG", help="final heading, degrees (default: any)")
    p.add_argument("--frame", default="map", help="frame of X, Y (default map; the planner accepts only map)")
    p.add_argument("--waypoints", type=Path, metavar="FILE", help="follow the waypoints of FILE in order (waits)")
    p.add_argument("--wait", action="store_true", help="follow the goal until it ends; exit 0 only when reached")
    p.add_argument("--timeout", type=float, metavar="S", help="with --wait: give up (and cancel) after S wall seconds")
    p.add_argument(
        "--at",
        type=float,
        metavar="T",
        help="send the goal at sim time T (s): mjnav goal takes part in lockstep until then, so the goal leaves at "
        "exactly T whatever the machine's load and the run repeats to the bit (fails when sim time is past T)",
    )
    p.add_argument("--json", action="store_true", help="one JSON object per line instead of text")
    p.add_argument("--ns", default="robot0", help="robot namespace (default robot0)")
    add_bus_arguments(p)
    p.set_defaults(func=run_goal)

    c = sub.add_parser(
        "cancel",
        help="cancel the active goal (delivery confirmed)",
        description=(
            "Publish on <ns>/cancel and wait for the planner's delivery receipt; then report which goal it canceled "
            "(seen on goal_status within --timeout). Exit 0 when the planner received the cancel, 3 when it did not."
        ),
    )
    c.add_argument("--timeout", type=float, default=3.0, metavar="S", help="seconds to wait (default 3)")
    c.add_argument("--ns", default="robot0", help="robot namespace (default robot0)")
    add_bus_arguments(c)
    c.set_defaults(func=run_cancel)


def state_name(state: int) -> str:
    """``GoalStatus`` state constant name without its prefix ("REACHED"), or the number as text."""
    return _constant_name("STATE_", state)


def error_name(code: int) -> str:
    """``GoalStatus`` error constant name ("ERROR_NO_PATH"), or the number as text."""
    return "ERROR_" + _constant_name("ERROR_", code)


def _constant_name(prefix: str, value: int) -> str:
    from mjnav.msgs import msg_class

    cls = msg_class("mjnav_msgs/msg/GoalStatus")
    for name in dir(cls):
        if name.startswith(prefix) and getattr(cls, name) == value:
            return name[len(prefix) :]
    return str(value)


class _Reporter:
    """Prints goal events as text lines or JSON lines."""

    def __init__(self, as_json: bool) -> None:
        self.as_json = as_json

    def __call__(self, event: dict[str, Any], text: str) -> None:
        print(json.dumps(event) if self.as_json else text, flush=True)


def _open(args: argparse.Namespace) -> Any:
    from mjnav.commands.bustools import open_connected

    return open_connected(args, args.ns)


def run_goal(args: argparse.Namespace) -> int:
    """``mjnav goal``."""
    from mjnav.bus import BusConfigError, BusUnavailable
    from mjnav.runtime.logs import setup_logging

    try:
        if args.waypoints is not None:
            if args.x is not None:
                raise ValueError("give either X Y or --waypoints FILE, not both")
            waypoints = read_waypoints(args.waypoints)
        else:
            if args.x is None or args.y is None:
                raise ValueError("give the goal as X Y (metres), or --waypoints FILE")
            waypoints = [Waypoint(args.x, args.y, args.yaw)]
        values = [v for w in waypoints for v in (w.x, w.y, w.yaw_deg) if v is not None]
        if not all(math.isfinite(v) for v in values):
            raise ValueError("coordinates and --yaw must be finite")
        if args.timeout is not None and not args.timeout > 0:
            raise ValueError("--timeout must be > 0")
        if args.at is not None and not (math.isfinite(args.at) and args.at >= 0):
            raise ValueError("--at must be a sim time >= 0 (seconds)")
        if args.at is not None and args.waypoints is not None:
            raise ValueError("--at sends one goal: give X Y, not --waypoints")
    except ValueError as exc:
        print(f"mjnav goal: {exc}", file=sys.stderr)
        return EXIT_USAGE
    setup_logging("WARNING")
    wait = args.wait or args.waypoints is not None
    report = _Reporter(args.json)
    try:
        bus = _open(args)
    except (BusUnavailable, BusConfigError) as exc:
        print(f"mjnav goal: {exc}", file=sys.stderr)
        return EXIT_UNREACHABLE
    with bus:
        statuses: queue.Queue[Any] = queue.Queue()
        bus.subscribe("goal_status", callback=statuses.put)  # before the request: no status can be missed
        deadline = None if args.timeout is None else time.monotonic() + args.timeout
        for index, waypoint in enumerate(waypoints):
            label = f"waypoint {index + 1}/{len(waypoints)}: " if len(waypoints) > 1 else ""
            code = _drive(bus, args.frame, waypoint, statuses, wait, deadline, report, label, args.at)
            if code != EXIT_REACHED:
                return code
        if len(waypoints) > 1:
            report({"waypoints": len(waypoints), "result": "REACHED"}, f"all {len(waypoints)} waypoints reached")
    return EXIT_REACHED


def _drive(
    bus: Any,
    frame: str,
    waypoint: Waypoint,
    statuses: queue.Queue[Any],
    wait: bool,
    deadline: float | None,
    report: _Reporter,
    label: str,
    at_s: float | None = None,
) -> int:
    """Send one goal through ``navigate`` (at sim time ``at_s``, when given) and, with ``wait``, follow it to its
    end; returns the exit code."""
    from mjnav.bus import NoReply, RemoteError
    from mjnav.geometry import yaw_to_quaternion
    from mjnav.msgs import from_dict

    q = (0.0, 0.0, 0.0, 0.0) if waypoint.yaw_deg is None else yaw_to_quaternion(math.radians(waypoint.yaw_deg))
    pose = {"position": {"x": waypoint.x, "y": waypoint.y}, "orientation": dict(zip("xyzw", q, strict=True))}
    request = from_dict("mjnav_msgs/msg/NavigateRequest", {"goal": {"header": {"frame_id": frame}, "pose": pose}})
    where = f"({waypoint.x:.2f}, {waypoint.y:.2f})"
    if waypoint.yaw_deg is not None:
        where += f" yaw {waypoint.yaw_deg:g}°"
    try:
        reply = bus.call("navigate", request, timeout_s=5.0) if at_s is None else _navigate_at(bus, request, at_s)
    except _TooLate as exc:
        print(f"mjnav goal: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except NoReply:
        print(
            f"mjnav goal: no planner answered on {bus.namespace}/navigate (is it running? `mjnav health planner`)",
            file=sys.stderr,
        )
        return EXIT_UNREACHABLE
    except RemoteError as exc:
        print(f"mjnav goal: the planner refused the request: {exc}", file=sys.stderr)
        return EXIT_FAILED
    if not reply.accepted:
        error = error_name(reply.error_code)
        report(
            {
                "goal_id": 0,
                "state": "REJECTED",
                "error": error,
                "text": reply.error_text,
                "goal": [waypoint.x, waypoint.y],
            },
            f"{label}goal {where} rejected: {error}: {reply.error_text}",
        )
        return EXIT_FAILED
    goal_id = int(reply.goal_id)
    report({"goal_id": goal_id, "state": "ACCEPTED", "goal": [waypoint.x, waypoint.y]},
           f"{label}goal {goal_id} {where} accepted")  # fmt: skip
    if not wait:
        return EXIT_REACHED
    last = "ACCEPTED"
    accepted_t: float | None = None  # sim time of the goal's first status (the planner took it)
    try:
        while True:
            remaining = None if deadline is None else deadline - time.monotonic()
            if remaining is not None and remaining <= 0:
                _cancel_quietly(bus)
                report({"goal_id": goal_id, "state": "TIMEOUT"}, f"{label}goal {goal_id}: no result in time: canceled")
                return EXIT_FAILED
            try:
                status = statuses.get(timeout=0.2 if remaining is None else min(0.2, remaining))
            except queue.Empty:
                continue
            if status.goal_id != goal_id:
                continue
            name = state_name(status.state)
            t = status.header.stamp.sec + status.header.stamp.nanosec * 1e-9
            accepted_t = t if accepted_t is None else accepted_t
            if name != last:
                last = name
                error = error_name(status.error_code)
                text = f"{label}goal {goal_id}: {name} at t={t:.2f} s"
                if status.error_code:
                    text += f": {error}: {status.error_text}"
                elif status.error_text:
                    text += f" ({status.error_text})"
                event = {"goal_id": goal_id, "state": name, "error": error, "text": status.error_text, "t": t}
                if name in ("REACHED", "FAILED", "CANCELED"):
                    event["time_s"] = round(t - accepted_t, 9)  # from the planner taking the goal to its end
                    text += f" ({event['time_s']:.2f} s)"
                report(event, text)
            if name == "REACHED":
                return EXIT_REACHED
            if name in ("FAILED", "CANCELED"):
                return EXIT_FAILED
    except KeyboardInterrupt:
        _cancel_quietly(bus)
        print(f"mjnav goal: interrupted: goal {goal_id} canceled", file=sys.stderr)
        return 130


class _TooLate(ValueError):
    """``--at`` names a sim time that has passed."""


def _navigate_at(bus: Any, request: Any, at_s: float) -> Any:
    """The ``navigate`` reply to ``request`` sent at sim time ``at_s`` from a lockstep step (see ``--at``).

    Raises:
        _TooLate: sim time is already past ``at_s``.
        NoReply, RemoteError: as :meth:`mjnav.bus.Bus.call`.
    """
    import threading

    from mjnav.runtime.participant import LockstepParticipant

    done = threading.Event()
    outcome: list[Any] = []

    def finish(value: Any) -> None:
        outcome.append(value)
        done.set()

    class TimedGoal(LockstepParticipant):
        """Steps when it joins, its next step at ``at_s``, where it sends the request; then every sim second
        (a participant until the command ends, as cheap as reporting)."""

        def __init__(self) -> None:
            self._init_participant(bus, f"goal{os.getpid()}", period_s=1.0)
            self._sent = False
            self._subscribe_clock()

        def _step(self, t: float) -> None:
            if self._sent:
                return
            if t > at_s + 1e-9:
                self._sent = True
                finish(_TooLate(f"sim time is {t:.2f} s, past --at {at_s:g} s"))
            elif t >= at_s - 1e-9:
                self._sent = True
                bus.call_async("navigate", request, finish, finish, timeout_s=5.0)  # leaves before the report
            else:
                self._next_step(at_s)  # report the next step at at_s: sim time waits there for the request

    client = TimedGoal()
    client._participate()
    done.wait()
    value = outcome[0]
    if isinstance(value, Exception):
        raise value
    return value


def _cancel_quietly(bus: Any) -> None:
    from mjnav.bus import NotDelivered
    from mjnav.msgs import from_dict

    try:
        bus.put_confirmed("cancel", [from_dict("std_msgs/msg/Empty")], timeout_s=2.0)
    except NotDelivered as exc:
        print(f"mjnav goal: the cancel was not confirmed: {exc}", file=sys.stderr)


def run_cancel(args: argparse.Namespace) -> int:
    """``mjnav cancel``."""
    from mjnav.bus import BusConfigError, BusUnavailable, NotDelivered
    from mjnav.msgs import from_dict
    from mjnav.runtime.logs import setup_logging

    if not args.timeout > 0:
        print("mjnav cancel: --timeout must be > 0", file=sys.stderr)
        return EXIT_USAGE
    setup_logging("WARNING")
    try:
        bus = _open(args)
    except (BusUnavailable, BusConfigError) as exc:
        print(f"mjnav cancel: {exc}", file=sys.stderr)
        return EXIT_UNREACHABLE
    with bus:
        canceled: queue.Queue[Any] = queue.Queue()
        cls_canceled = _state_value("CANCELED")
        bus.subscribe("goal_status", callback=lambda s: canceled.put(s) if s.state == cls_canceled else None)
        try:
            bus.put_confirmed("cancel", [from_dict("std_msgs/msg/Empty")], timeout_s=args.timeout)
        except NotDelivered as exc:
            print(f"mjnav cancel: {exc}", file=sys.stderr)
            return EXIT_UNREACHABLE
        try:
            status = canceled.get(timeout=args.timeout)
            print(f"goal {status.goal_id} canceled")
        except queue.Empty:
            print(f"cancel delivered to the planner; no goal was reported canceled within {args.timeout:g} s "
                  "(none was active, or sim time is paused)")  # fmt: skip
    return EXIT_REACHED


def _state_value(name: str) -> int:
    from mjnav.msgs import msg_class

    return int(getattr(msg_class("mjnav_msgs/msg/GoalStatus"), f"STATE_{name}"))

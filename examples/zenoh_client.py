#!/usr/bin/env python3
"""A plain Zenoh client of an mjnav stack: only `eclipse-zenoh` and `rosbags`, no mjnav.

It joins the router as a Zenoh client, decodes `<ns>/scan` (sensor_msgs/LaserScan) and `<ns>/odom`
(nav_msgs/Odometry) as the standard ROS 2 messages they are (CDR), prints a few of each, then sends a navigation
goal (geometry_msgs/PoseStamped, frame `map`, stamped with the sim time of the last odometry) on `<ns>/goal`.

    pip install eclipse-zenoh rosbags
    python examples/zenoh_client.py                              # router at tcp/127.0.0.1:7447 (mjnav up)
    python examples/zenoh_client.py --connect tcp/10.0.0.5:7447 --goal 3.8 2.2 1.57 --count 10
    python examples/zenoh_client.py --no-goal --json             # one JSON object per line
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import threading
import time
from typing import Any

import zenoh
from rosbags.typesys import Stores, get_typestore

TYPES = get_typestore(Stores.ROS2_HUMBLE)
SCAN, ODOM, GOAL = "sensor_msgs/msg/LaserScan", "nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped"


def seconds(stamp: Any) -> float:
    """builtin_interfaces/Time as seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def yaw_of(q: Any) -> float:
    """Yaw (rad) of a geometry_msgs/Quaternion."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def goal_message(x: float, y: float, yaw: float, stamp_s: float) -> Any:
    """A geometry_msgs/PoseStamped goal in frame `map`."""
    t = TYPES.types
    ns = round(stamp_s * 1e9)
    header = t["std_msgs/msg/Header"](
        stamp=t["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id="map"
    )
    pose = t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
    )
    return t[GOAL](header=header, pose=pose)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--connect", default="tcp/127.0.0.1:7447", help="router endpoint (default tcp/127.0.0.1:7447)")
    parser.add_argument("--ns", default="robot0", help="robot namespace (default robot0)")
    parser.add_argument("--count", type=int, default=5, help="messages of each topic to print (default 5)")
    parser.add_argument("--timeout", type=float, default=30.0, help="give up after this many seconds (default 30)")
    parser.add_argument(
        "--goal",
        nargs="+",
        type=float,
        default=[3.8, 2.2, 1.5708],
        metavar="X Y [YAW]",
        help="goal in the map frame, metres and radians (default: the rooms world's goal)",
    )
    parser.add_argument("--no-goal", action="store_true", help="only listen")
    parser.add_argument("--json", action="store_true", help="print one JSON object per line")
    args = parser.parse_args()
    if len(args.goal) not in (2, 3):
        parser.error("--goal takes X Y or X Y YAW")

    config = zenoh.Config()
    config.insert_json5("mode", json.dumps("client"))
    config.insert_json5("connect/endpoints", json.dumps([args.connect]))
    config.insert_json5("connect/timeout_ms", json.dumps(int(args.timeout * 1000)))  # wait for a starting router
    lock = threading.Lock()
    seen = {"scan": 0, "odom": 0}
    last_stamp = {"odom": 0.0}
    done = threading.Event()

    def show(record: dict[str, Any], text: str) -> None:
        with lock:
            print(json.dumps(record) if args.json else text, flush=True)

    def on_scan(sample: zenoh.Sample) -> None:
        msg: Any = TYPES.deserialize_cdr(sample.payload.to_bytes(), SCAN)
        valid = [r for r in msg.ranges if msg.range_min <= r <= msg.range_max]
        nearest = float(min(valid)) if valid else math.inf
        with lock:
            if seen["scan"] >= args.count:
                return
            seen["scan"] += 1
        t = seconds(msg.header.stamp)
        show(
            {
                "key": str(sample.key_expr),
                "type": SCAN,
                "stamp": t,
                "frame_id": msg.header.frame_id,
                "beams": len(msg.ranges),
                "nearest_m": nearest if math.isfinite(nearest) else None,
            },
            f"scan  t={t:8.3f} s  frame={msg.header.frame_id}  beams={len(msg.ranges)}  nearest={nearest:.2f} m",
        )
        if min(seen.values()) >= args.count:
            done.set()

    def on_odom(sample: zenoh.Sample) -> None:
        msg: Any = TYPES.deserialize_cdr(sample.payload.to_bytes(), ODOM)
        t = seconds(msg.header.stamp)
        with lock:
            last_stamp["odom"] = max(last_stamp["odom"], t)
            if seen["odom"] >= args.count:
                return
            seen["odom"] += 1
        p, v = msg.pose.pose, msg.twist.twist
        show(
            {
                "key": str(sample.key_expr),
                "type": ODOM,
                "stamp": t,
                "x": p.position.x,
                "y": p.position.y,
                "yaw": yaw_of(p.orientation),
                "v": v.linear.x,
                "omega": v.angular.z,
            },
            f"odom  t={t:8.3f} s  x={p.position.x:7.3f} y={p.position.y:7.3f} yaw={yaw_of(p.orientation):6.3f} rad"
            f"  v={v.linear.x:5.2f} m/s  w={v.angular.z:5.2f} rad/s",
        )
        if min(seen.values()) >= args.count:
            done.set()

    with zenoh.open(config) as session:
        session.declare_subscriber(f"{args.ns}/scan", on_scan)
        session.declare_subscriber(f"{args.ns}/odom", on_odom)
        if not done.wait(args.timeout):
            print(f"timeout: got {seen} messages from {args.connect} within {args.timeout} s", file=sys.stderr)
            return 1
        if args.no_goal:
            return 0
        # Goals are events: reliable, never dropped under congestion.
        goal_key = f"{args.ns}/goal"
        publisher = session.declare_publisher(
            goal_key,
            encoding=zenoh.Encoding.APPLICATION_CDR.with_schema(GOAL),
            congestion_control=zenoh.CongestionControl.BLOCK,
            priority=zenoh.Priority.DATA_HIGH,
        )
        status: Any = publisher  # the stubs of some zenoh releases mistype matching_status
        deadline = time.monotonic() + 5.0
        while not status.matching_status.matching and time.monotonic() < deadline:
            time.sleep(0.05)  # give the planner's subscription a moment to be known
        if not status.matching_status.matching:
            print(f"warning: nobody subscribes to {goal_key} yet; sending anyway", file=sys.stderr)
        x, y, yaw = args.goal[0], args.goal[1], args.goal[2] if len(args.goal) == 3 else 0.0
        stamp = last_stamp["odom"]
        publisher.put(bytes(TYPES.serialize_cdr(goal_message(x, y, yaw, stamp), GOAL)))
        show(
            {"key": goal_key, "type": GOAL, "stamp": stamp, "x": x, "y": y, "yaw": yaw, "sent": True},
            f"goal  sent ({x:.2f}, {y:.2f}, {yaw:.3f}) on {goal_key} stamped t={stamp:.3f} s",
        )
        publisher.undeclare()
    return 0


if __name__ == "__main__":
    sys.exit(main())

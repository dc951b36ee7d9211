"""The topic table: every Zenoh key mjnav uses, its ROS 2 type and its delivery semantics.

Keys are ``<namespace>/<topic>`` — the mapping zenoh-bridge-ros2dds uses for ROS 2 topic ``/<namespace>/<topic>`` —
so a ROS 2 user behind the bridge sees ordinary topics. Nothing outside this module spells a key.

Delivery: every message is published reliably and never dropped in transit (a publisher waits under congestion:
lockstep runs must see every message); the kinds differ at the subscriber:
- ``SNAPSHOT``: latest wins; subscribers keep only the newest message (scan, odom, map, cmd_vel …).
- ``EVENT``: subscribers queue every message until it is handled (goal, cancel …).

*Latched* topics (ROS 2's transient-local durability) also keep their newest message at the publisher, and a
subscriber that joins later gets it at once (Zenoh's advanced publisher and subscriber with history): the robot
description, ``tf_static``, the maps, the plan, the path and the goal's status. A late joiner never waits for a
re-send, and nobody re-sends.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from enum import Enum

DEFAULT_NAMESPACE = "robot0"

_NAMESPACE_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")


class Kind(Enum):
    """Delivery semantics of a topic."""

    SNAPSHOT = "snapshot"
    EVENT = "event"


@dataclass(frozen=True, slots=True)
class Topic:
    """One row of the topic table.

    Attributes:
        name: topic name under the namespace.
        msgtype: ROS 2 message type, e.g. ``sensor_msgs/msg/LaserScan``.
        kind: snapshot (latest wins) or event (never dropped).
        publisher: which service publishes it.
        rate: nominal rate, as text for the docs ("10 Hz", "on change").
        description: one line for the README.
        per_service: the key carries the service name: ``<namespace>/<name>/<service>``.
        express: sent at once rather than batched (the clock and lockstep reports: each closes a lockstep round,
            and sending it flushes what its publisher batched before it).
        stack_namespace: the namespace the shipped stacks use for it when it is not the default (``uav0`` for the
            UAV's topics), as the README's table shows it; any namespace works on the wire.
        subscribers: the services that must receive every message of an event topic: a publisher asking for
            delivery receipts (``mjnav pub``, :meth:`mjnav.bus.Bus.put_confirmed`) waits for one from each.
        latched: each publisher keeps its newest message and a subscriber that joins later receives it (ROS 2's
            transient-local durability).
    """

    name: str
    msgtype: str
    kind: Kind
    publisher: str
    rate: str
    description: str
    per_service: bool = False
    express: bool = False
    stack_namespace: str | None = None
    subscribers: tuple[str, ...] = ()
    latched: bool = False

    def key(self, namespace: str = DEFAULT_NAMESPACE, service: str | None = None) -> str:
        """The Zenoh key of this topic in ``namespace``; per-service topics need ``service``
        (``"*"`` gives a wildcard over all services)."""
        return _key(self.name, self.per_service, namespace, service)

    @property
    def pattern(self) -> str:
        """The key under the namespace as documented, e.g. ``status/<service>``."""
        return f"{self.name}/<service>" if self.per_service else self.name

    def history_key(self, namespace: str = DEFAULT_NAMESPACE) -> str:
        """Where a latched topic's publishers answer late joiners (Zenoh's advanced publisher declares its cache's
        queryable and its liveliness token under ``<key>/@adv/``): for access control."""
        if not self.latched or self.per_service:
            raise ValueError(f"topic {self.name!r} keeps no history")
        return f"{self.key(namespace)}/{HISTORY_SUFFIX}"


#: Key suffix under which Zenoh's advanced publishers serve their history (see :meth:`Topic.history_key`).
HISTORY_SUFFIX = "@adv/**"


@dataclass(frozen=True, slots=True)
class Endpoint:
    """A request/reply endpoint (Zenoh queryable), keyed like a ROS 2 service behind the bridge."""

    name: str
    request_type: str
    response_type: str
    server: str
    description: str
    per_service: bool = False
    express: bool = False

    def key(self, namespace: str = DEFAULT_NAMESPACE, service: str | None = None) -> str:
        """The Zenoh key of this endpoint in ``namespace`` (``service`` for per-service endpoints)."""
        return _key(self.name, self.per_service, namespace, service)

    @property
    def pattern(self) -> str:
        """The key under the namespace as documented, e.g. ``config/<service>``."""
        return f"{self.name}/<service>" if self.per_service else self.name


def _key(name: str, per_service: bool, namespace: str, service: str | None) -> str:
    check_namespace(namespace)
    if per_service:
        if not service or "/" in service:
            raise ValueError(f"topic {name!r} is per service: give service=<name> (or '*')")
        return f"{namespace}/{name}/{service}"
    if service is not None:
        raise ValueError(f"topic {name!r} is not per service")
    return f"{namespace}/{name}"


_S, _E = Kind.SNAPSHOT, Kind.EVENT

TOPICS: dict[str, Topic] = {
    t.name: t
    for t in (
        Topic(
            "clock",
            "rosgraph_msgs/msg/Clock",
            _S,
            "sim",
            "20 Hz sim time",
            "Simulation time; every service steps on it",
            express=True,
        ),
        Topic("scan", "sensor_msgs/msg/LaserScan", _S, "sim", "10 Hz", "Planar lidar, frame `laser`"),
        Topic(
            "odom",
            "nav_msgs/msg/Odometry",
            _S,
            "sim",
            "20 Hz",
            "Wheel-encoder odometry, `odom` → `base_link`, drifts",
        ),
        Topic("imu", "sensor_msgs/msg/Imu", _S, "sim", "100 Hz", "Gyro and accelerometer, frame `imu`"),
        Topic("joint_states", "sensor_msgs/msg/JointState", _S, "sim", "20 Hz", "Wheel positions and rates"),
        Topic(
            "tf",
            "tf2_msgs/msg/TFMessage",
            _S,
            "sim, slam",
            "20 Hz, 10 Hz",
            "`odom` → `base_link` (sim), `map` → `odom` (slam)",
        ),
        Topic(
            "ground_truth",
            "geometry_msgs/msg/PoseStamped",
            _S,
            "sim",
            "20 Hz",
            "True pose `map` → `base_link`",
        ),
        Topic(
            "truth",
            "geometry_msgs/msg/PoseStamped",
            _S,
            "sim",
            "20 Hz",
            "True pose `map` → `base_link` for evaluation only (mjnav demo, benchmarks); no navigation service "
            "reads it",
        ),
        Topic(
            "pose",
            "geometry_msgs/msg/PoseWithCovarianceStamped",
            _S,
            "slam",
            "10 Hz",
            "The robot's estimated pose in `map` (SLAM's `map` → `odom` composed with the newest odometry)",
        ),
        Topic(
            "localization_health",
            "diagnostic_msgs/msg/DiagnosticStatus",
            _S,
            "slam",
            "10 Hz (each scan)",
            "How well SLAM localises: level OK, WARN (degraded: on odometry) or ERROR (lost), why, and values "
            "(returns, match_score, bad_scans, unmatched_m, degenerate, starved); the controller slows, then stops, on "
            "it (not for want of returns: open space)",
        ),
        Topic(
            "initialpose",
            "geometry_msgs/msg/PoseWithCovarianceStamped",
            _E,
            "sim, user",
            "once at t = 0, on request",
            "Initial pose in `map`, as RViz's 2D Pose Estimate sends it (SLAM starts or relocalises there); the sim "
            "announces the spawn pose when sim time starts",
        ),
        Topic(
            "robot_description",
            "std_msgs/msg/String",
            _S,
            "sim",
            "once",
            "The robot's MJCF, flattened (as ROS's `robot_description`): footprint, sensor frames and lidar for "
            "every service",
            latched=True,
        ),
        Topic(
            "tf_static",
            "tf2_msgs/msg/TFMessage",
            _S,
            "sim",
            "once",
            "Fixed transforms `base_link` → each sensor frame of the robot model (`laser`, `imu`)",
            latched=True,
        ),
        Topic(
            "obstacles",
            "tf2_msgs/msg/TFMessage",
            _S,
            "sim",
            "10 Hz",
            "True poses `map` → body of the world's moving bodies (worlds that have some)",
        ),
        Topic(
            "sim_status",
            "mjnav_msgs/msg/SimStatus",
            _S,
            "sim",
            "10 Hz",
            "World, collisions, real-time factor, watchdog",
        ),
        Topic(
            "collision_monitor",
            "diagnostic_msgs/msg/DiagnosticStatus",
            _S,
            "sim",
            "on change",
            "The collision monitor under every velocity command: OK, WARN (slowed: zone, scale, time to collision) or "
            "ERROR (stopped)",
            latched=True,
        ),
        Topic(
            "cmd_vel",
            "geometry_msgs/msg/Twist",
            _S,
            "controller",
            "20 Hz",
            "Velocity command (linear.x m/s, angular.z rad/s)",
        ),
        Topic(
            "map",
            "nav_msgs/msg/OccupancyGrid",
            _S,
            "slam",
            "1 Hz",
            "Occupancy map in `map` (SLAM's, re-rendered from optimised poses; the mapper's with mapper.map_source = "
            "scan)",
            latched=True,
        ),
        Topic(
            "costmap",
            "nav_msgs/msg/OccupancyGrid",
            _S,
            "mapper",
            "2 Hz",
            "Inflated costmap, 0–100; grows with the area the lidar has reached",
            latched=True,
        ),
        Topic(
            "cmd_vel_teleop",
            "geometry_msgs/msg/Twist",
            _S,
            "user (`mjnav teleop`)",
            "10 Hz while driving",
            "Teleoperation command; overrides `cmd_vel` while fresh (the sim's mux)",
        ),
        Topic(
            "goal",
            "geometry_msgs/msg/PoseStamped",
            _E,
            "user",
            "on request",
            "Navigation goal in `map` (unconfirmed; `navigate` answers with an id)",
            subscribers=("planner",),
        ),
        Topic(
            "cancel",
            "std_msgs/msg/Empty",
            _E,
            "user",
            "on request",
            "Cancel the current goal",
            subscribers=("planner",),
        ),
        Topic("plan", "nav_msgs/msg/Path", _S, "planner", "on change", "Raw grid plan in `map`", latched=True),
        Topic(
            "path",
            "nav_msgs/msg/Path",
            _S,
            "smoother",
            "on change",
            "Smoothed path the controller follows",
            latched=True,
        ),
        Topic(
            "goal_status",
            "mjnav_msgs/msg/GoalStatus",
            _E,
            "planner",
            "on change",
            "Goal lifecycle with a typed failure reason; the planner owns every goal",
            latched=True,
        ),
        Topic(
            "controller_feedback",
            "mjnav_msgs/msg/ControllerFeedback",
            _E,
            "controller",
            "on change",
            "The controller's report to the planner on the active goal: following, arrived, no progress, halted",
            latched=True,
        ),
        Topic(
            "receipt",
            "mjnav_msgs/msg/Receipt",
            _E,
            "event subscribers",
            "on request",
            "Delivery receipt of an event message that asked for one (`mjnav pub`)",
            per_service=True,
        ),
        Topic(
            "status",
            "mjnav_msgs/msg/ServiceStatus",
            _S,
            "every service",
            "1 Hz",
            "Loop rate, overruns, received/rejected message counts",
            per_service=True,
        ),
        Topic(
            "lockstep",
            "mjnav_msgs/msg/LockstepReady",
            _S,
            "every sim-time service",
            "after each step",
            "Lockstep barrier: the step just done and when the next is due; the sim waits for it",
            per_service=True,
            express=True,
        ),
        # The UAV stack (namespace uav0): uav_sim -> ins -> flight_controller -> uav_sim. It also uses clock, imu
        # (100 Hz, body FLU, mean specific force over the period, orientation = the AHRS attitude in ENU),
        # ground_truth (3-D pose), sim_status, status and lockstep.
        Topic(
            "gps",
            "sensor_msgs/msg/NavSatFix",
            _S,
            "uav_sim",
            "10 Hz",
            "GPS fix (WGS84), stamped when taken",
            stack_namespace="uav0",
        ),
        Topic(
            "datum",
            "sensor_msgs/msg/NavSatFix",
            _S,
            "uav_sim",
            "once",
            "WGS84 position of the `map` frame's origin (ENU), which the GPS fixes are referred to",
            stack_namespace="uav0",
            latched=True,
        ),
        Topic(
            "baro",
            "sensor_msgs/msg/FluidPressure",
            _S,
            "uav_sim",
            "25 Hz",
            "Barometric static pressure, Pa",
            stack_namespace="uav0",
        ),
        Topic(
            "mocap",
            "nav_msgs/msg/Odometry",
            _S,
            "uav_sim",
            "50 Hz",
            "Motion capture (true pose and twist, ENU `map` → FLU `base_link`), standing for VICON",
            stack_namespace="uav0",
        ),
        Topic(
            "ins_odom",
            "nav_msgs/msg/Odometry",
            _S,
            "ins",
            "25 Hz",
            "GPS/INS estimate in a local ENU (`map`, REP-103) or NED (`map_ned`) frame, with covariance",
            stack_namespace="uav0",
        ),
        Topic(
            "ins_health",
            "diagnostic_msgs/msg/DiagnosticArray",
            _S,
            "ins",
            "5 Hz + on change",
            "INS health, stamped as its estimate: OK, WARN (no barometer fused), ERROR (no GPS fix fused for "
            "`gps_timeout_s`: the horizontal position is lost), with the fused / rejected (χ² gate) / reset counts "
            "of GPS and barometer and the rejected IMU samples by reason",
            stack_namespace="uav0",
        ),
        Topic(
            "rotor_cmd",
            "sensor_msgs/msg/JointState",
            _S,
            "flight_controller",
            "50 Hz",
            "Rotor speed commands `rotor0..3` (velocity, rad/s, PX4 quad-X order)",
            stack_namespace="uav0",
        ),
        Topic(
            "setpoint",
            "geometry_msgs/msg/PoseStamped",
            _S,
            "user",
            ">= 2 Hz",
            "UAV position/yaw setpoint (ENU)",
            stack_namespace="uav0",
        ),
        Topic(
            "trajectory",
            "nav_msgs/msg/Path",
            _S,
            "user",
            ">= 2 Hz",
            "UAV trajectory: poses stamped with the sim time they are due (ENU)",
            stack_namespace="uav0",
        ),
        Topic(
            "arm",
            "std_msgs/msg/Bool",
            _E,
            "user",
            "on request",
            "Arm (true) or land and disarm (false)",
            stack_namespace="uav0",
        ),
        Topic(
            "flight_state",
            "std_msgs/msg/String",
            _S,
            "flight_controller",
            "10 Hz + on change",
            "disarmed, armed, offboard, landing, failsafe_land (no setpoint), failsafe_hold / failsafe_descend "
            "(position lost), failsafe_return (geofence)",
            stack_namespace="uav0",
        ),
    )
}

ENDPOINTS: dict[str, Endpoint] = {
    e.name: e
    for e in (
        Endpoint(
            "config",
            "std_msgs/msg/String",
            "std_msgs/msg/String",
            "every service",
            "Current configuration of a service as JSON",
            per_service=True,
        ),
        Endpoint(
            "set_param",
            "std_msgs/msg/String",
            "std_msgs/msg/String",
            "every service",
            'Set one runtime-settable config key (`mjnav param set`); request: JSON {"key", "value"}, validated like '
            'the TOML file; reply: JSON {"key", "value", "previous"}, applied before the next step',
            per_service=True,
        ),
        Endpoint(
            "slam_info",
            "std_msgs/msg/String",
            "std_msgs/msg/String",
            "slam",
            'SLAM statistics as JSON: {"mode", "scans", "keyframes", "loop_closures", "optimizations"}',
        ),
        Endpoint(
            "save_map",
            "std_msgs/msg/String",
            "std_msgs/msg/String",
            "mapper",
            "Save the map as PGM + YAML; request: .yaml path relative to the mapper's `maps_dir` (default `maps/`; "
            'paths outside it are refused; empty = the configured `save_path`); reply: JSON {"yaml": path}',
        ),
        Endpoint(
            "navigate",
            "mjnav_msgs/msg/NavigateRequest",
            "mjnav_msgs/msg/NavigateResponse",
            "planner",
            "Drive to a pose (Nav2's NavigateToPose): replies accepted with a goal id, or rejected with a GoalStatus "
            "error code; feedback and result follow on `goal_status`",
        ),
    )
}

#: Access-control role of a user's tools (goals, cancel, teleop, ``mjnav demo``'s mission client): the common name
#: of the operator certificate ``mjnav certs`` writes. The services' identities are their names.
OPERATOR = "operator"
#: In the rights tables: each identity, on its own key of a per-service topic or endpoint (``status/<identity>``).
OWN = "<own>"
#: In the rights tables: every identity that holds a certificate of the stack's CA.
ANYONE = "<anyone>"

#: Who may publish each topic when access control is on (``mjnav up --secure``); everyone may subscribe to
#: everything. The router's ACL rules are generated from this table (:mod:`mjnav.bus.acl`), and a test checks that
#: every publisher a service declares is allowed by it.
PUBLISH_RIGHTS: dict[str, tuple[str, ...]] = {
    "clock": ("sim", "uav_sim"),
    "scan": ("sim",),
    "odom": ("sim",),
    "imu": ("sim", "uav_sim"),
    "joint_states": ("sim",),
    "tf": ("sim", "slam"),
    "ground_truth": ("sim", "uav_sim"),
    "truth": ("sim",),
    "pose": ("slam",),
    "localization_health": ("slam",),
    "initialpose": ("sim", OPERATOR),
    "robot_description": ("sim",),
    "tf_static": ("sim",),
    "obstacles": ("sim",),
    "sim_status": ("sim", "uav_sim"),
    "collision_monitor": ("sim",),
    "cmd_vel": ("controller", OPERATOR),
    "cmd_vel_teleop": (OPERATOR,),
    "receipt": (OWN,),
    "map": ("slam", "mapper"),
    "costmap": ("mapper",),
    "goal": (OPERATOR,),
    "cancel": (OPERATOR,),
    "plan": ("planner",),
    "path": ("smoother",),
    "goal_status": ("planner",),
    "controller_feedback": ("controller",),
    "status": (OWN,),
    "lockstep": (OWN,),
    "gps": ("uav_sim",),
    "datum": ("uav_sim",),
    "baro": ("uav_sim",),
    "mocap": ("uav_sim",),
    "ins_odom": ("ins",),
    "ins_health": ("ins",),
    "rotor_cmd": ("flight_controller",),
    "setpoint": (OPERATOR,),
    "trajectory": (OPERATOR,),
    "arm": (OPERATOR,),
    "flight_state": ("flight_controller",),
}

#: Who may serve (answer) each endpoint when access control is on.
SERVE_RIGHTS: dict[str, tuple[str, ...]] = {
    "config": (OWN,),
    "set_param": (OWN,),
    "save_map": ("mapper",),
    "slam_info": ("slam",),
    "navigate": ("planner",),
}
#: Who may call each endpoint when access control is on (only an operator makes the mapper write files).
CALL_RIGHTS: dict[str, tuple[str, ...]] = {
    "config": (ANYONE,),
    "set_param": (OPERATOR,),
    "save_map": (OPERATOR,),
    "slam_info": (ANYONE,),
    "navigate": (OPERATOR,),
}

#: Liveliness key of a running service (a Zenoh liveliness token, not a topic).
ALIVE_PREFIX = "mjnav/alive"


def alive_key(namespace: str, service: str) -> str:
    """Liveliness token key of ``service`` in ``namespace``; ``service="*"`` matches them all."""
    check_namespace(namespace)
    return f"{ALIVE_PREFIX}/{namespace}/{service}"


#: Liveliness key prefix of the lockstep participants (services on sim time, mission clients).
LOCKSTEP_PREFIX = "mjnav/lockstep"


def lockstep_key(namespace: str, participant: str) -> str:
    """Liveliness token key of lockstep ``participant`` in ``namespace``; ``"*"`` matches them all."""
    check_namespace(namespace)
    return f"{LOCKSTEP_PREFIX}/{namespace}/{participant}"


def check_namespace(namespace: str) -> None:
    """Raise ValueError unless ``namespace`` is a valid ROS-style name (letters, digits, ``_``, ``/``)."""
    if not _NAMESPACE_RE.match(namespace):
        raise ValueError(f"invalid namespace {namespace!r}: use letters, digits and '_' (e.g. robot0)")


def topic(name: str) -> Topic:
    """The table row for ``name``; raises KeyError naming the known topics."""
    try:
        return TOPICS[name]
    except KeyError:
        raise KeyError(f"unknown topic {name!r}; known topics: {', '.join(TOPICS)}") from None


def endpoint(name: str) -> Endpoint:
    """The table row for endpoint ``name``."""
    try:
        return ENDPOINTS[name]
    except KeyError:
        raise KeyError(f"unknown endpoint {name!r}; known endpoints: {', '.join(ENDPOINTS)}") from None


def resolve_key(key: str) -> tuple[str, Topic]:
    """Split a concrete key ``<namespace>/<topic>`` into its namespace and table row.

    Per-service topics (``robot0/status/sim``) match their ``{service}`` row. Raises KeyError when no row matches.
    """
    for row in TOPICS.values():
        pattern = re.escape(row.name) + (r"/[^/]+" if row.per_service else "")
        m = re.match(rf"^(?P<ns>.+)/{pattern}$", key)
        if m and _NAMESPACE_RE.match(m.group("ns")):
            return m.group("ns"), row
    raise KeyError(f"key {key!r} matches no topic of the table (expected <namespace>/<topic>)")


def markdown_table(namespace: str = DEFAULT_NAMESPACE) -> str:
    """The topic table as Markdown, as it appears in README.md (generated; a test keeps them equal)."""
    lines = [
        "| key | type | delivery | publisher | rate | description |",
        "|---|---|---|---|---|---|",
    ]
    for row in TOPICS.values():
        key = f"{row.stack_namespace or namespace}/{row.pattern}"
        delivery = row.kind.value + (", latched" if row.latched else "")
        lines.append(f"| `{key}` | `{row.msgtype}` | {delivery} | {row.publisher} | {row.rate} | {row.description} |")
    lines.append("")
    lines.append("| endpoint (queryable) | request | reply | server | description |")
    lines.append("|---|---|---|---|---|")
    for ep in ENDPOINTS.values():
        key = f"{namespace}/{ep.pattern}"
        lines.append(f"| `{key}` | `{ep.request_type}` | `{ep.response_type}` | {ep.server} | {ep.description} |")
    lines.append("")
    lines.append(
        f"Liveliness tokens: `{ALIVE_PREFIX}/{namespace}/<service>` while a service runs, "
        f"`{LOCKSTEP_PREFIX}/{namespace}/<participant>` while a lockstep participant runs."
    )
    return "\n".join(lines)


if __name__ == "__main__":
    print(markdown_table())

"""The topic table: every Zenoh key mjnav uses, its ROS 2 type and its delivery semantics.

Keys are ``<namespace>/<topic>`` — the mapping zenoh-bridge-ros2dds uses for ROS 2 topic ``/<namespace>/<topic>`` —
so a ROS 2 user behind the bridge sees ordinary topics. Nothing outside this module spells a key.

Delivery: every message is published reliably and never dropped in transit (a publisher waits under congestion:
lockstep runs must see every message); the kinds differ at the subscriber:
- ``SNAPSHOT``: latest wins; subscribers keep only the newest message (scan, odom, map, cmd_vel …).
- ``EVENT``: subscribers queue every message until it is handled (goal, cancel …).
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
        subscribers: the services that must receive every message of an event topic: a publisher asking for
            delivery receipts (``mjnav pub``, :meth:`mjnav.bus.Bus.put_confirmed`) waits for one from each.
    """

    name: str
    msgtype: str
    kind: Kind
    publisher: str
    rate: str
    description: str
    per_service: bool = False
    express: bool = False
    subscribers: tuple[str, ...] = ()

    def key(self, namespace: str = DEFAULT_NAMESPACE, service: str | None = None) -> str:
        """The Zenoh key of this topic in ``namespace``; per-service topics need ``service``
        (``"*"`` gives a wildcard over all services)."""
        return _key(self.name, self.per_service, namespace, service)

    @property
    def pattern(self) -> str:
        """The key under the namespace as documented, e.g. ``status/<service>``."""
        return f"{self.name}/<service>" if self.per_service else self.name


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
            "50 Hz",
            "Wheel-encoder odometry, `odom` → `base_link`, drifts",
        ),
        Topic("imu", "sensor_msgs/msg/Imu", _S, "sim", "100 Hz", "Gyro and accelerometer, frame `imu`"),
        Topic("joint_states", "sensor_msgs/msg/JointState", _S, "sim", "50 Hz", "Wheel positions and rates"),
        Topic("tf", "tf2_msgs/msg/TFMessage", _S, "sim", "50 Hz", "Transform `odom` → `base_link`"),
        Topic(
            "ground_truth",
            "geometry_msgs/msg/PoseStamped",
            _S,
            "sim",
            "50 Hz",
            "True pose `map` → `base_link`",
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
            "cmd_vel",
            "geometry_msgs/msg/Twist",
            _S,
            "controller",
            "20 Hz",
            "Velocity command (linear.x m/s, angular.z rad/s)",
        ),
        Topic("map", "nav_msgs/msg/OccupancyGrid", _S, "mapper", "2 Hz", "Log-odds occupancy map, frame `map`"),
        Topic("costmap", "nav_msgs/msg/OccupancyGrid", _S, "mapper", "2 Hz", "Inflated costmap, 0–100"),
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
        Topic("plan", "nav_msgs/msg/Path", _S, "planner", "on change", "Raw grid plan in `map`"),
        Topic("path", "nav_msgs/msg/Path", _S, "smoother", "on change", "Smoothed path the controller follows"),
        Topic(
            "goal_status",
            "mjnav_msgs/msg/GoalStatus",
            _E,
            "planner, controller",
            "on change",
            "Goal lifecycle with a typed failure reason",
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
        key = f"{namespace}/{row.pattern}"
        lines.append(
            f"| `{key}` | `{row.msgtype}` | {row.kind.value} | {row.publisher} | {row.rate} | {row.description} |"
        )
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

"""The ros_bridge service: the stack's topics on rmw_zenoh's key expressions, for ROS 2 nodes on
``RMW_IMPLEMENTATION=rmw_zenoh_cpp`` (``mjnav up --ros rmw_zenoh``).

Outbound, every topic of the table that is not per-service (``clock``, ``scan``, ``tf``, ``map`` …) is relayed from
``<ns>/<topic>`` to ``<domain>/<ns>/<topic>/<dds type>/<RIHS01 hash>`` with rmw_zenoh's attachment (sequence
number, source time, the bridge publisher's GID), and the publisher's liveliness token (``MP``) is declared under
a ROS 2 node named after the service that publishes the topic (``/robot0/sim``), from the first message on: so
``ros2 topic list`` shows what the stack really publishes. Inbound, the operator's topics (``cmd_vel``, ``goal``,
``cancel``, ``initialpose`` …) are subscribed on their rmw_zenoh keys, with a subscription token (``MS``) under the
node ``/<ns>/ros_bridge``, and relayed to ``<ns>/<topic>``. Payloads are CDR on both sides and pass unchanged; the
services that receive them validate them as they validate anything else. Neither direction sees the other's
relays (Zenoh's ``allowed_origin=REMOTE``), so nothing loops.

The bridge is a relay on wall time, not a lockstep participant: what a ROS 2 node sends reaches the services like
any other operator input. Durability is volatile on the ROS 2 side (a late-joining ROS 2 subscriber gets the next
``map`` or ``tf_static``, not the last one).
"""

from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass
from typing import Any

from mjnav.bus import RawSample, cdr_encoding
from mjnav.bus.raw import undeclare
from mjnav.msgs import rmw_zenoh
from mjnav.msgs.topics import OPERATOR, PUBLISH_RIGHTS, TOPICS, Topic
from mjnav.runtime import Service

#: The topics a ROS 2 node may send into the stack by default: those the operator may publish.
INBOUND = tuple(name for name, rights in PUBLISH_RIGHTS.items() if OPERATOR in rights)


@dataclass(frozen=True)
class RosBridgeConfig:
    """ros_bridge settings (``services/ros_bridge.toml``).

    Attributes:
        rate_hz: rate of the (bookkeeping) loop, wall time.
        domain_id: ROS domain id (``ROS_DOMAIN_ID`` of the ROS 2 nodes); -1 = this process's ``ROS_DOMAIN_ID``,
            else 0.
        outbound: topics relayed to ROS 2 (empty = every topic of the table that is not per-service).
        inbound: topics a ROS 2 node may publish into the stack (default: the operator's topics).
    """

    rate_hz: float = 1.0
    domain_id: int = -1
    outbound: tuple[str, ...] = ()
    inbound: tuple[str, ...] = INBOUND

    def __post_init__(self) -> None:
        if not self.rate_hz > 0.0:
            raise ValueError(f"rate_hz must be > 0, got {self.rate_hz}")
        if self.domain_id != -1:
            rmw_zenoh.check_domain(self.domain_id)
        for name in self.outbound + self.inbound:
            row = TOPICS.get(name)
            if row is None:
                raise ValueError(f"unknown topic {name!r}; topics: {', '.join(TOPICS)}")
            if row.per_service:
                raise ValueError(f"topic {name!r} is per service: it is not bridged")
        for name in self.inbound:
            if OPERATOR not in PUBLISH_RIGHTS.get(name, ()):
                raise ValueError(f"inbound topic {name!r} is not one an operator may publish")

    def resolved_domain(self) -> int:
        """The domain id in force (``ROS_DOMAIN_ID`` when ``domain_id`` is -1)."""
        if self.domain_id != -1:
            return self.domain_id
        text = os.environ.get("ROS_DOMAIN_ID", "").strip() or "0"
        try:
            domain = int(text)
        except ValueError:
            raise ValueError(f"ROS_DOMAIN_ID must be an integer, got {text!r}") from None
        rmw_zenoh.check_domain(domain)
        return domain


class _Outbound:
    """Relays one topic from its mjnav key to its rmw_zenoh key (declared at its first message)."""

    def __init__(self, bridge: RosBridgeService, row: Topic) -> None:
        self.row = row
        self.key = rmw_zenoh.data_key(bridge.domain, row, bridge.bus.namespace)
        self.gid = os.urandom(rmw_zenoh.GID_BYTES)
        self.sequence = 0
        self._bridge = bridge
        self._pub: Any = None
        self._lock = threading.Lock()

    def on_sample(self, sample: RawSample) -> None:
        with self._lock:
            if self._bridge.bus.closing:
                return
            if self._pub is None:
                self._pub = self._bridge.declare_outbound(self.row, self.key)
            self.sequence += 1
            attachment = rmw_zenoh.attachment(self.sequence, time.time_ns(), self.gid)
            self._pub.put(sample.payload, attachment=attachment)
        self._bridge.count("out")


class RosBridgeService(Service[RosBridgeConfig]):
    """Relay between mjnav's keys and rmw_zenoh's."""

    name = "ros_bridge"
    config_class = RosBridgeConfig
    uses_sim_time = False
    runs_alone = True  # it ignores what its own session publishes (no echo of its own relaying)

    def configure(self) -> None:
        cfg = self.config
        self.domain = cfg.resolved_domain()
        self.session_id = self.bus.session_id
        ns = self.bus.namespace
        self._lock = threading.Lock()
        self._nodes: dict[str, int] = {}
        self._entities = 0
        self._declared: list[Any] = []
        self.counts = {"out": 0, "in": 0}
        outbound = cfg.outbound or tuple(name for name, row in TOPICS.items() if not row.per_service)
        for name in outbound:
            relay = _Outbound(self, TOPICS[name])
            self._declared.append(self.bus.subscribe_raw(TOPICS[name].key(ns), relay.on_sample, remote_only=True))
        for name in cfg.inbound:
            self._declare_inbound(TOPICS[name])
        self.log.info(
            "rmw_zenoh bridge on ROS domain %d: %d topics out, %d in (%s)",
            self.domain,
            len(outbound),
            len(cfg.inbound),
            ", ".join(cfg.inbound),
        )

    def _token(self, key: str) -> None:
        self._declared.append(self.bus.declare_token(key))

    def _node(self, node: str) -> int:
        """The id of ROS 2 node ``/<ns>/<node>``, declaring its token the first time (call with the lock held)."""
        node_id = self._nodes.get(node)
        if node_id is None:
            node_id = self._nodes[node] = len(self._nodes)
            self._token(rmw_zenoh.node_token(self.domain, self.session_id, node_id, self.bus.namespace, node))
        return node_id

    def _endpoint(self, kind: str, node: str, row: Topic) -> None:
        with self._lock:
            node_id = self._node(node)
            self._entities += 1
            key = rmw_zenoh.endpoint_token(
                self.domain, self.session_id, node_id, self._entities, kind, self.bus.namespace, node, row
            )
            self._token(key)

    def declare_outbound(self, row: Topic, key: str) -> Any:
        """Declare the rmw_zenoh publisher of ``row`` and its token, under the node of the topic's publisher."""
        pub = self.bus.publisher_raw(key, encoding="application/cdr", row=row, remote_only=True)
        self._declared.append(pub)
        self._endpoint("MP", row.publisher.split(",")[0].strip(), row)
        return pub

    def _declare_inbound(self, row: Topic) -> None:
        ns = self.bus.namespace
        pub = self.bus.publisher_raw(row.key(ns), encoding=str(cdr_encoding(row.msgtype)), row=row)
        self._declared.append(pub)

        def on_sample(sample: RawSample) -> None:
            self.count("in")
            pub.put(sample.payload)

        key = rmw_zenoh.data_key(self.domain, row, ns)
        self._declared.append(self.bus.subscribe_raw(key, on_sample, remote_only=True))
        self._endpoint("MS", self.name, row)

    def count(self, direction: str) -> None:
        """Count one relayed message (``"out"`` or ``"in"``)."""
        with self._lock:
            self.counts[direction] += 1

    def step(self, now: float) -> None:
        """Nothing to do per step: the relays run in Zenoh's callbacks (the loop keeps the status heartbeat)."""

    def deactivate(self) -> None:
        for entity in reversed(self._declared):
            undeclare(entity)
        self._declared.clear()
        self.log.info("relayed %d messages to ROS 2, %d from ROS 2", self.counts["out"], self.counts["in"])

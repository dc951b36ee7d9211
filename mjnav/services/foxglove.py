"""The foxglove service: a Foxglove WebSocket server streaming the stack's topics live (``mjnav up --foxglove``).

Every topic of the table that is not per-service is offered as a channel named like its ROS 2 topic
(``/robot0/scan``), with the ROS 2 schema of its type (``ros2msg`` encoding: the ``.msg`` text and its
dependencies) and CDR messages — the bytes the bus already carries, passed on unchanged, so the Foxglove app decodes
them as it decodes a ROS 2 bag and draws ``map``, ``scan``, ``tf``, ``path`` … in its 3D panel. A payload without
the topic's CDR encoding is dropped. The service only reads from the bus (it declares no publisher), and logs a
message only while a client is subscribed to its channel. ``services/foxglove_layout.json`` is a layout for the
Foxglove app (import it from the app's layout menu) that shows the stack in namespace ``robot0``.
"""

from __future__ import annotations

import importlib.util
import time
from dataclasses import dataclass
from typing import Any

from mjnav.bus import BYTES_ENCODING, RawSample, cdr_encoding
from mjnav.bus.raw import undeclare
from mjnav.msgs import message_definition
from mjnav.msgs.topics import TOPICS, Topic
from mjnav.runtime import Service


@dataclass(frozen=True)
class FoxgloveConfig:
    """foxglove settings (``services/foxglove.toml``).

    Attributes:
        rate_hz: rate of the (bookkeeping) loop, wall time.
        host: interface the WebSocket server binds to (loopback by default; ``0.0.0.0`` serves the network).
        port: WebSocket port (Foxglove's default 8765; 0 picks a free one).
        topics: topics streamed (empty = every topic of the table that is not per-service).
    """

    rate_hz: float = 1.0
    host: str = "127.0.0.1"
    port: int = 8765
    topics: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.rate_hz > 0.0:
            raise ValueError(f"rate_hz must be > 0, got {self.rate_hz}")
        if not 0 <= self.port <= 65535:
            raise ValueError(f"port must be 0..65535, got {self.port}")
        if not self.host:
            raise ValueError("host must not be empty (127.0.0.1 = this machine only, 0.0.0.0 = every interface)")
        for name in self.topics:
            row = TOPICS.get(name)
            if row is None:
                raise ValueError(f"unknown topic {name!r}; topics: {', '.join(TOPICS)}")
            if row.per_service:
                raise ValueError(f"topic {name!r} is per service: it is not streamed")
        if importlib.util.find_spec("foxglove") is None:
            raise ValueError("the foxglove service needs foxglove-sdk: pip install -e '.[foxglove]'")


def streamed_topics(config: FoxgloveConfig) -> list[Topic]:
    """The topic rows the service streams."""
    names = config.topics or tuple(name for name, row in TOPICS.items() if not row.per_service)
    return [TOPICS[name] for name in names]


class _Relay:
    """One topic: its Foxglove channel, fed from its Zenoh key."""

    def __init__(self, channel: Any, row: Topic) -> None:
        self.channel = channel
        self.encoding = str(cdr_encoding(row.msgtype))
        self.sent = 0
        self.dropped = 0

    def on_sample(self, sample: RawSample) -> None:
        if not self.channel.has_sinks():  # no client subscribed: nothing to do
            return
        if sample.encoding not in (self.encoding, BYTES_ENCODING):
            self.dropped += 1
            return
        self.channel.log(sample.data(), log_time=time.time_ns())
        self.sent += 1


class FoxgloveService(Service[FoxgloveConfig]):
    """Foxglove WebSocket server fed from the bus."""

    name = "foxglove"
    config_class = FoxgloveConfig
    uses_sim_time = False
    port_settings = ("port",)

    def configure(self) -> None:
        import foxglove

        cfg = self.config
        self.context = foxglove.Context()
        self.server = foxglove.start_server(name="mjnav", host=cfg.host, port=cfg.port, context=self.context)
        self.port = self.server.port
        ns = self.bus.namespace
        self.relays: dict[str, _Relay] = {}
        self._subs: list[Any] = []
        for row in streamed_topics(cfg):
            schema = foxglove.Schema(
                name=row.msgtype, encoding="ros2msg", data=message_definition(row.msgtype).encode()
            )
            channel = foxglove.Channel(f"/{ns}/{row.name}", schema=schema, message_encoding="cdr", context=self.context)
            relay = self.relays[row.name] = _Relay(channel, row)
            self._subs.append(self.bus.subscribe_raw(row.key(ns), relay.on_sample))
        self.log.info("Foxglove WebSocket server on ws://%s:%d, %d topics", cfg.host, self.port, len(self.relays))

    def step(self, now: float) -> None:
        """Nothing to do per step: the relays run in Zenoh's callbacks (the loop keeps the status heartbeat)."""

    def deactivate(self) -> None:
        for sub in self._subs:
            undeclare(sub)
        self._subs.clear()
        self.server.stop()
        sent = sum(r.sent for r in self.relays.values())
        dropped = sum(r.dropped for r in self.relays.values())
        self.log.info("streamed %d messages (%d dropped: not CDR of the topic's type)", sent, dropped)

"""Republish an MCAP recording on the bus with its original timing (scaled by a real-time factor).

Messages are read in log-time order and each is published when ``(log_time - first_log_time) / rtf`` wall seconds
have passed since the start, on the key it was recorded from (channel metadata ``zenoh_key``, else the topic name
without its leading ``/``), optionally moved to another namespace. Each key keeps the delivery of its topic
(snapshot or event). Channels whose topic is not in mjnav's table, or whose schema names another type than the
table's, are skipped and reported.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mjnav.bag.errors import BagError, BagFormatError
from mjnav.bag.keys import key_for_topic
from mjnav.bus import Bus, Publisher, key_matcher, wait_until
from mjnav.msgs import resolve_key

log = logging.getLogger("mjnav.bag")


@dataclass
class PlayStats:
    """What a replay published.

    Attributes:
        messages: messages published per key.
        skipped_channels: recorded topics not replayed, with the reason.
        bag_span_s: log-time span of the replayed messages, seconds.
        wall_s: wall seconds the replay took.
        max_lag_s: largest delay of a publication behind its schedule, seconds.
    """

    messages: dict[str, int] = field(default_factory=dict)
    skipped_channels: dict[str, str] = field(default_factory=dict)
    bag_span_s: float = 0.0
    wall_s: float = 0.0
    max_lag_s: float = 0.0

    @property
    def total(self) -> int:
        """Messages published."""
        return sum(self.messages.values())


def play(
    path: str | Path,
    bus: Bus,
    *,
    rtf: float = 1.0,
    key_expressions: list[str] | None = None,
    namespace: str | None = None,
    stop: threading.Event | None = None,
    wait_subscribers_s: float = 0.0,
    on_publish: Callable[[str, int], None] | None = None,
) -> PlayStats:
    """Publish the messages of an MCAP file on ``bus`` with their recorded timing.

    Args:
        path: MCAP file written by ``mjnav bag record`` (or any ``ros2``-profile MCAP with mjnav keys).
        bus: open bus to publish on.
        rtf: real-time factor: 2 plays twice as fast; 0 publishes as fast as possible.
        key_expressions: replay only keys intersecting these Zenoh key expressions (None: all).
        namespace: publish under this namespace instead of the recorded one.
        stop: set it to end the replay early.
        wait_subscribers_s: before the first message, wait up to this long for a subscriber on any replayed key.
        on_publish: called with (key, log_time_ns) after each publication.

    Raises:
        BagFormatError: the file is not a readable MCAP file.
        BagError: bad arguments (negative ``rtf``, bad namespace).
    """
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    if not rtf >= 0.0:
        raise BagError(f"rtf must be >= 0 (0 = as fast as possible), got {rtf}")
    try:
        wanted = key_matcher(key_expressions)
    except ValueError as exc:
        raise BagError(str(exc)) from exc
    stop = stop or threading.Event()
    stats = PlayStats()
    publishers: dict[int, Publisher] = {}
    try:
        with open(path, "rb") as f:
            reader = make_reader(f)
            summary = reader.get_summary()
            if summary is None:
                raise BagFormatError(f"{path} has no summary section (unfinished recording?); cannot replay it")
            for channel in summary.channels.values():
                pub = _publisher(bus, channel, summary.schemas.get(channel.schema_id), namespace, wanted, stats)
                if pub is not None:
                    publishers[channel.id] = pub
            if not publishers:
                raise BagFormatError(f"{path} holds no channel of an mjnav topic to replay")
            if wait_subscribers_s > 0 and not wait_until(
                lambda: any(p.wait_for_subscribers(0.0) for p in publishers.values()), wait_subscribers_s, 0.05
            ):
                log.warning("no subscriber on the replayed keys after %.1f s; playing anyway", wait_subscribers_s)
            start_wall = time.monotonic()
            first_ns: int | None = None
            last_ns = 0
            for _schema, channel, message in reader.iter_messages(log_time_order=True):
                pub = publishers.get(channel.id)
                if pub is None:
                    continue
                if first_ns is None:
                    first_ns = message.log_time
                last_ns = message.log_time
                if rtf > 0:
                    due = start_wall + (message.log_time - first_ns) / 1e9 / rtf
                    if stop.wait(max(0.0, due - time.monotonic())):
                        break
                    stats.max_lag_s = max(stats.max_lag_s, time.monotonic() - due)
                elif stop.is_set():
                    break
                pub.put_bytes(message.data)
                stats.messages[pub.key] = stats.messages.get(pub.key, 0) + 1
                if on_publish is not None:
                    on_publish(pub.key, message.log_time)
            stats.wall_s = time.monotonic() - start_wall
            stats.bag_span_s = (last_ns - first_ns) / 1e9 if first_ns is not None else 0.0
    except OSError as exc:
        raise BagError(f"cannot read {path}: {exc.strerror}") from exc
    except McapError as exc:
        raise BagFormatError(f"{path} is not a readable MCAP file: {exc}") from exc
    finally:
        for pub in publishers.values():
            pub.close()
    return stats


def _publisher(
    bus: Bus,
    channel: Any,
    schema: Any,
    namespace: str | None,
    wanted: Callable[[str], bool],
    stats: PlayStats,
) -> Publisher | None:
    key = channel.metadata.get("zenoh_key") or key_for_topic(channel.topic)
    try:
        recorded_ns, row = resolve_key(key)
    except KeyError:
        stats.skipped_channels[channel.topic] = "not an mjnav topic"
        return None
    if channel.message_encoding != "cdr":
        stats.skipped_channels[channel.topic] = f"message encoding {channel.message_encoding!r} is not cdr"
        return None
    if schema is not None and schema.name != row.msgtype:
        stats.skipped_channels[channel.topic] = f"type {schema.name} is not {row.msgtype}"
        return None
    if not wanted(key):
        stats.skipped_channels[channel.topic] = "filtered out"
        return None
    if namespace is not None and namespace != recorded_ns:
        service = key.rsplit("/", 1)[1] if row.per_service else None
        try:
            key = row.key(namespace, service)
        except ValueError as exc:
            raise BagError(str(exc)) from exc
    return Publisher(bus, row, key)

"""Summarise an MCAP file: time span, and per channel its topic, key, type, message count and rate."""

from __future__ import annotations

import datetime as dt
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from mjnav.bag.errors import BagError, BagFormatError
from mjnav.bag.keys import key_for_topic


@dataclass(frozen=True)
class ChannelInfo:
    """One channel of a bag.

    Attributes:
        topic: ROS 2 topic name (``/robot0/scan``).
        key: the Zenoh key it was recorded from (``robot0/scan``).
        msgtype: schema name (``sensor_msgs/msg/LaserScan``).
        schema_encoding: ``ros2msg`` for mjnav bags.
        message_encoding: ``cdr`` for mjnav bags.
        messages: number of messages.
        rate_hz: messages per second over the bag's span (0 for fewer than two messages).
    """

    topic: str
    key: str
    msgtype: str
    schema_encoding: str
    message_encoding: str
    messages: int
    rate_hz: float


@dataclass(frozen=True)
class BagInfo:
    """Summary of a bag.

    Attributes:
        path: the file.
        size_bytes: file size.
        profile: MCAP profile (``ros2``).
        library: writer library.
        messages: total message count.
        start_ns, end_ns: first and last log time, ns since the epoch.
        channels: per-channel summary, sorted by topic.
        complete: the file has its summary section (a finished recording).
    """

    path: Path
    size_bytes: int
    profile: str
    library: str
    messages: int
    start_ns: int
    end_ns: int
    channels: tuple[ChannelInfo, ...]
    complete: bool

    @property
    def duration_s(self) -> float:
        """Seconds between the first and last message."""
        return (self.end_ns - self.start_ns) / 1e9 if self.messages else 0.0

    def to_dict(self) -> dict[str, Any]:
        """Plain values (for JSON)."""
        data = asdict(self)
        data["path"] = str(self.path)
        data["duration_s"] = self.duration_s
        return data


def bag_info(path: str | Path) -> BagInfo:
    """Read the summary of an MCAP file (scanning the messages when the summary section is missing).

    Raises:
        BagError: the file cannot be read.
        BagFormatError: it is not an MCAP file.
    """
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    p = Path(path)
    try:
        size = p.stat().st_size
        with open(p, "rb") as f:
            reader = make_reader(f)
            header = reader.get_header()
            summary = reader.get_summary()
            if summary is not None and summary.statistics is not None:
                stats = summary.statistics
                counts = dict(stats.channel_message_counts)
                start, end, total = stats.message_start_time, stats.message_end_time, stats.message_count
                channels, schemas, complete = summary.channels, summary.schemas, True
            else:
                counts, channels, schemas = {}, {}, {}
                start, end, total = 0, 0, 0
                for schema, channel, message in reader.iter_messages(log_time_order=False):
                    channels[channel.id] = channel
                    if schema is not None:
                        schemas[schema.id] = schema
                    counts[channel.id] = counts.get(channel.id, 0) + 1
                    start = message.log_time if total == 0 else min(start, message.log_time)
                    end = max(end, message.log_time)
                    total += 1
                complete = False
    except OSError as exc:
        raise BagError(f"cannot read {p}: {exc.strerror}") from exc
    except McapError as exc:
        raise BagFormatError(f"{p} is not a readable MCAP file: {exc}") from exc
    span = (end - start) / 1e9
    rows = []
    for cid, channel in channels.items():
        schema = schemas.get(channel.schema_id)
        n = counts.get(cid, 0)
        rows.append(
            ChannelInfo(
                topic=channel.topic,
                key=channel.metadata.get("zenoh_key") or key_for_topic(channel.topic),
                msgtype=schema.name if schema is not None else "",
                schema_encoding=schema.encoding if schema is not None else "",
                message_encoding=channel.message_encoding,
                messages=n,
                rate_hz=(n - 1) / span if n > 1 and span > 0 else 0.0,
            )
        )
    rows.sort(key=lambda c: c.topic)
    return BagInfo(p, size, header.profile, header.library, total, start, end, tuple(rows), complete)


def format_info(info: BagInfo) -> str:
    """Human-readable summary, like ``ros2 bag info``."""

    def stamp(ns: int) -> str:
        return dt.datetime.fromtimestamp(ns / 1e9, tz=dt.UTC).isoformat(timespec="milliseconds")

    unfinished = "" if info.complete else " (no summary: unfinished recording)"
    lines = [
        f"file:      {info.path} ({info.size_bytes / 1e6:.2f} MB){unfinished}",
        f"profile:   {info.profile or '-'} ({info.library or 'unknown writer'})",
        f"duration:  {info.duration_s:.3f} s",
    ]
    if info.messages:
        lines.append(f"start:     {stamp(info.start_ns)}")
        lines.append(f"end:       {stamp(info.end_ns)}")
    lines.append(f"messages:  {info.messages}")
    if info.channels:
        width = max(len(c.topic) for c in info.channels)
        tw = max(len(c.msgtype) for c in info.channels)
        lines.append(f"channels:  {len(info.channels)}")
        lines.append(f"  {'topic':{width}s}  {'type':{tw}s}  {'messages':>8s}  {'rate Hz':>8s}")
        for c in info.channels:
            lines.append(f"  {c.topic:{width}s}  {c.msgtype:{tw}s}  {c.messages:8d}  {c.rate_hz:8.2f}")
    return "\n".join(lines)

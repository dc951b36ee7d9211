"""Record mjnav keys to MCAP with their ROS 2 schemas (``ros2`` profile: schemas ``ros2msg``, messages ``cdr``).

Every channel carries the full ``.msg`` definition of its type (:func:`mjnav.msgs.message_definition`, the text
rosbag2 writes), so Foxglove, ``ros2 bag`` with the MCAP plugin and ``mcap_ros2.reader`` decode the file without
knowing mjnav. Payloads are stored as received (CDR with its encapsulation header) after a decode check: a payload
of a key that matches no topic of the table, with a non-CDR encoding, or that does not decode as its type is
skipped and counted, never written. Log and publish times are the receive time (wall clock, ns since the epoch).
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import mjnav
from mjnav.bag.errors import BagError
from mjnav.bag.keys import topic_for_key
from mjnav.msgs import codec, message_definition, resolve_key

if TYPE_CHECKING:
    from mjnav.bus import RawSample

log = logging.getLogger("mjnav.bag")

#: Compression of MCAP chunks by name.
COMPRESSIONS = ("zstd", "lz4", "none")


@dataclass
class RecordStats:
    """What a recording holds.

    Attributes:
        messages: messages written per key.
        skipped: payloads not written, per reason (``unknown key``, ``encoding``, ``undecodable``).
        first_ns, last_ns: receive times of the first and last written message (0 when none).
    """

    messages: dict[str, int] = field(default_factory=dict)
    skipped: dict[str, int] = field(default_factory=dict)
    first_ns: int = 0
    last_ns: int = 0

    @property
    def total(self) -> int:
        """Messages written."""
        return sum(self.messages.values())

    @property
    def span_s(self) -> float:
        """Seconds between the first and last written message."""
        return (self.last_ns - self.first_ns) / 1e9 if self.total else 0.0


class BagWriter:
    """An open MCAP file receiving mjnav messages; safe to call from Zenoh's callback threads.

    Args:
        path: output file (created or truncated).
        compression: ``zstd`` (default), ``lz4`` or ``none``.

    Raises:
        BagError: the file cannot be created or the compression is unknown.
    """

    def __init__(self, path: str | Path, *, compression: str = "zstd") -> None:
        from mcap.writer import CompressionType, Writer

        if compression not in COMPRESSIONS:
            raise BagError(f"compression must be one of {COMPRESSIONS}, got {compression!r}")
        self.path = Path(path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file: IO[bytes] = open(self.path, "wb")  # noqa: SIM115 (closed in close())
        except OSError as exc:
            raise BagError(f"cannot write {self.path}: {exc.strerror}") from exc
        kind = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}[compression]
        self._writer = Writer(self._file, compression=kind)
        self._writer.start(profile="ros2", library=f"mjnav {mjnav.__version__}")
        self._lock = threading.Lock()
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self.stats = RecordStats()
        self._closed = False

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _skip(self, reason: str) -> None:
        self.stats.skipped[reason] = self.stats.skipped.get(reason, 0) + 1

    def _channel(self, key: str, msgtype: str, delivery: str) -> int:
        channel = self._channels.get(key)
        if channel is None:
            schema = self._schemas.get(msgtype)
            if schema is None:
                schema = self._writer.register_schema(msgtype, "ros2msg", message_definition(msgtype).encode())
                self._schemas[msgtype] = schema
            metadata = {"zenoh_key": key, "delivery": delivery}
            channel = self._writer.register_channel(topic_for_key(key), "cdr", schema, metadata)
            self._channels[key] = channel
        return channel

    def add(
        self, key: str, payload: bytes, *, encoding: str = "application/cdr", log_time_ns: int | None = None
    ) -> bool:
        """Write one payload received on ``key``; returns False (and counts why) when it is skipped.

        Args:
            key: concrete Zenoh key, e.g. ``robot0/scan``.
            payload: CDR bytes as received.
            encoding: the sample's Zenoh encoding (``application/cdr[;type]`` or ``zenoh/bytes`` are accepted).
            log_time_ns: receive time, ns since the epoch (default now).
        """
        t = time.time_ns() if log_time_ns is None else log_time_ns
        try:
            _, row = resolve_key(key)
        except KeyError:
            with self._lock:
                self._skip("unknown key")
            return False
        base, _, schema = encoding.partition(";")
        if base not in ("application/cdr", "zenoh/bytes") or (schema and schema != row.msgtype):
            with self._lock:
                self._skip("encoding")
            return False
        try:
            codec.decode(payload, row.msgtype)
        except codec.MessageError:
            with self._lock:
                self._skip("undecodable")
            return False
        with self._lock:
            if self._closed:
                return False
            channel = self._channel(key, row.msgtype, row.kind.value)
            seq = self._sequence.get(channel, 0)
            self._sequence[channel] = seq + 1
            self._writer.add_message(channel, log_time=t, data=payload, publish_time=t, sequence=seq)
            stats = self.stats
            stats.messages[key] = stats.messages.get(key, 0) + 1
            if stats.first_ns == 0 or t < stats.first_ns:
                stats.first_ns = t
            stats.last_ns = max(stats.last_ns, t)
        return True

    def close(self) -> RecordStats:
        """Write the summary (index, statistics) and close the file; idempotent."""
        with self._lock:
            if not self._closed:
                self._closed = True
                try:
                    self._writer.finish()
                finally:
                    self._file.close()
        return self.stats


def record(
    bus: Any,
    path: str | Path,
    key_expressions: list[str],
    *,
    duration_s: float | None = None,
    stop: threading.Event | None = None,
    compression: str = "zstd",
    max_messages: int | None = None,
) -> RecordStats:
    """Record every sample matching ``key_expressions`` on ``bus``'s session into ``path``.

    Runs until ``duration_s`` wall seconds pass, ``stop`` is set, or ``max_messages`` are written.

    Args:
        bus: an open :class:`mjnav.bus.Bus` (only its Zenoh session is used).
        path: output MCAP file.
        key_expressions: Zenoh key expressions such as ``robot0/**`` (see :func:`mjnav.bag.keys.key_expressions`).
        duration_s: wall seconds to record (None: until ``stop``).
        stop: set it to end the recording early (e.g. from a signal handler).
        compression: ``zstd``, ``lz4`` or ``none``.
        max_messages: stop after this many written messages.

    Returns:
        The recording's statistics (the file is finished and closed).
    """
    from mjnav.bus.raw import undeclare

    stop = stop or threading.Event()
    with BagWriter(path, compression=compression) as writer:

        def on_sample(sample: RawSample) -> None:
            ok = writer.add(sample.key, sample.data(), encoding=sample.encoding)
            if ok and max_messages is not None and writer.stats.total >= max_messages:
                stop.set()

        subscribers = [bus.subscribe_raw(expr, on_sample) for expr in key_expressions]
        log.info("recording %s to %s", ", ".join(key_expressions), writer.path)
        try:
            stop.wait(duration_s)  # until the duration passes or someone sets stop
        finally:
            for sub in subscribers:
                undeclare(sub)
        return writer.close()

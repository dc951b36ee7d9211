"""Raw samples: bytes on any key, for the relays that pass payloads through without decoding them.

The ROS 2 bridge (rmw_zenoh's keys), the Foxglove relay and the bag recorder and player move payloads between keys
or to files as they are. They go through the same transport as every typed topic — the bus's session, its QoS
(:func:`~mjnav.bus.bus.publisher_qos`), its clean-up — via :meth:`mjnav.bus.Bus.subscribe_raw` (callbacks on
Zenoh's callback thread, not the network thread: a relay's file or socket I/O never holds the network up),
:meth:`~mjnav.bus.Bus.publisher_raw` and :meth:`~mjnav.bus.Bus.declare_token`; nothing outside ``mjnav.bus``
opens or drives a Zenoh session itself.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Any

import zenoh

log = logging.getLogger("mjnav.bus")

#: The encoding of untyped bytes (what zenoh-bridge-ros2dds sends).
BYTES_ENCODING = str(zenoh.Encoding.ZENOH_BYTES)


class RawSample:
    """One received sample, undecoded.

    Attributes:
        key: the key it was published on.
        encoding: its encoding, e.g. ``application/cdr;sensor_msgs/msg/LaserScan``.
        attachment: its attachment bytes (None without one).
    """

    __slots__ = ("_sample", "attachment", "encoding", "key")

    def __init__(self, sample: zenoh.Sample) -> None:
        self._sample = sample
        self.key = str(sample.key_expr)
        self.encoding = str(sample.encoding)
        attachment = sample.attachment
        self.attachment = attachment.to_bytes() if attachment is not None else None

    @property
    def payload(self) -> Any:
        """The payload as the transport holds it: hand it to :meth:`RawPublisher.put` without a copy."""
        return self._sample.payload

    def data(self) -> bytes:
        """The payload's bytes."""
        return self._sample.payload.to_bytes()


class RawPublisher:
    """Puts payloads on one key (see :meth:`mjnav.bus.Bus.publisher_raw`)."""

    def __init__(self, pub: zenoh.Publisher, key: str) -> None:
        self._pub = pub
        self.key = key

    def put(self, payload: Any, attachment: bytes | None = None) -> None:
        """Publish ``payload`` (bytes, or a :attr:`RawSample.payload` passed through) with ``attachment``."""
        self._pub.put(payload, attachment=attachment)

    def undeclare(self) -> None:
        """Stop publishing (idempotent; quiet when the session is already closing)."""
        undeclare(self._pub)


def undeclare(entity: Any) -> None:
    """Undeclare a Zenoh entity, quietly when the session is already closing."""
    try:
        entity.undeclare()
    except zenoh.ZError as exc:
        log.debug("undeclare failed: %s", exc)


def check_key_expr(expr: str) -> None:
    """Whether ``expr`` is a valid key expression (``robot0/scan``, ``robot0/status/*``, ``robot1/**``).

    Raises:
        ValueError: it is not, with Zenoh's reason.
    """
    try:
        zenoh.KeyExpr(expr)
    except zenoh.ZError as exc:
        raise ValueError(f"invalid key expression {expr!r}: {exc}") from exc


def key_matcher(exprs: Sequence[str] | None) -> Callable[[str], bool]:
    """A test of whether a key intersects any of the key expressions ``exprs`` (all keys match when None or empty).

    Raises:
        ValueError: an invalid key expression.
    """
    if not exprs:
        return lambda key: True
    for expr in exprs:
        check_key_expr(expr)
    parsed = [zenoh.KeyExpr(e) for e in exprs]
    return lambda key: any(e.intersects(zenoh.KeyExpr(key)) for e in parsed)

"""Typed publish/subscribe and request/reply over Zenoh, keyed by the topic table.

A :class:`Bus` wraps one Zenoh session and one robot namespace. Publishers encode ROS 2 messages to CDR and check
their type against the table; subscriptions decode and validate every payload in Zenoh's callback thread and keep
the newest message (snapshot topics) or every message (event topics). A payload that does not decode or validate is
counted and logged with its key and the reason — it never reaches the service and never raises into it.
"""

from __future__ import annotations

import ctypes
import logging
import struct
import threading
import time
import uuid
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import zenoh
import zenoh.ext

from mjnav.bus.config import BusConfig
from mjnav.bus.raw import RawPublisher, RawSample
from mjnav.msgs import codec
from mjnav.msgs.topics import (
    DEFAULT_NAMESPACE,
    Kind,
    Topic,
    alive_key,
    check_namespace,
    endpoint,
    lockstep_key,
    topic,
)
from mjnav.msgs.validate import validate, validator

log = logging.getLogger("mjnav.bus")

#: Zenoh encodings accepted for CDR payloads (our own, plain bytes as zenoh-bridge-ros2dds sends them).
_CDR_ENCODINGS = ("application/cdr", "zenoh/bytes")
#: Rejections per key logged in full before the log is thinned to one line per second.
_LOG_FIRST = 10


class RemoteError(RuntimeError):
    """A request/reply endpoint answered with an error."""


class NoReply(TimeoutError):
    """No endpoint answered a request within its timeout."""


class BusUnavailable(ConnectionError):
    """The Zenoh session could not be opened: no router answered in time, or a listen port is taken."""


class NotDelivered(TimeoutError):
    """An event message was not confirmed by every subscriber the topic table names (see
    :meth:`Bus.put_confirmed`).

    Attributes:
        missing: the services whose receipt did not arrive.
    """

    def __init__(self, message: str, missing: list[str]) -> None:
        super().__init__(message)
        self.missing = missing


#: Zenoh attachment prefix of an event sample that asks its subscribers for a delivery receipt.
RECEIPT_REQUEST = b"receipt="
#: Receipt requests a subscription remembers, so that a resent event is confirmed again but delivered once.
_RECENT_REQUESTS = 4096
#: Wall seconds :meth:`Bus.put_confirmed` waits for a receipt before it sends that event again.
RESEND_AFTER_S = 1.0
#: Zenoh attachment prefix of a sample sent at a known sim time (:attr:`Bus.sim_time`): 8 bytes of a little-endian
#: float64 follow (then, on an event sample, possibly a receipt request).
SIM_TIME_TAG = b"t="
_SIM_TIME = struct.Struct("<d")
_TAG_LEN = len(SIM_TIME_TAG) + _SIM_TIME.size


class Gate(Protocol):
    """Staged delivery, as the bus sees it (the runtime implements it: :class:`mjnav.runtime.simtime.SimTimeGate`)."""

    def stage(self, sub: Subscription, key: str, msg: Any, sent_at: float | None) -> None:
        """Take an accepted sample of ``sub`` (sent at sim time ``sent_at``, None when untagged) to deliver later."""

    def defer(self, action: Callable[[], None]) -> None:
        """Take an action to run in order with the samples staged around it."""


def cdr_encoding(msgtype: str) -> zenoh.Encoding:
    """The Zenoh encoding mjnav puts on its samples: ``application/cdr;<ros type>``."""
    return zenoh.Encoding.APPLICATION_CDR.with_schema(msgtype)


@dataclass
class BusStats:
    """Message counters of one bus (all subscriptions and publishers of a process)."""

    received: int = 0
    rejected: int = 0
    published: int = 0
    rejected_by_key: dict[str, int] = field(default_factory=dict)
    last_rejection: str = ""


class _RejectLog:
    """Logs rejections with key and reason: the first few per key in full, then at most one line per second."""

    def __init__(self) -> None:
        self._count: dict[str, int] = {}
        self._last_log: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}

    def __call__(self, key: str, reason: str) -> None:
        n = self._count.get(key, 0) + 1
        self._count[key] = n
        now = time.monotonic()
        if n <= _LOG_FIRST or now - self._last_log.get(key, 0.0) >= 1.0:
            extra = self._suppressed.pop(key, 0)
            more = f" ({extra} more since last report)" if extra else ""
            log.warning("rejected message on %s: %s%s", key, reason, more)
            self._last_log[key] = now
        else:
            self._suppressed[key] = self._suppressed.get(key, 0) + 1


def publisher_qos(row: Topic | None) -> dict[str, Any]:
    """Zenoh publisher options of a topic (None: of any key that is not a topic's): reliable and blocking for every
    topic, at one priority.

    Nothing is dropped in transit — a lockstep step must see every message its peers sent before it, a lost
    costmap or clock would change or stall the run — and one priority keeps one publisher's messages in the order
    they were sent whatever their topic (a participant's messages reach the others before its ``lockstep``
    report). Only the topics that close a lockstep round (clock, lockstep reports) are ``express``; the others are
    batched, which keeps throughput up when the sim publishes thousands of messages per second. Snapshot and event
    topics differ only at the subscriber (newest kept, or every message queued).
    """
    return {
        "congestion_control": zenoh.CongestionControl.BLOCK,
        "reliability": zenoh.Reliability.RELIABLE,
        "priority": zenoh.Priority.DATA,
        "express": row is not None and row.express,
    }


#: Messages a latched topic's publisher keeps for subscribers that join later (the newest).
LATCH_DEPTH = 1


class Publisher:
    """Publishes the messages of one topic (reliably: see :func:`publisher_qos`).

    A latched topic's publisher is Zenoh's advanced publisher with a cache of :data:`LATCH_DEPTH` (ROS 2's
    transient-local durability): a subscriber that joins later receives the newest message from it at once. Its
    samples carry a sequence number (sample-miss detection), which is what the cache needs when the session does
    not timestamp its samples. Never publish on a latched key from a callback of a subscription to that same key on
    the same session (this bus or one :meth:`Bus.sharing` it): Zenoh delivers the sample to that subscription while
    its callback holds the subscription's lock, and the put never returns (publish from a step, or from another
    session).
    """

    def __init__(self, bus: Bus, row: Topic, key: str) -> None:
        self.topic = row
        self.key = key
        self._bus = bus
        self._pub: Any
        if row.latched:
            self._pub = zenoh.ext.declare_advanced_publisher(
                bus.session,
                key,
                encoding=cdr_encoding(row.msgtype),
                cache=zenoh.ext.CacheConfig(LATCH_DEPTH),
                sample_miss_detection=zenoh.ext.MissDetectionConfig(heartbeat=None, sporadic_heartbeat=None),
                publisher_detection=True,
                **publisher_qos(row),
            )
        else:
            self._pub = bus.session.declare_publisher(key, encoding=cdr_encoding(row.msgtype), **publisher_qos(row))
        self._encode = codec.encoder(row.msgtype)

    def put(self, msg: Any, *, receipt_id: str | None = None) -> None:
        """Encode ``msg`` (must be of the topic's type) and publish it; with ``receipt_id`` every event subscriber
        answers on ``receipt/<service>`` (see :meth:`Bus.put_confirmed`)."""
        self.put_bytes(self._encode(msg), receipt_id=receipt_id)

    def put_bytes(self, payload: bytes, *, receipt_id: str | None = None) -> None:
        """Publish an already-encoded CDR payload (nothing, once the bus is closing: a callback still running
        while :meth:`Bus.close` undeclares everything must not fail on it)."""
        if self._bus.closing:
            return
        t = self._bus.sim_time
        attachment = b"" if t is None else SIM_TIME_TAG + _SIM_TIME.pack(t)
        if receipt_id is not None:
            attachment += RECEIPT_REQUEST + receipt_id.encode()
        if attachment:
            self._pub.put(payload, attachment=attachment)
        else:
            self._pub.put(payload)
        self._bus._count_published()

    def wait_for_subscribers(self, timeout_s: float) -> bool:
        """Block until at least one subscriber matches this key (or the timeout); returns whether one did."""
        matched = threading.Event()

        def on_status(status: zenoh.MatchingStatus) -> None:
            if status.matching:
                matched.set()

        # An advanced (latched) publisher has no matching status of its own: a plain one on the key tells the same.
        probe: zenoh.Publisher = self._bus.session.declare_publisher(self.key) if self.topic.latched else self._pub
        listener = probe.declare_matching_listener(on_status)
        try:
            if probe.matching_status.matching:  # type: ignore[attr-defined]
                return True
            return matched.wait(timeout_s)
        finally:
            listener.undeclare()
            if probe is not self._pub:
                probe.undeclare()

    def close(self) -> None:
        """Undeclare the publisher."""
        self._pub.undeclare()


#: Samples a lossy subscription holds between two reads on an event topic (or a wildcard); a snapshot topic holds
#: only the newest. Older ones are dropped when it is full.
LOSSY_CAPACITY = 256
#: Wall seconds between two looks at a lossy subscription's ring buffer in :meth:`Subscription.wait`.
LOSSY_POLL_S = 0.01


class Subscription:
    """Receives one topic (or a wildcard over per-service topics), decoded and validated.

    Snapshot topics keep only the newest message per key; event topics queue every message until drained.

    A ``lossy`` subscription (an observer outside the loop, such as the viewer) can never hold its publishers
    back: Zenoh puts its samples in a ring buffer without waiting for this process (the oldest are dropped when it
    is full: :data:`LOSSY_CAPACITY`, one for a snapshot topic), and they are decoded only when read
    (:meth:`take`, :meth:`drain`, :meth:`latest`; a snapshot topic decodes only the newest). A subscriber whose
    callback runs in Zenoh's thread instead makes the router wait for it when it falls behind — and with it the
    publishers, whose samples are reliable and blocking (:func:`publisher_qos`).
    """

    def __init__(
        self,
        bus: Bus,
        row: Topic,
        key: str,
        callback: Callable[[Any], None] | None,
        immediate: bool = False,
        lossy: bool = False,
    ) -> None:
        if lossy and callback is not None:
            raise ValueError(f"{key}: a lossy subscription takes no callback (it is read with take/drain/latest)")
        self.topic = row
        self.key = key
        self._bus = bus
        self._callback = callback
        self._cond = threading.Condition()
        self._latest: Any = None
        self._by_key: dict[str, Any] = {}
        self._queue: deque[Any] = deque()
        self._fresh = False
        self._read = False  # a message was handed out (latest/take/drain/wait): wait() then waits for a newer one
        self._waiters = 0  # threads in wait(): delivery only notifies when there are any
        self.count = 0
        self._wildcard = "*" in key
        self._immediate = immediate
        self._requests: OrderedDict[bytes, None] = OrderedDict()  # receipt requests delivered lately
        self._encoding = cdr_encoding(row.msgtype)
        self._decode = codec.decoder(row.msgtype)
        self._validate = validator(row.msgtype)
        self._lossy = lossy
        self._sub: Any
        handler: Any
        if lossy:
            newest_only = row.kind is Kind.SNAPSHOT and not self._wildcard
            handler = zenoh.handlers.RingChannel(1 if newest_only else LOSSY_CAPACITY)
        else:
            # In Zenoh's network thread (not the default thread per subscriber): samples are then handled in the
            # order they arrived across all subscriptions of the session, which staged delivery relies on.
            handler = zenoh.handlers.Callback(self._on_network_sample, indirect=False)
        if row.latched:
            # The newest message of every publisher that is up now or appears later, then the live ones.
            history = zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=LATCH_DEPTH)
            self._sub = zenoh.ext.declare_advanced_subscriber(bus.session, key, handler, history=history)
        else:
            self._sub = bus.session.declare_subscriber(key, handler)

    def _on_network_sample(self, sample: zenoh.Sample) -> None:
        """:meth:`_on_sample` as called by Zenoh in its network thread, which first keeps its Python thread state."""
        if not getattr(_network_thread, "adopted", False):
            _adopt_network_thread()
        self._on_sample(sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        if self._bus.closing:
            return
        # Hot path (every message of every topic): skip the string work when the key is not a wildcard and the
        # encoding is exactly ours.
        key = str(sample.key_expr) if self._wildcard else self.key
        encoding = sample.encoding
        reason = None if encoding == self._encoding else _encoding_problem(encoding, self.topic.msgtype)
        msg = None
        if reason is None:
            try:
                msg = self._decode(sample.payload.to_bytes())
                self._validate(msg)
            except codec.MessageError as exc:
                reason = str(exc)
        if reason is not None:
            self._bus._reject(key, reason)
            return
        attachment = b"" if sample.attachment is None else sample.attachment.to_bytes()
        sent_at = None
        if attachment.startswith(SIM_TIME_TAG) and len(attachment) >= _TAG_LEN:
            sent_at = _SIM_TIME.unpack_from(attachment, len(SIM_TIME_TAG))[0]
            attachment = attachment[_TAG_LEN:]
        request = attachment if self.topic.kind is Kind.EVENT and attachment.startswith(RECEIPT_REQUEST) else b""
        if request and request in self._requests:
            # A resend (its receipt was lost on the way back): confirm again, deliver once.
            self._bus._send_receipt(key, request)
            return
        gate = self._bus.gate
        if gate is not None and not self._immediate:
            gate.stage(self, key, msg, sent_at)
        else:
            self._deliver(key, msg)
        if request:
            # Queued for the service (or handed to its callback): confirm delivery when the publisher asked.
            self._requests[request] = None
            if len(self._requests) > _RECENT_REQUESTS:
                self._requests.popitem(last=False)
            self._bus._send_receipt(key, request)

    def _deliver(self, key: str, msg: Any) -> None:
        with self._cond:
            self._latest = msg
            self._by_key[key] = msg
            if self.topic.kind is Kind.EVENT and self._callback is None:  # a callback consumes events itself
                self._queue.append(msg)
            self._fresh = True
            self.count += 1
            if self._waiters:  # Condition.notify_all is pure Python: skip it on the hot path when nobody waits
                self._cond.notify_all()
        self._bus._count_received()
        if self._callback is not None:
            try:
                self._callback(msg)
            except Exception:
                log.exception("callback for %s failed", key)

    def _pull(self) -> None:
        """A lossy subscription: decode and deliver what its ring buffer holds (in arrival order)."""
        if not self._lossy:
            return
        while (sample := self._sub.try_recv()) is not None:
            self._on_sample(sample)

    def latest(self) -> Any:
        """The newest message received (``None`` before the first)."""
        self._pull()
        with self._cond:
            self._read |= self._latest is not None
            return self._latest

    def latest_by_key(self) -> dict[str, Any]:
        """Newest message per concrete key (useful on wildcard subscriptions such as ``status/*``)."""
        self._pull()
        with self._cond:
            self._read |= bool(self._by_key)
            return dict(self._by_key)

    def take(self) -> Any:
        """The newest message if one arrived since the last ``take``, else ``None``."""
        self._pull()
        with self._cond:
            if not self._fresh:
                return None
            self._fresh = False
            self._read = True
            return self._latest

    def drain(self) -> list[Any]:
        """Every queued message of an event topic, oldest first (the queue is emptied).

        Subscriptions with a callback hand every event to it and queue nothing.
        """
        self._pull()
        with self._cond:
            items = list(self._queue)
            self._queue.clear()
            self._fresh = False
            self._read |= bool(items)
            return items

    def wait(self, timeout_s: float, predicate: Callable[[Any], bool] | None = None) -> Any:
        """Wait until a message arrives (that satisfies ``predicate``, when given); returns it or ``None``.

        Only messages arriving after the call count, unless ``predicate`` already holds for the newest one, or
        nothing has been read from this subscription yet (then the newest message counts, whenever it arrived: a
        latched topic's history may well arrive between :meth:`Bus.subscribe` and this call, and is never sent
        again). A lossy subscription looks at its ring buffer every :data:`LOSSY_POLL_S` (nothing signals an
        arrival there).
        """
        deadline = time.monotonic() + timeout_s
        self._pull()
        with self._cond:
            newest = self._latest
            if newest is not None and (not self._read if predicate is None else predicate(newest)):
                self._read = True
                return newest
            seen = self.count
        while True:
            self._pull()
            with self._cond:
                if self.count != seen:
                    seen = self.count
                    if predicate is None or predicate(self._latest):
                        self._read = True
                        return self._latest
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._waiters += 1
                try:
                    self._cond.wait(min(remaining, LOSSY_POLL_S) if self._lossy else remaining)
                finally:
                    self._waiters -= 1

    def close(self) -> None:
        """Undeclare the subscriber."""
        self._sub.undeclare()


#: Per-thread flag of :func:`_adopt_network_thread` (a thread state's own storage: it lasts as long as the state).
_network_thread = threading.local()


def _adopt_network_thread() -> None:
    """Keep the calling Zenoh thread's Python thread state for the thread's life (call with the GIL held).

    Zenoh's network threads are not Python's: each callback enters Python through ``PyGILState_Ensure``, which makes
    a thread state for a thread that has none and deletes it again when the callback returns. In CPython 3.11 that
    maps and unmaps a 16 KB frame stack and builds the state afresh for every message: an idle planner's two network
    threads made ~1,200 mmap/munmap pairs per second (strace); with the state kept, idle lockstep participants took
    13-29 % less CPU per sim second (a few runs on a loaded machine). One more ``PyGILState_Ensure``, never
    released, keeps the count above zero, so every later callback on this thread reuses its state (what a C
    extension does for a thread it calls Python from). Zenoh's network threads live as long as the process, so the
    states kept are few (one per thread).
    """
    _network_thread.adopted = True
    ctypes.pythonapi.PyGILState_Ensure()


def _encoding_problem(encoding: zenoh.Encoding, msgtype: str) -> str | None:
    text = str(encoding)
    base, _, schema = text.partition(";")
    if base not in _CDR_ENCODINGS:
        return f"wrong encoding {text!r} (expected CDR of {msgtype})"
    if base == "application/cdr" and schema and schema != msgtype:
        return f"wrong type {schema} (expected {msgtype})"
    return None


class Bus:
    """One Zenoh session bound to a robot namespace, with typed topics and endpoints.

    Args:
        session: an open ``zenoh.Session``; the bus closes it in :meth:`close` when it opened it itself.
        namespace: robot namespace that prefixes every key (default ``robot0``).
    """

    def __init__(self, session: zenoh.Session, namespace: str = DEFAULT_NAMESPACE, *, owns_session: bool = False):
        check_namespace(namespace)
        self.session = session
        #: Where accepted samples go before their subscriptions (None: straight there): a sim-time participant's
        #: staging (:class:`mjnav.runtime.simtime.SimTimeGate`), which holds them until the clock says they are due.
        #: Subscriptions made ``immediate`` (the clock itself, lockstep reports) bypass it.
        self.gate: Gate | None = None
        #: The sim time this bus's owner has reached (None: no sim time), set by the runtime: the newest clock it
        #: committed (a sim-time service) or published (the sim). Every sample it publishes carries it
        #: (:data:`SIM_TIME_TAG`), so a staged subscriber delivers the sample only at a later clock.
        self.sim_time: float | None = None
        #: Set by :meth:`close`: samples still arriving are ignored and publishing does nothing.
        self.closing = False
        #: The service this bus belongs to (set by :class:`mjnav.runtime.Service`): it signs delivery receipts.
        self.owner: str | None = None
        self._receipt_pub: Publisher | None = None
        self.namespace = namespace
        self.stats = BusStats()
        self._owns_session = owns_session
        self._lock = threading.Lock()
        self._reject_log = _RejectLog()
        self._declared: list[Any] = []

    @classmethod
    def open(cls, config: BusConfig, namespace: str = DEFAULT_NAMESPACE) -> Bus:
        """Open a Zenoh session with ``config`` and wrap it.

        Raises:
            BusUnavailable: nothing answered on ``config.connect`` within ``config.connect_timeout_s``, or an
                endpoint of ``config.listen`` cannot be bound (port in use).
        """
        try:
            session = zenoh.open(config.to_zenoh())
        except zenoh.ZError as exc:
            where = ", ".join(config.listen if config.mode == "router" else config.connect)
            raise BusUnavailable(f"cannot open a Zenoh {config.mode} session on {where}: {exc}") from exc
        return cls(session, namespace, owns_session=True)

    def __enter__(self) -> Bus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Undeclare everything this bus declared and close the session if the bus opened it."""
        self.closing = True
        for entity in reversed(self._declared):
            try:
                entity.close() if hasattr(entity, "close") else entity.undeclare()
            except Exception as exc:  # the session may already be gone
                log.debug("undeclare failed: %s", exc)
        self._declared.clear()
        if self._owns_session and not self.session.is_closed():
            self.session.close()

    # ------------------------------------------------------------------------------------------------- counters

    def _count_received(self) -> None:
        with self._lock:
            self.stats.received += 1

    def _count_published(self) -> None:
        with self._lock:
            self.stats.published += 1

    def _reject(self, key: str, reason: str) -> None:
        with self._lock:
            self.stats.rejected += 1
            self.stats.rejected_by_key[key] = self.stats.rejected_by_key.get(key, 0) + 1
            self.stats.last_rejection = f"{key}: {reason}"
        self._reject_log(key, reason)

    def _send_receipt(self, key: str, attachment: bytes) -> None:
        """Answer an event sample that asked for a receipt (only buses that belong to a service sign them)."""
        if self.owner is None or not attachment.startswith(RECEIPT_REQUEST):
            return
        pub = self._receipt_publisher()
        request_id = attachment[len(RECEIPT_REQUEST) :].decode(errors="replace")
        fields = {"service": self.owner, "key": key, "request_id": request_id}
        pub.put(codec.from_dict("mjnav_msgs/msg/Receipt", fields))

    def _receipt_publisher(self) -> Publisher:
        """The service's ``receipt`` publisher, declared on first need. A publisher declared inside the first
        receipt's callback could lose that receipt: Zenoh may drop a new publisher's first samples until it has
        learnt where the subscribers are (seen once: 29 of 30 receipts)."""
        with self._lock:
            if self._receipt_pub is None:
                self._receipt_pub = self.publisher("receipt", service=self.owner)
            return self._receipt_pub

    def defer(self, action: Callable[[], None]) -> None:
        """Run ``action`` as if it were a message arriving now: through the :attr:`gate` when there is one (at the
        clock that commits what arrived around it), at once otherwise. For inputs that come through no subscription
        — a request on an endpoint — so that a sim-time service sees them at a step boundary, in the order they
        arrived relative to its topics."""
        gate = self.gate
        if gate is not None:
            gate.defer(action)
        else:
            action()

    # ----------------------------------------------------------------------------------------- pub/sub by name

    def key(self, name: str, service: str | None = None) -> str:
        """The key of topic ``name`` in this bus's namespace."""
        return topic(name).key(self.namespace, service)

    def publisher(self, name: str, service: str | None = None) -> Publisher:
        """Declare a publisher for topic ``name`` (per-service topics need ``service``)."""
        row = topic(name)
        pub = Publisher(self, row, row.key(self.namespace, service))
        self._declared.append(pub)
        return pub

    def subscribe(
        self,
        name: str,
        *,
        callback: Callable[[Any], None] | None = None,
        service: str | None = None,
        immediate: bool = False,
        lossy: bool = False,
    ) -> Subscription:
        """Subscribe to topic ``name``.

        Args:
            name: topic name from the table.
            callback: optional function called (in Zenoh's thread) with each accepted message.
            service: the service of a per-service topic (``"*"`` for all).
            immediate: deliver at once even when the bus has a :attr:`gate` (the clock itself, barrier reports).
            lossy: for observers outside the lockstep loop (the viewer): never hold publishers back, at the price of
                messages dropped while the reader falls behind (see :class:`Subscription`); no ``callback``.
        """
        row = topic(name)
        if row.kind is Kind.EVENT and self.owner is not None:
            self._receipt_publisher()  # declared now, routed by the time the first receipt goes out
        sub = Subscription(self, row, row.key(self.namespace, service), callback, immediate, lossy)
        self._declared.append(sub)
        return sub

    # ----------------------------------------------------------------------------------- raw bytes on any key

    def subscribe_raw(self, key_expr: str, callback: Callable[[RawSample], None], *, remote_only: bool = False) -> Any:
        """Call ``callback`` (in Zenoh's thread) with every sample on ``key_expr``, undecoded (relays, recorders).

        An exception in ``callback`` is logged and the sample dropped. ``remote_only``: ignore what this session
        publishes itself (a relay between two keys must not hear its own output). Undeclared with the bus; call
        ``undeclare()`` on the result to stop earlier.
        """

        def handler(sample: zenoh.Sample) -> None:
            if not getattr(_network_thread, "adopted", False):
                _adopt_network_thread()
            if self.closing:
                return
            try:
                callback(RawSample(sample))
            except Exception:
                log.exception("raw subscriber on %s failed on a sample of %s", key_expr, sample.key_expr)

        origin = zenoh.Locality.REMOTE if remote_only else zenoh.Locality.ANY
        sub = self.session.declare_subscriber(key_expr, handler, allowed_origin=origin)
        self._declared.append(sub)
        return sub

    def publisher_raw(
        self, key: str, *, encoding: str, row: Topic | None = None, remote_only: bool = False
    ) -> RawPublisher:
        """A publisher of raw payloads on ``key`` with ``encoding``, with the QoS of topic ``row`` (every topic's
        when None). ``remote_only``: not delivered to this session's own subscribers."""
        qos = publisher_qos(row)
        destination = zenoh.Locality.REMOTE if remote_only else zenoh.Locality.ANY
        pub = self.session.declare_publisher(
            key, encoding=zenoh.Encoding(encoding), allowed_destination=destination, **qos
        )
        self._declared.append(pub)
        return RawPublisher(pub, key)

    def declare_token(self, key: str) -> Any:
        """Declare the liveliness token ``key`` (any key: a ROS 2 graph entity's); it vanishes with the bus."""
        token = self.session.liveliness().declare_token(key)
        self._declared.append(token)
        return token

    def sharing(self) -> Bus:
        """Another bus on this one's session and namespace, with its own subscriptions, gate, counters and receipts
        (a service of a container); closing it leaves the session open."""
        return Bus(self.session, self.namespace)

    def connected(self) -> bool:
        """Whether the session is linked to a router or a peer now."""
        info = self.session.info
        return bool(list(info.routers_zid()) or list(info.peers_zid()))

    @property
    def session_id(self) -> str:
        """The Zenoh session's id (hex)."""
        return str(self.session.info.zid())

    def put_confirmed(
        self, name: str, msgs: list[Any], *, timeout_s: float = 5.0, period_s: float = 0.0
    ) -> dict[str, int]:
        """Publish event messages on topic ``name`` and wait until each subscriber the topic table names
        (``Topic.subscribers``) confirmed every one of them with a receipt. A message still unconfirmed after
        ``RESEND_AFTER_S`` is sent again with the same request id: subscribers deliver it once and confirm it
        again (at least once on the wire, exactly once to the service).

        Args:
            name: an event topic of the table.
            msgs: the messages, sent in order.
            timeout_s: wall seconds to wait for the subscribers to match, and then for the last receipts.
            period_s: wall seconds between two messages (pacing, 0 = back to back).

        Returns:
            Receipts received per service (every named subscriber has ``len(msgs)``; other subscribers that
            answered, e.g. the viewer, are counted too).

        Raises:
            NotDelivered: a named subscriber did not confirm every message within ``timeout_s`` (it is not
                running, or it rejected the payload).
            ValueError: ``name`` is not an event topic or names no subscribers.
        """
        row = topic(name)
        if row.kind is not Kind.EVENT or not row.subscribers:
            raise ValueError(f"topic {name!r} is not an event topic with named subscribers")
        tag = uuid.uuid4().hex
        got: dict[str, set[str]] = {}
        cond = threading.Condition()

        def on_receipt(msg: Any) -> None:
            if msg.request_id.startswith(tag):
                with cond:
                    got.setdefault(msg.service, set()).add(msg.request_id)
                    cond.notify_all()

        receipts = self.subscribe("receipt", service="*", callback=on_receipt)
        pub = self.publisher(name)
        try:
            pub.wait_for_subscribers(timeout_s)
            start = time.monotonic()
            for i, msg in enumerate(msgs):
                if i and period_s > 0:
                    time.sleep(max(0.0, start + i * period_s - time.monotonic()))  # pacing, not synchronisation
                pub.put(msg, receipt_id=f"{tag}-{i}")
            deadline = time.monotonic() + timeout_s
            resend_at = time.monotonic() + RESEND_AFTER_S

            def missing() -> list[str]:
                return [s for s in row.subscribers if len(got.get(s, ())) < len(msgs)]

            while True:
                with cond:
                    now = time.monotonic()
                    while missing() and now < min(deadline, resend_at):
                        cond.wait(min(deadline, resend_at) - now)
                        now = time.monotonic()
                    lost = missing()
                    if not lost:
                        return {service: len(ids) for service, ids in got.items()}
                    if now >= deadline:
                        counts = ", ".join(f"{s} {len(got.get(s, ()))}/{len(msgs)}" for s in lost)
                        raise NotDelivered(
                            f"{pub.key}: no receipt within {timeout_s} s from {counts} "
                            f"(is it running? `mjnav health {' '.join(lost)}`)",
                            lost,
                        )
                    unconfirmed = [i for i in range(len(msgs)) if any(f"{tag}-{i}" not in got.get(s, ()) for s in lost)]
                # A receipt can be lost: a service's receipt publisher may learn of the receipt subscription declared
                # above only after the first events reach it (Zenoh routes data faster than declarations; seen twice:
                # 29 of 30 receipts). Subscribers deliver a resent event once and confirm it again.
                for i in unconfirmed:
                    pub.put(msgs[i], receipt_id=f"{tag}-{i}")
                resend_at = time.monotonic() + RESEND_AFTER_S
        finally:
            for entity in (receipts, pub):
                self._declared.remove(entity)
                entity.close()

    # ------------------------------------------------------------------------------------------- request/reply

    def serve(self, name: str, handler: Callable[[Any], Any], service: str | None = None) -> Any:
        """Answer requests on endpoint ``name`` with ``handler(request) -> response``.

        An empty request payload stands for a default-valued request. A request that does not decode, or a
        handler that raises, is answered with an error reply (the text names the problem) and counted.
        """
        ep = endpoint(name)
        key = ep.key(self.namespace, service)

        def on_query(query: zenoh.Query) -> None:
            try:
                payload = query.payload.to_bytes() if query.payload is not None else b""
                request = codec.decode(payload, ep.request_type) if payload else codec.from_dict(ep.request_type)
                validate(request)
            except codec.MessageError as exc:
                self._reject(key, str(exc))
                query.reply_err(f"bad request: {exc}")
                return
            try:
                response = handler(request)
                data = codec.encode(response, ep.response_type)
            except Exception as exc:
                log.exception("handler for %s failed", key)
                query.reply_err(f"{type(exc).__name__}: {exc}")
                return
            query.reply(key, data, encoding=cdr_encoding(ep.response_type))

        queryable = self.session.declare_queryable(key, on_query)
        self._declared.append(queryable)
        return queryable

    def call(self, name: str, request: Any = None, *, timeout_s: float = 5.0, service: str | None = None) -> Any:
        """Send a request to endpoint ``name`` and return the decoded response.

        Raises:
            NoReply: nobody answered within ``timeout_s``.
            RemoteError: the server answered with an error, or with a response that does not decode.
        """
        ep = endpoint(name)
        key = ep.key(self.namespace, service)
        payload = codec.encode(request, ep.request_type) if request is not None else b""
        replies = self.session.get(key, payload=payload, encoding=cdr_encoding(ep.request_type), timeout=timeout_s)
        for reply in replies:
            return _reply_value(reply, ep.response_type)
        raise NoReply(f"no reply on {key} within {timeout_s} s")

    def call_async(
        self,
        name: str,
        request: Any,
        on_reply: Callable[[Any], None],
        on_error: Callable[[Exception], None],
        *,
        timeout_s: float = 5.0,
        service: str | None = None,
    ) -> None:
        """Send a request to endpoint ``name`` and return at once; the first reply goes to ``on_reply`` (decoded)
        or ``on_error`` (:class:`RemoteError`), no reply within ``timeout_s`` to ``on_error`` (:class:`NoReply`),
        in Zenoh's thread. For a caller that must not block, e.g. a lockstep client stepping in the clock's
        callback: the request leaves before anything it publishes afterwards."""
        ep = endpoint(name)
        key = ep.key(self.namespace, service)
        payload = codec.encode(request, ep.request_type) if request is not None else b""
        answered = threading.Event()

        def on_sample(reply: zenoh.Reply) -> None:
            if answered.is_set():
                return
            answered.set()
            try:
                value = _reply_value(reply, ep.response_type)
            except RemoteError as exc:
                on_error(exc)
                return
            on_reply(value)

        def on_done() -> None:
            if not answered.is_set():
                answered.set()
                on_error(NoReply(f"no reply on {key} within {timeout_s} s"))

        handler = zenoh.handlers.Callback(on_sample, on_done)
        self.session.get(
            key,
            handler,
            payload=payload,
            encoding=cdr_encoding(ep.request_type),
            timeout=timeout_s,
            priority=zenoh.Priority.DATA,  # the same as every topic: in order with what the caller publishes next
            congestion_control=zenoh.CongestionControl.BLOCK,
        )

    # ------------------------------------------------------------------------------------------------ liveliness

    def declare_alive(self, service: str) -> Any:
        """Declare the liveliness token ``mjnav/alive/<ns>/<service>``; it vanishes when the process does."""
        token = self.session.liveliness().declare_token(alive_key(self.namespace, service))
        self._declared.append(token)
        return token

    def declare_lockstep(self, participant: str) -> Any:
        """Declare the lockstep token ``mjnav/lockstep/<ns>/<participant>``: the sim waits for this participant's
        ``lockstep`` reports while the token is up."""
        token = self.session.liveliness().declare_token(lockstep_key(self.namespace, participant))
        self._declared.append(token)
        return token

    def watch_lockstep(self, callback: Callable[[str, bool], None]) -> Any:
        """Call ``callback(participant, present)`` whenever a lockstep token of this namespace appears or vanishes
        (tokens already up are reported first)."""
        return self._watch_tokens(lockstep_key(self.namespace, ""), callback)

    def alive_services(self, timeout_s: float = 1.0) -> list[str]:
        """Names of the services whose liveliness token is up in this namespace."""
        prefix = alive_key(self.namespace, "")
        replies = self.session.liveliness().get(alive_key(self.namespace, "*"), timeout=timeout_s)
        return sorted(str(r.ok.key_expr)[len(prefix) :] for r in replies if r.ok is not None)

    def watch_alive(self, callback: Callable[[str, bool], None]) -> Any:
        """Call ``callback(service, alive)`` whenever a service token of this namespace appears or vanishes."""
        return self._watch_tokens(alive_key(self.namespace, ""), callback)

    def _watch_tokens(self, prefix: str, callback: Callable[[str, bool], None]) -> Any:
        def on_sample(sample: zenoh.Sample) -> None:
            callback(str(sample.key_expr)[len(prefix) :], sample.kind == zenoh.SampleKind.PUT)

        sub = self.session.liveliness().declare_subscriber(prefix + "*", on_sample, history=True)
        self._declared.append(sub)
        return sub


def _reply_value(reply: zenoh.Reply, response_type: str) -> Any:
    """The decoded response of a reply, or :class:`RemoteError` for an error reply or one that does not decode."""
    if reply.ok is not None:
        try:
            return codec.decode(reply.ok.payload.to_bytes(), response_type)
        except codec.MessageError as exc:
            raise RemoteError(f"undecodable reply on {reply.ok.key_expr}: {exc}") from exc
    err = reply.err
    raise RemoteError(err.payload.to_string() if err is not None else "error reply without payload")


def wait_until(predicate: Callable[[], bool], timeout_s: float, poll_s: float = 0.01) -> bool:
    """Poll ``predicate`` until it holds or ``timeout_s`` passes; returns whether it held.

    For conditions that have no event to wait on (process state, files); message arrivals should use
    :meth:`Subscription.wait` instead.
    """
    deadline = time.monotonic() + timeout_s
    while True:
        if predicate():
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(poll_s)

"""Lockstep: sim time advances only when every participant has finished the step that is due.

:class:`LockstepBarrier` is the sim's side; :class:`LockstepReporter` a participant's.

Participants are the services that step on sim time (and mission clients): each holds a lockstep token
(``mjnav/lockstep/<ns>/<name>``) and, after every step, reports on ``<ns>/lockstep/<name>`` the sim time of its next
step (``ready_until``). The sim may step from t to t + Δ only while every participant's ``ready_until`` lies after t.

Why this makes runs repeatable: a participant publishes its outputs before its report, every message has the same
Zenoh priority and all traffic goes through the router, so by the time the sim has every report for t, every
message published at steps up to t has reached the router ahead of the sim's next clock. Subscribers commit what
arrived when that clock arrives (:class:`~mjnav.runtime.simtime.gate.SimTimeGate`): each step sees exactly the
messages of earlier sim time, whatever the machine's load.

Membership follows the tokens: a participant that appears joins at the next clock the sim publishes; one that
vanishes (killed) is dropped at once. One that holds its token but reports nothing for ``timeout_s`` of wall time
(hung) is named in the log and left out until it reports again, so the barrier never hangs on it. While an expected
participant is missing (dropped or left out) the sim runs at most at real time (:meth:`LockstepBarrier.missing`):
its own watchdogs still act on sim time, and a restart of a few wall seconds costs a few sim seconds, as on a
real robot, instead of minutes of sim time without it.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Collection, Iterable
from typing import Any

from mjnav.bus import Bus
from mjnav.msgs import msg_class, ros

#: Sim-time tolerance when comparing a participant's next step with the sim's time (ticks are milliseconds apart).
_EPS_S = 1e-6


class LockstepBarrier:
    """Tracks the participants and tells the sim when it may advance.

    Args:
        bus: the sim's bus (reports and tokens are received on it, undelayed).
        expected: participants that must be present before sim time starts (the stack's sim-time services).
        timeout_s: wall seconds a participant may hold the barrier before it is named and left out.
        log: where waits and departures are reported.
    """

    def __init__(self, bus: Bus, expected: Iterable[str], timeout_s: float, log: logging.Logger) -> None:
        self.expected = frozenset(expected)
        self.timeout_s = timeout_s
        self.log = log
        self._cond = threading.Condition()
        self._ready: dict[str, float] = {}  # participant -> sim time of its next step
        self._left_out: set[str] = set()
        self._published = -math.inf  # newest clock the sim has published (-inf: time has not started)
        self._tick_s = 0.0
        self._blocked_since: float | None = None
        self._waiting_at: float | None = None  # the sim time the sim waits to step past (None: not waiting)
        self._waiting_among: Collection[str] | None = None  # whom it waits for (None: everybody)
        self._last_start_log = time.monotonic()
        #: Wall seconds :meth:`wait` has waited in total (the barrier's cost in a run's wall time).
        self.waited_s = 0.0
        bus.subscribe("lockstep", service="*", callback=self._on_report, immediate=True)
        bus.watch_lockstep(self._on_token)

    # ------------------------------------------------------------------------------------- Zenoh callbacks

    def _on_token(self, name: str, present: bool) -> None:
        with self._cond:
            if present:
                # A newcomer surely receives the next clock the sim publishes, not the one already out.
                first = 0.0 if self._published == -math.inf else self._published + self._tick_s
                self._ready[name] = first
                self.log.info("lockstep: %s joined (first step at %.3f s)", name, first)
            elif self._ready.pop(name, None) is not None:
                self._left_out.discard(name)
                self.log.warning("lockstep: %s left (its token vanished); sim time goes on without it", name)
            self._cond.notify_all()

    def _on_report(self, msg: Any) -> None:
        name = msg.participant
        done = ros.seconds(msg.header.stamp)
        with self._cond:
            if name not in self._ready or done > self._published + _EPS_S:
                return  # not a participant (yet), or a report from before the sim restarted
            self._ready[name] = ros.seconds(msg.ready_until)
            rejoined = name in self._left_out
            if rejoined:
                self._left_out.discard(name)
                self.log.info("lockstep: %s reports again and rejoins", name)
            # wake the sim only when it may step now: one wake-up per round, not one per report
            if rejoined or self._waiting_at is None or not self._blocking(self._waiting_at, self._waiting_among):
                self._cond.notify_all()

    # ------------------------------------------------------------------------------------------- the sim

    def participants(self) -> list[str]:
        """Names of the participants present now."""
        with self._cond:
            return sorted(self._ready)

    def missing(self) -> list[str]:
        """Expected participants that are absent or left out now (restarting, hung)."""
        with self._cond:
            return sorted((self.expected - set(self._ready)) | (self._left_out & self.expected))

    def started(self) -> bool:
        """Whether every expected participant is present (sim time may start); logs who is missing every 5 s."""
        with self._cond:
            missing = sorted(self.expected - set(self._ready))
        if missing and time.monotonic() - self._last_start_log >= 5.0:
            self._last_start_log = time.monotonic()
            self.log.info("lockstep: waiting for %s before sim time starts", ", ".join(missing))
        return not missing

    def published(self, t: float, tick_s: float) -> None:
        """The sim published its clock at ``t``; the next one follows ``tick_s`` later."""
        with self._cond:
            self._published = t
            self._tick_s = tick_s

    def blocking(self, t: float, among: Collection[str] | None = None) -> list[str]:
        """Participants (of ``among``, default all) whose next step is due at or before sim time ``t``: the sim must
        not step past ``t`` without them."""
        with self._cond:
            return self._blocking(t, among)

    def _blocking(self, t: float, among: Collection[str] | None = None) -> list[str]:
        return sorted(
            n
            for n, r in self._ready.items()
            if r <= t + _EPS_S and n not in self._left_out and (among is None or n in among)
        )

    def wait(self, t: float, timeout_s: float, among: Collection[str] | None = None) -> bool:
        """Wait up to ``timeout_s`` wall seconds until every participant (of ``among``, default all; absent ones do
        not count) has finished its step at ``t``; returns whether they have.

        A participant blocking for longer than :attr:`timeout_s` in total is logged and left out.
        """
        start = time.monotonic()
        with self._cond:
            self._waiting_at, self._waiting_among = t, among
            try:
                return self._wait(t, start + timeout_s, among)
            finally:
                self._waiting_at = self._waiting_among = None
                self.waited_s += time.monotonic() - start

    def _wait(self, t: float, deadline: float, among: Collection[str] | None) -> bool:
        """:meth:`wait`'s loop (the condition's lock held)."""
        while True:
            blocking = self._blocking(t, among)
            now = time.monotonic()
            if not blocking:
                self._blocked_since = None
                return True
            if self._blocked_since is None:
                self._blocked_since = now
            elif now - self._blocked_since >= self.timeout_s:
                for name in blocking:
                    self.log.warning(
                        "lockstep: %s has not finished its step due at %.3f s after %.1f s of wall time: "
                        "going on without it until it reports again",
                        name,
                        self._ready[name],
                        now - self._blocked_since,
                    )
                    self._left_out.add(name)
                self._blocked_since = None
                continue
            if now >= deadline:
                return False
            self._cond.wait(min(deadline - now, self._blocked_since + self.timeout_s - now))


class LockstepReporter:
    """A participant's part in the barrier: its token (``mjnav/lockstep/<ns>/<name>``, declared here) and a report
    after every step."""

    def __init__(self, bus: Bus, participant: str) -> None:
        self._pub = bus.publisher("lockstep", service=participant)
        self._msg = msg_class("mjnav_msgs/msg/LockstepReady")
        self.participant = participant
        bus.declare_lockstep(participant)

    def ready(self, done: float, ready_until: float) -> None:
        """Report the step at sim time ``done`` finished; the next one is due at ``ready_until``."""
        self._pub.put(
            self._msg(header=ros.header(done, ""), participant=self.participant, ready_until=ros.time_msg(ready_until))
        )

"""The client side of lockstep shared by mission clients (``MissionClient``, ``FlightClient``, ``mjnav goal --at``).

From its first job on, a client is a lockstep participant: it steps every ``period_s`` of sim time in the clock's
callback (:meth:`LockstepParticipant._step`, under ``_lock``, after committing what arrived before that clock) and
reports the step on ``<ns>/lockstep/<name>`` like a service. Its clock is a :class:`~mjnav.runtime.simtime.SimClock`
(a clock more than :data:`~mjnav.runtime.simtime.MAX_CLOCK_JUMP_S` ahead is dropped as forged; one going back — the
sim restarted — re-syncs the steps); its schedule a :class:`~mjnav.runtime.simtime.Schedule`.
"""

from __future__ import annotations

import math
import threading
from typing import Any

from mjnav.bus import Bus
from mjnav.runtime.simtime import LockstepReporter, Schedule, SimClock, SimTimeGate


class LockstepParticipant:
    """Base of the clients that take part in lockstep; subclasses implement :meth:`_step`."""

    def _init_participant(self, bus: Bus, name: str, period_s: float) -> None:
        """Set up the state (call first in ``__init__``; the bus's samples go through a :class:`SimTimeGate` from
        here on)."""
        self.bus = bus
        self.name = name
        self.period_s = period_s
        self._lock = threading.Condition()
        self._now = math.nan
        self._schedule: Schedule | None = None  # None: not taking part; its next due time is the next step's
        self._reporter: LockstepReporter | None = None
        self._gate = SimTimeGate(bus)

    def _subscribe_clock(self) -> Any:
        """Subscribe to the clock (call last in ``__init__``, after the other subscriptions)."""
        self._clock = SimClock(self.bus, [self._gate], on_tick=self._on_tick)
        return self._clock._sub

    def _participate(self) -> None:
        """Take part from the next clock on (declares the lockstep token the first time)."""
        with self._lock:
            join = self._reporter is None
            self._schedule = Schedule(self.period_s, math.nan)  # the first step at the first clock from here on
        if join:
            # From now on the sim waits for this client's steps; a sim that expects it starts time only now.
            self._reporter = LockstepReporter(self.bus, self.name)

    def _step(self, t: float) -> None:
        """One lockstep step at sim time ``t`` (called under ``_lock``)."""
        raise NotImplementedError

    def _next_step(self, t: float) -> None:
        """Make the next step due at ``t`` rather than on the period (call from :meth:`_step`)."""
        assert self._schedule is not None
        self._schedule.reset(t)

    def _on_tick(self, t: float, restarted: bool) -> None:
        with self._lock:
            self._now = t
            schedule = self._schedule
            if schedule is None:
                return
            if restarted or math.isnan(schedule.origin_s):
                schedule.reset(t)  # the first clock since taking part, or the sim restarted
            if not schedule.due(t):
                return
            self._step(t)
            ready_until = schedule.next_s
            self._lock.notify_all()
        assert self._reporter is not None
        self._reporter.ready(t, ready_until)

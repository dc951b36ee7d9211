"""The client side of lockstep shared by mission clients (``MissionClient``, ``FlightClient``).

From its first job on, a client is a lockstep participant: it steps every ``period_s`` of sim time in the clock's
callback (:meth:`LockstepParticipant._step`, under ``_lock``, after committing what arrived before that clock) and
reports the step on ``<ns>/lockstep/<name>`` like a service. A clock more than
:data:`~mjnav.runtime.runner.MAX_CLOCK_JUMP_S` ahead is dropped (forged); one going back (the sim restarted)
re-syncs the steps.
"""

from __future__ import annotations

import math
import threading
from typing import Any

from mjnav.bus import Bus
from mjnav.msgs import msg_class, ros
from mjnav.runtime.runner import MAX_CLOCK_JUMP_S


class LockstepParticipant:
    """Base of the clients that take part in lockstep; subclasses implement :meth:`_step`."""

    def _init_participant(self, bus: Bus, name: str, period_s: float) -> None:
        """Set up the state (call first in ``__init__``; the bus becomes staged)."""
        self.bus = bus
        self.name = name
        self.period_s = period_s
        self._lock = threading.Condition()
        self._now = math.nan
        self._next_tick = math.nan
        self._participating = False
        self.rejected_clocks = 0  # clock messages dropped as too far ahead (forged)
        bus.staged = True
        self._ready_pub = bus.publisher("lockstep", service=name)
        self._ready = msg_class("mjnav_msgs/msg/LockstepReady")

    def _subscribe_clock(self) -> Any:
        """Subscribe to the clock (call last in ``__init__``, after the other subscriptions)."""
        return self.bus.subscribe("clock", callback=self._on_clock, immediate=True)

    def _participate(self) -> None:
        """Take part from the next clock on (declares the lockstep token the first time)."""
        with self._lock:
            join = not self._participating
            self._participating = True
            self._next_tick = -math.inf  # the first step at the first clock from here on
        if join:
            # From now on the sim waits for this client's steps; a sim that expects it starts time only now.
            self.bus.declare_lockstep(self.name)

    def _step(self, t: float) -> None:
        """One lockstep step at sim time ``t`` (called under ``_lock``)."""
        raise NotImplementedError

    def _on_clock(self, msg: Any) -> None:
        t = ros.seconds(msg.clock)
        with self._lock:
            if t > self._now + MAX_CLOCK_JUMP_S:  # forged or corrupt: the services drop it too
                self.rejected_clocks += 1
                return
        self.bus.commit(t)  # what was sent before this clock: measurements and statuses up to t
        with self._lock:
            if not t >= self._now:  # the first clock, or the sim restarted
                self._next_tick = t
            self._now = t
            if not self._participating:
                return
            if self._next_tick == -math.inf:
                self._next_tick = t
            if t < self._next_tick - 1e-9:
                return
            self._step(t)
            while self._next_tick <= t + 1e-9:
                self._next_tick += self.period_s
            self._lock.notify_all()
        self._ready_pub.put(
            self._ready(header=ros.header(t, ""), participant=self.name, ready_until=ros.time_msg(self._next_tick))
        )

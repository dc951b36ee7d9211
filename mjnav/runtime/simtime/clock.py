"""Sim time as a participant sees it: the ``clock`` topic, believed only in sane steps, committing what is due.

Every process that steps on sim time — a service's runner, the services of a container, a mission client — reads
the clock through :class:`SimClock`: a clock more than :data:`MAX_CLOCK_JUMP_S` ahead of the current time is
dropped and counted (one forged message must not fast-forward a participant out of the run); a clock going back
is a sim restart (counted in :attr:`SimClock.jumps_back`); an accepted clock commits the participant's gates
(:class:`~mjnav.runtime.simtime.gate.SimTimeGate`), so the step at that time sees what was sent before it, then
calls ``on_tick`` (a mission client steps there, in the clock's callback) and wakes whoever waits for that time.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from mjnav.bus import Bus
from mjnav.msgs import ros
from mjnav.runtime.simtime.gate import SimTimeGate

log = logging.getLogger("mjnav.runtime")

#: Largest forward step of sim time between two clock messages that is believed (sim s); a clock further ahead is
#: dropped as forged or corrupt (the sim ticks 0.05 s apart; a restarted sim goes back, never far forward).
MAX_CLOCK_JUMP_S = 5.0
#: Wall seconds a blocking wait sleeps at most before it looks at its stop flag again.
_POLL_S = 0.1


class StopRequested(Exception):
    """Raised inside waits when the waiting loop was asked to stop."""


class ClockJumpedBack(Exception):
    """The sim clock went backwards (the simulator restarted); pending waits are abandoned."""


class Stopper(Protocol):
    """What a wait looks at to give up: a stop flag with a timed wait (``threading.Event`` is one)."""

    def is_set(self) -> bool: ...

    def wait(self, timeout: float) -> bool: ...


class SimClock:
    """Sim time from the ``clock`` topic of ``bus`` (see the module docstring).

    Args:
        bus: where the clock is read (an immediate subscription: it is never staged itself).
        gates: committed at every accepted clock, in this order.
        on_tick: called with (t, restarted) after the commit, in the clock's callback (Zenoh's thread), under no
            lock of this class.
    """

    def __init__(
        self,
        bus: Bus,
        gates: Sequence[SimTimeGate] = (),
        on_tick: Callable[[float, bool], None] | None = None,
    ) -> None:
        self._cond = threading.Condition()
        self._now = math.nan
        self._waiting_for = -math.inf  # the time a wait is blocked on (-inf: wake on any clock)
        self.jumps_back = 0
        self.rejected_jumps = 0
        self._bus = bus
        self._gates = list(gates)
        self._on_tick = on_tick
        self._sub = bus.subscribe("clock", callback=self._on_clock, immediate=True)

    def _on_clock(self, msg: Any) -> None:
        t = ros.seconds(msg.clock)
        with self._cond:
            if t > self._now + MAX_CLOCK_JUMP_S:  # False while no clock arrived yet (NaN)
                self.rejected_jumps += 1
                if self.rejected_jumps <= 10 or self.rejected_jumps % 1000 == 0:
                    log.warning(
                        "clock jump from %.3f s to %.3f s on %s dropped (%d so far): more than %.0f s ahead",
                        self._now, t, self._bus.key("clock"), self.rejected_jumps, MAX_CLOCK_JUMP_S,
                    )  # fmt: skip
                return
        for gate in self._gates:
            gate.commit(t)
        with self._cond:
            back = t < self._now
            first = math.isnan(self._now)
            if back:
                self.jumps_back += 1
            self._now = t
        if self._on_tick is not None:
            self._on_tick(t, back or first)
        with self._cond:
            if back or t >= self._waiting_for:
                self._cond.notify_all()

    def now(self) -> float:
        """The newest accepted clock, s (NaN before the first)."""
        with self._cond:
            return self._now

    def wait_until(self, t: float, stop: Stopper, jumps: int | None = None) -> float:
        """Block until sim time >= ``t``; returns it.

        Raises:
            StopRequested: ``stop`` was set meanwhile.
            ClockJumpedBack: :attr:`jumps_back` differs from ``jumps`` (default: its value at the call).
        """
        with self._cond:
            jumps = self.jumps_back if jumps is None else jumps
            self._waiting_for = t
            try:
                while not (self._now >= t):  # also loops while no clock arrived yet (NaN)
                    if stop.is_set():
                        raise StopRequested
                    if self.jumps_back != jumps:
                        raise ClockJumpedBack
                    self._cond.wait(_POLL_S)
                return self._now
            finally:
                self._waiting_for = -math.inf


class WallClock:
    """Wall time since creation, with :class:`SimClock`'s waiting interface (services that step on wall time)."""

    jumps_back = 0

    def __init__(self) -> None:
        import time

        self._monotonic = time.monotonic
        self._t0 = time.monotonic()

    def now(self) -> float:
        """Seconds since creation."""
        return self._monotonic() - self._t0

    def wait_until(self, t: float, stop: Stopper, jumps: int | None = None) -> float:
        """Block until ``t``; returns the time reached.

        Raises:
            StopRequested: ``stop`` was set meanwhile.
        """
        while True:
            now = self.now()
            if now >= t:
                return now
            if stop.wait(min(t - now, _POLL_S)):
                raise StopRequested

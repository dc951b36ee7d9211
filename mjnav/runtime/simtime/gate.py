"""Staged delivery: what a sim-time participant receives waits until the clock says it is due.

A participant's step at sim time t must see exactly the messages its peers published before the sim reached t —
the same ones on a busy machine as on an idle one. The gate holds every sample its bus accepts (in arrival order)
until :meth:`SimTimeGate.commit` at a clock; a sample sent at sim time t or later (its ``t=`` tag, see
:data:`mjnav.bus.SIM_TIME_TAG`) stays held for a later clock whatever the order it arrived in: the router forwards
clock t to each subscriber in turn, so a peer that got it first may step and publish before another subscriber's
copy of the clock goes out (seen under load: a same-seed mission changed). After a clock that went back (a sim
restart) everything held is delivered: what was sent before the restart is old, not early.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any

from mjnav.bus import Bus

log = logging.getLogger("mjnav.runtime")


class SimTimeGate:
    """Holds a bus's incoming samples (and deferred actions) until the clock commits them; stamps what the bus sends
    with the newest committed sim time (:attr:`mjnav.bus.Bus.sim_time`).

    Args:
        bus: the participant's bus; the gate installs itself as its :attr:`~mjnav.bus.Bus.gate`.
    """

    def __init__(self, bus: Bus) -> None:
        self._bus = bus
        self._lock = threading.Lock()
        self._held: list[tuple[Any, str, Any, float | None]] = []  # (subscription or None, key, msg or action, t)
        bus.gate = self

    def stage(self, sub: Any, key: str, msg: Any, sent_at: float | None) -> None:
        """Hold ``msg`` (received on ``key`` by subscription ``sub``, sent at sim time ``sent_at``) for a clock."""
        with self._lock:
            self._held.append((sub, key, msg, sent_at))

    def defer(self, action: Callable[[], None]) -> None:
        """Run ``action`` as if it were a message arriving now: at the next commit, in order with the messages held
        around it (a request on an endpoint, which comes through no subscription)."""
        with self._lock:
            self._held.append((None, "", action, None))

    def commit(self, now: float) -> None:
        """Deliver, in arrival order, what was sent before sim time ``now`` (and what carried no time); ``now``
        becomes the bus's :attr:`~mjnav.bus.Bus.sim_time`."""
        bus = self._bus
        with self._lock:
            back = bus.sim_time is not None and now < bus.sim_time  # the sim restarted
            bus.sim_time = now
            held = self._held
            if back:
                self._held = []
            else:
                self._held = [item for item in held if item[3] is not None and item[3] >= now]
                held = [item for item in held if item[3] is None or item[3] < now]
        for sub, key, msg, _ in held:
            if sub is None:
                try:
                    msg()
                except Exception:
                    log.exception("deferred action failed")
            else:
                sub._deliver(key, msg)

"""Freshness of the services a service's inputs come from, in sim time, through their lockstep reports.

Every service on sim time reports each step on ``<ns>/lockstep/<name>`` (:class:`~mjnav.runtime.simtime.
LockstepReporter`, in lockstep and free-running alike) with the sim time its next step is due (``ready_until``). A
watched service is *stale* once sim time is more than ``grace_s`` past that due time with no newer report: it died,
hung, or was left out of the lockstep. Inputs that arrive only when they change (a plan, a path, a goal's status)
have no age of their own; the age of their producer's newest step bounds them instead.

In lockstep the sim never passes a participant's due time without its report, so nothing is stale while every
service keeps up; sim time only moves on without one the barrier has left out, and then the watch says so within
``grace_s`` of sim time. A service never heard from is not watched (a stack without it). After the clock went back
(a restarted sim) a report of the old timeline counts only once the new one has caught up with it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

from mjnav.msgs import ros


class UpstreamWatch:
    """Watches the step reports of ``services`` on ``bus``.

    Args:
        bus: the watching service's bus.
        services: names of the services whose steps to watch.
        grace_s: sim seconds past a service's due step after which it is stale, > 0.
    """

    def __init__(self, bus: Any, services: Iterable[str], grace_s: float) -> None:
        if not (math.isfinite(grace_s) and grace_s > 0):
            raise ValueError(f"grace_s must be a positive number of seconds, got {grace_s}")
        self.grace_s = grace_s
        self._subs = {name: bus.subscribe("lockstep", service=name) for name in sorted(set(services))}

    def stale(self, now: float) -> list[tuple[str, float]]:
        """The watched services that missed a due step at sim time ``now``: (name, the due time) each."""
        out = []
        for name, sub in self._subs.items():
            msg = sub.latest()
            if msg is None:
                continue
            done = ros.seconds(msg.header.stamp)
            if done > now + self.grace_s:  # the clock went back (a restarted sim): the old timeline's report
                continue
            due = ros.seconds(msg.ready_until)
            if now - due > self.grace_s:
                out.append((name, due))
        return out

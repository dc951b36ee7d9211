"""Time's one home: the clock as participants read it, the staging of what they receive by sim time, the schedule of
every periodic duty, the lockstep barrier and its reports, and wall-clock pacing. The bus only carries the sim-time
tag of each sample (:data:`mjnav.bus.SIM_TIME_TAG`); what it means is decided here.

* :class:`SimClock` — the ``clock`` topic believed in sane steps (:data:`MAX_CLOCK_JUMP_S`), restarts detected,
  gates committed, waits woken; :class:`WallClock` the same interface on wall time.
* :class:`SimTimeGate` — staged delivery: a step at sim time t sees exactly what was sent before t.
* :class:`Schedule` — due at origin + k · period, from the count (no drift): the runner's ticks, the sim's
  publications, the sim's hooks, a client's steps.
* :class:`LockstepBarrier` (the sim's side) and :class:`LockstepReporter` (a participant's).
* :class:`Pacer` — at most ``rtf`` × wall time, with or without catching up after a stall.


:class:`Schedule` and :class:`Pacer` need no transport: :mod:`mjnav.sim` steps with them without importing Zenoh
(the other names load on first use).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from mjnav.runtime.simtime.pacing import Pacer
from mjnav.runtime.simtime.schedule import Schedule

if TYPE_CHECKING:
    from mjnav.runtime.simtime.clock import (
        MAX_CLOCK_JUMP_S,
        ClockJumpedBack,
        SimClock,
        Stopper,
        StopRequested,
        WallClock,
    )
    from mjnav.runtime.simtime.gate import SimTimeGate
    from mjnav.runtime.simtime.lockstep import LockstepBarrier, LockstepReporter

_LAZY = {
    "MAX_CLOCK_JUMP_S": "clock",
    "ClockJumpedBack": "clock",
    "SimClock": "clock",
    "Stopper": "clock",
    "StopRequested": "clock",
    "WallClock": "clock",
    "SimTimeGate": "gate",
    "LockstepBarrier": "lockstep",
    "LockstepReporter": "lockstep",
}

__all__ = [
    "MAX_CLOCK_JUMP_S",
    "ClockJumpedBack",
    "LockstepBarrier",
    "LockstepReporter",
    "Pacer",
    "Schedule",
    "SimClock",
    "SimTimeGate",
    "StopRequested",
    "Stopper",
    "WallClock",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'mjnav.runtime.simtime' has no attribute {name!r}")
    return getattr(importlib.import_module(f"mjnav.runtime.simtime.{module}"), name)

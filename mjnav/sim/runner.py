"""Run a :class:`~mjnav.sim.Simulator` against wall time, with periodic hooks.

:class:`SimRunner` is the one stepping loop of the project: behind ``mjnav sim``, ``mjnav record`` and the sim
service. It advances the simulator in whole physics steps and calls *hooks* — plain callables taking the
simulator — on their own sim-time schedules. The bus bridge is a hook (apply the newest ``cmd_vel``, publish
whatever falls due), and so is the recorder at its frame rate. :meth:`SimRunner.run` is a blocking, paced run
for a duration; :meth:`SimRunner.advance` steps up to a sim time within a wall-time budget, for a caller that
owns the pacing (the sim service, stepping in its own rate loop).

Hooks are due on schedules (:class:`~mjnav.runtime.simtime.Schedule`: sim time, from a count, no drift) and
called at the first physics step at or after each due time. Pacing (:meth:`SimRunner.run`) is the project's one pacer,
:class:`~mjnav.runtime.simtime.Pacer`: with ``rtf`` = a number, the loop sleeps so that sim time advances ``rtf``
times as fast as wall time (1.0 = real time), checked at every hook call and at least every ``pace_period_s`` of
sim time; a loop that has fallen behind (a stall) starts the line again rather than sprinting to catch up.
``rtf=None`` runs as fast as possible.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

from mjnav.runtime.simtime import Pacer, Schedule
from mjnav.sim.errors import InvalidCommandError
from mjnav.sim.simulator import Simulator

#: A hook: called with the simulator at its due sim times; must not step the simulator itself.
Hook = Callable[[Simulator], None]


@dataclass(frozen=True, slots=True)
class RunStats:
    """Outcome of :meth:`SimRunner.run`.

    Attributes:
        sim_time_s: sim time advanced by this run, seconds.
        wall_s: wall time of the stepping loop (including hooks and pacing sleeps), seconds.
        steps: physics steps taken.
        stopped_early: True when ``should_stop`` ended the run before ``duration_s``.
    """

    sim_time_s: float
    wall_s: float
    steps: int
    stopped_early: bool = False

    @property
    def real_time_factor(self) -> float:
        """Sim seconds per wall second (inf for a zero-length wall time)."""
        return self.sim_time_s / self.wall_s if self.wall_s > 0.0 else math.inf


@dataclass(slots=True)
class _Scheduled:
    hook: Hook
    schedule: Schedule | None  # None: every physics step
    offset_s: float
    next_k: int  # the physics step of the next call


class SimRunner:
    """Steps a simulator for a duration at a real-time factor, calling hooks on their schedules."""

    def __init__(self, sim: Simulator, *, rtf: float | None = 1.0, pace_period_s: float = 0.01) -> None:
        """Bind the simulator.

        Args:
            sim: the simulator to advance.
            rtf: target real-time factor (sim seconds per wall second), or ``None`` for as fast as possible.
            pace_period_s: longest stretch of sim time between two pacing checks, seconds (paced runs only).

        Raises:
            InvalidCommandError: ``rtf`` or ``pace_period_s`` is not a positive number.
        """
        if rtf is not None and not (math.isfinite(rtf) and rtf > 0.0):
            raise InvalidCommandError(f"rtf must be a positive number or None (as fast as possible), got {rtf}")
        if not (math.isfinite(pace_period_s) and pace_period_s > 0.0):
            raise InvalidCommandError(f"pace_period_s must be positive, got {pace_period_s}")
        self.sim = sim
        self.rtf = rtf
        self._pace_steps = max(1, round(pace_period_s / sim.timestep_s))
        self._hooks: list[_Scheduled] = []

    def add_hook(self, hook: Hook, period_s: float | None = None, offset_s: float = 0.0) -> None:
        """Call ``hook(sim)`` ``offset_s`` from now (at the start of the next run when 0) and then every
        ``period_s`` of sim time.

        Args:
            hook: the callable; it may read sensors and call ``set_command`` but must not step the simulator.
            period_s: sim-time period, seconds; ``None`` = every physics step (costly: one Python call per
                step). A call falls on the first physics step at or after its due time; due times do not drift.
            offset_s: sim seconds from now to the first call (>= 0).

        Raises:
            InvalidCommandError: a non-positive period or a negative offset.
        """
        if period_s is not None and not (math.isfinite(period_s) and period_s > 0.0):
            raise InvalidCommandError(f"hook period must be positive or None, got {period_s}")
        if not (math.isfinite(offset_s) and offset_s >= 0.0):
            raise InvalidCommandError(f"hook offset must be >= 0 s, got {offset_s}")
        schedule = None if period_s is None else Schedule(period_s, self.sim.time_s + offset_s)
        self._hooks.append(_Scheduled(hook, schedule, offset_s, self._step_at(self.sim.time_s + offset_s)))

    def _step_at(self, t: float) -> int:
        """The first physics step at or after sim time ``t``."""
        return math.ceil(t / self.sim.timestep_s - 1e-6)

    def _call_due(self, end: int) -> int:
        """Call the hooks due at the current step; returns the step of the next due hook (at most ``end``)."""
        sim = self.sim
        k = sim.step_count
        nxt = end
        for h in self._hooks:
            if h.next_k <= k:
                h.hook(sim)
                if h.schedule is None:
                    h.next_k = k + 1
                else:
                    h.schedule.due(sim.time_s)
                    h.next_k = max(k + 1, self._step_at(h.schedule.next_s))
            nxt = min(nxt, h.next_k)
        return nxt

    def advance(self, target_s: float, wall_deadline: float | None = None) -> None:
        """Step up to sim time ``target_s`` (rounded to a whole step; ``inf``: until the deadline), calling every
        hook that falls due on the way, including at the time reached. No pacing: the caller paces.

        Hook schedules continue across calls (they started when the hook was added). Stops early when
        ``time.perf_counter()`` passes ``wall_deadline``.
        """
        sim = self.sim
        end = sys.maxsize if math.isinf(target_s) else round(target_s / sim.timestep_s)
        while True:
            nxt = self._call_due(end)
            if sim.step_count >= end or (wall_deadline is not None and time.perf_counter() >= wall_deadline):
                return
            sim.step(nxt - sim.step_count)

    def run(self, duration_s: float, *, should_stop: Callable[[], bool] | None = None) -> RunStats:
        """Advance ``duration_s`` of sim time (rounded to whole steps), pacing and calling hooks.

        Hooks due at the start time run before the first step; hooks due exactly at the end time do not run
        (a 3 s run at 30 Hz calls a hook 90 times). ``should_stop`` is polled at every hook/pacing boundary.

        Raises:
            InvalidCommandError: a negative or non-finite duration.
        """
        if not (math.isfinite(duration_s) and duration_s >= 0.0):
            raise InvalidCommandError(f"duration_s must be a non-negative number, got {duration_s}")
        sim = self.sim
        dt = sim.timestep_s
        k0 = sim.step_count
        end = k0 + round(duration_s / dt)
        for h in self._hooks:  # schedules restart at the current step
            if h.schedule is not None:
                h.schedule.reset(sim.time_s + h.offset_s)
            h.next_k = self._step_at(sim.time_s + h.offset_s)
        pacer = Pacer(self.rtf)
        pacer.reset(sim.time_s)
        stopped = False
        wall0 = time.perf_counter()
        while sim.step_count < end:
            k = sim.step_count
            nxt = self._call_due(end)
            if should_stop is not None and should_stop():
                stopped = True
                break
            if pacer.rtf is not None:
                nxt = min(nxt, k + self._pace_steps)
                pacer.sleep_until(sim.time_s)
            sim.step(nxt - k)
        if not stopped:
            pacer.sleep_until(sim.time_s)
        wall = time.perf_counter() - wall0
        steps = sim.step_count - k0
        return RunStats(sim_time_s=steps * dt, wall_s=wall, steps=steps, stopped_early=stopped)

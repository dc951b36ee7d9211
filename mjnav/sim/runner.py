"""Run a :class:`~mjnav.sim.Simulator` against wall time, with periodic hooks.

:class:`SimRunner` is the one stepping loop of the project: behind ``mjnav sim``, ``mjnav record`` and the sim
service. It advances the simulator in whole physics steps and calls *hooks* — plain callables taking the
simulator — on their own sim-time schedules. The bus bridge is a hook (apply the newest ``cmd_vel``, publish
whatever falls due), and so is the recorder at its frame rate. :meth:`SimRunner.run` is a blocking, paced run
for a duration; :meth:`SimRunner.advance` steps up to a sim time within a wall-time budget, for a caller that
owns the pacing (the sim service, stepping in its own rate loop).

Pacing: with ``rtf`` = a number, the loop sleeps so that sim time advances ``rtf`` times as fast as wall time
(1.0 = real time), checked at every hook call and at least every ``pace_period_s`` of sim time; when the loop
falls behind it does not sleep and does not try to catch up. ``rtf=None`` runs as fast as possible.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

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
    period_steps: float
    origin: int
    count: int
    next_k: int


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

    def add_hook(self, hook: Hook, period_s: float | None = None) -> None:
        """Call ``hook(sim)`` now (at the start of the next run) and then every ``period_s`` of sim time.

        Args:
            hook: the callable; it may read sensors and call ``set_command`` but must not step the simulator.
            period_s: sim-time period, seconds; ``None`` = every physics step (costly: one Python call per
                step).
                Due times are whole steps (rounded), without cumulative drift.

        Raises:
            InvalidCommandError: a non-positive period.
        """
        dt = self.sim.timestep_s
        if period_s is None:
            period_steps = 1.0
        elif math.isfinite(period_s) and period_s > 0.0:
            period_steps = max(1.0, period_s / dt)
        else:
            raise InvalidCommandError(f"hook period must be positive or None, got {period_s}")
        k = self.sim.step_count
        self._hooks.append(_Scheduled(hook, period_steps, k, 0, k))

    def _call_due(self, end: int) -> int:
        """Call the hooks due at the current step; returns the step of the next due hook (at most ``end``)."""
        sim = self.sim
        k = sim.step_count
        nxt = end
        for h in self._hooks:
            if h.next_k <= k:
                h.hook(sim)
                h.count += 1
                h.next_k = max(k + 1, h.origin + round(h.count * h.period_steps))
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
            h.origin, h.count, h.next_k = k0, 0, k0
        paced = self.rtf is not None
        wall_per_step = dt / self.rtf if self.rtf is not None else 0.0
        stopped = False
        wall0 = time.perf_counter()
        while sim.step_count < end:
            k = sim.step_count
            nxt = self._call_due(end)
            if should_stop is not None and should_stop():
                stopped = True
                break
            if paced:
                nxt = min(nxt, k + self._pace_steps)
                ahead = wall0 + (k - k0) * wall_per_step - time.perf_counter()
                if ahead > 0.0:
                    time.sleep(ahead)
            sim.step(nxt - k)
        if paced and not stopped:
            ahead = wall0 + (sim.step_count - k0) * wall_per_step - time.perf_counter()
            if ahead > 0.0:
                time.sleep(ahead)
        wall = time.perf_counter() - wall0
        steps = sim.step_count - k0
        return RunStats(sim_time_s=steps * dt, wall_s=wall, steps=steps, stopped_early=stopped)

"""Wall-clock pacing: sim time at most ``rtf`` × wall time."""

from __future__ import annotations

import math
import time
from collections.abc import Callable


class Pacer:
    """How much sim time the wall clock allows: ``rtf`` sim seconds per wall second from a reference (wall, sim)
    pair.

    Args:
        rtf: sim seconds per wall second; ``None`` or 0: as fast as possible (no bound).
        catch_up: after falling behind (a stall, a slow step), make the lost time up by running faster until back on
            the line (free-running: sim time follows wall time, like hardware); False: start the line again from
            where the sim is when it has fallen more than ``slack_s`` of wall time behind — never sprint after a
            stall (lockstep, paced runs).
        slack_s: how far behind the line (wall seconds) counts as fallen behind, without ``catch_up``.
        lead_s: how far ahead of the sim (sim seconds) the line starts when it (re)starts: a lockstep sim that
            advances a clock tick at a time starts with the next tick allowed at once.
        clock: the wall clock, seconds (``time.monotonic``).

    Raises:
        ValueError: a negative or non-finite ``rtf``.
    """

    def __init__(
        self,
        rtf: float | None,
        *,
        catch_up: bool = False,
        slack_s: float = 0.1,
        lead_s: float = 0.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if rtf is not None and not (math.isfinite(rtf) and rtf >= 0.0):
            raise ValueError(f"rtf must be >= 0 (0 or None: as fast as possible), got {rtf}")
        self.rtf = rtf if rtf else None
        self.catch_up = catch_up
        self.slack_s = slack_s
        self.lead_s = lead_s
        self._clock = clock
        self._ref: tuple[float, float] | None = None  # (wall, sim) the line starts from

    def reset(self, sim_s: float | None = None) -> None:
        """Start the line at sim time ``sim_s`` (plus ``lead_s``) now; None: at the next :meth:`allowed`."""
        self._ref = None if sim_s is None else self._start(sim_s)

    def _start(self, sim_s: float) -> tuple[float, float]:
        lead_wall = self.lead_s / self.rtf if self.rtf else 0.0
        return self._clock() - lead_wall, sim_s

    def allowed(self, sim_s: float) -> float:
        """The sim time the wall clock allows now, the sim being at ``sim_s`` (inf without a bound)."""
        if self.rtf is None:
            return math.inf
        if self._ref is None:
            self._ref = self._start(sim_s)
        line = self._ref[1] + self.rtf * (self._clock() - self._ref[0])
        if not self.catch_up and sim_s < line - self.rtf * self.slack_s:
            self._ref = self._start(sim_s)  # fallen behind: the line starts again here
            line = self._ref[1] + self.rtf * (self._clock() - self._ref[0])
        return line

    def sleep_until(self, sim_s: float) -> None:
        """Sleep until the wall clock allows sim time ``sim_s``, the sim being there (a loop that steps, then
        waits for the time it reached)."""
        self.allowed(sim_s)
        delay = self.wait_s(sim_s)
        if delay > 0.0:
            time.sleep(delay)

    def wait_s(self, sim_s: float) -> float:
        """Wall seconds to wait until sim time ``sim_s`` is allowed (0 when it is)."""
        if self.rtf is None or self._ref is None:
            return 0.0
        return max(0.0, self._ref[0] + (sim_s - self._ref[1]) / self.rtf - self._clock())

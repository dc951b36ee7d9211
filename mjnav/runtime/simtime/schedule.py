"""One schedule type for every periodic duty on a clock (sim time or wall time)."""

from __future__ import annotations

import math

#: Tolerance on due times: accumulated float error never defers a duty to the next tick.
EPS_S = 1e-9


class Schedule:
    """Due at ``origin_s + k · period_s`` for k = 0, 1, … — each due time computed from the count, so there is no
    drift however long it runs.

    Args:
        period_s: seconds between two due times (> 0).
        origin_s: the first due time.

    Raises:
        ValueError: a period that is not a positive number.
    """

    def __init__(self, period_s: float, origin_s: float = 0.0) -> None:
        if not (math.isfinite(period_s) and period_s > 0.0):
            raise ValueError(f"a schedule's period must be a positive number of seconds, got {period_s}")
        self.period_s = period_s
        self.reset(origin_s)

    @classmethod
    def every(cls, rate_hz: float, origin_s: float = 0.0) -> Schedule:
        """The schedule of a rate (``rate_hz`` per second)."""
        return cls(1.0 / rate_hz, origin_s)

    def reset(self, origin_s: float) -> None:
        """Start again: the next due time is ``origin_s``."""
        self.origin_s = origin_s
        self.count = 0

    @property
    def next_s(self) -> float:
        """The next due time."""
        return self.origin_s + self.count * self.period_s

    def due(self, t: float) -> bool:
        """Whether a due time has been reached at ``t``; if so the duty counts as done and the schedule moves to the
        first due time after ``t`` (missed ones are skipped, not made up)."""
        if t + EPS_S < self.next_s:
            return False
        self.count = math.floor((t + EPS_S - self.origin_s) / self.period_s) + 1
        return True

    def missed(self, t: float) -> int:
        """How many due times before the one reached at ``t`` passed without a call to :meth:`due` (0 when ``t`` is
        the next due time or earlier)."""
        return max(0, math.floor((t + EPS_S - self.origin_s) / self.period_s) - self.count)

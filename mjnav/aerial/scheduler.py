"""Onboard task scheduler: a cyclic executive run on simulated time.

A table of `Task` rows (name, rate, time budget, priority) is run on a base tick supplied by the caller's sim
time (no wall clock). At each base tick every task whose next release is due runs once, in the table's fixed
order — the seed's order IMU → DAQ → CAM → CTL → SVO → NET → CMM → DLG for `default_task_table()`. Releases are
computed with exact rational arithmetic, so over ``n`` consecutive base ticks starting at tick 0 a task of rate
``f`` runs exactly ``floor((n - 1) · f / f_base) + 1`` times (10 s at a 1 kHz base → a 1 kHz IMU task runs
10,000 times, a 30 Hz camera task 300 times).

A task's handler returns its (simulated) execution time in microseconds; a run longer than the task's budget is
an overrun, and a base tick whose tasks together take longer than the base period is a frame overrun. Priority is
carried for reporting and for the caller's own policies (larger = more important); it does not reorder the fixed
execution order.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction

from mjnav.aerial.errors import InvalidParameterError

__all__ = ["SEED_TASK_ORDER", "Scheduler", "Task", "TaskStats", "default_task_table"]

SEED_TASK_ORDER = ("IMU", "DAQ", "CAM", "CTL", "SVO", "NET", "CMM", "DLG")
"""The seed's fixed execution order: IMU read, data acquisition, camera, control, servo output, network,
communication, data logging."""

Handler = Callable[[float], "float | None"]


@dataclass(frozen=True)
class Task:
    """One row of the task table.

    Attributes:
        name: unique task name.
        rate_hz: release rate, Hz (0 < rate_hz <= the scheduler's base rate).
        budget_us: time budget per run, microseconds (> 0).
        priority: larger = more important (reported; the execution order is the table order).
    """

    name: str
    rate_hz: float
    budget_us: float
    priority: int = 0

    def __post_init__(self) -> None:
        if not self.name:
            raise InvalidParameterError("task name must not be empty")
        if not self.rate_hz > 0.0:
            raise InvalidParameterError(f"task {self.name}: rate_hz must be > 0, got {self.rate_hz}")
        if not self.budget_us > 0.0:
            raise InvalidParameterError(f"task {self.name}: budget_us must be > 0, got {self.budget_us}")


@dataclass
class TaskStats:
    """Counters of one task: runs, overruns (run time > budget), total and worst simulated run time (µs)."""

    invocations: int = 0
    overruns: int = 0
    total_us: float = 0.0
    max_us: float = 0.0


def default_task_table() -> tuple[Task, ...]:
    """The seed's eight tasks in their fixed order, for a 1 kHz base tick.

    IMU 1000 Hz/100 µs, DAQ 500 Hz/80 µs, CAM 30 Hz/2000 µs, CTL 250 Hz/150 µs, SVO 250 Hz/50 µs,
    NET 50 Hz/300 µs, CMM 10 Hz/500 µs, DLG 10 Hz/1000 µs; priorities descend in that order (IMU 8 … DLG 1).
    """
    rows = [
        ("IMU", 1000.0, 100.0),
        ("DAQ", 500.0, 80.0),
        ("CAM", 30.0, 2000.0),
        ("CTL", 250.0, 150.0),
        ("SVO", 250.0, 50.0),
        ("NET", 50.0, 300.0),
        ("CMM", 10.0, 500.0),
        ("DLG", 10.0, 1000.0),
    ]
    return tuple(Task(n, r, b, len(rows) - i) for i, (n, r, b) in enumerate(rows))


@dataclass
class _Slot:
    task: Task
    num: int  # rate / base = num / den
    den: int
    next_release: int = 0
    stats: TaskStats = field(default_factory=TaskStats)


class Scheduler:
    """Cyclic executive over a task table, stepped by the caller on sim time.

    Args:
        tasks: the task table (`Task` rows or (name, rate_hz, budget_us, priority) tuples); run in this order at
            each tick (names unique).
        base_rate_hz: base tick rate, Hz; every task rate must be <= it.
        handlers: task name → callable(now_s) returning the run's simulated duration in µs (None counts as 0).
            Tasks without a handler run as no-ops taking 0 µs.
        t0_s: sim time of tick 0, seconds.

    Raises:
        InvalidParameterError: duplicate names, a rate above the base rate, a handler for an unknown task.
    """

    def __init__(
        self,
        tasks: Sequence[Task | tuple[str, float, float, int]],
        base_rate_hz: float = 1000.0,
        handlers: Mapping[str, Handler] | None = None,
        t0_s: float = 0.0,
    ) -> None:
        if not base_rate_hz > 0.0:
            raise InvalidParameterError(f"base_rate_hz must be > 0, got {base_rate_hz}")
        table = [t if isinstance(t, Task) else Task(*t) for t in tasks]
        names = [t.name for t in table]
        if len(set(names)) != len(names):
            raise InvalidParameterError(f"task names must be unique, got {names}")
        base = Fraction(base_rate_hz).limit_denominator(10**6)
        self._slots: list[_Slot] = []
        for t in table:
            if t.rate_hz > base_rate_hz:
                raise InvalidParameterError(f"task {t.name}: rate {t.rate_hz} Hz exceeds the base rate {base_rate_hz}")
            ratio = Fraction(t.rate_hz).limit_denominator(10**6) / base
            self._slots.append(_Slot(t, ratio.numerator, ratio.denominator))
        self._handlers: dict[str, Handler] = dict(handlers or {})
        unknown = set(self._handlers) - set(names)
        if unknown:
            raise InvalidParameterError(f"handlers for unknown tasks: {sorted(unknown)}")
        self.base_rate_hz = float(base_rate_hz)
        self.t0_s = float(t0_s)
        self.period_us = 1e6 / self.base_rate_hz
        self.tick_count = 0
        self.frame_overruns = 0
        self.skipped_releases = 0

    @property
    def tasks(self) -> tuple[Task, ...]:
        """The task table in execution order."""
        return tuple(s.task for s in self._slots)

    def set_handler(self, name: str, handler: Handler) -> None:
        """Attach (or replace) the handler of task ``name``."""
        if name not in {s.task.name for s in self._slots}:
            raise InvalidParameterError(f"no task named {name!r}")
        self._handlers[name] = handler

    def tick_index(self, now_s: float) -> int:
        """The base tick index of sim time ``now_s`` (rounded to the nearest tick)."""
        return round((now_s - self.t0_s) * self.base_rate_hz)

    def tick(self, now_s: float | None = None) -> list[str]:
        """Run the tasks due at sim time ``now_s`` (default: the next base tick) and return their names in order.

        Ticks must not go backwards; skipped ticks are allowed (each task then runs once and the releases it
        missed are counted in ``skipped_releases``).

        Raises:
            InvalidParameterError: ``now_s`` is before the last tick run.
        """
        k = self.tick_count if now_s is None else self.tick_index(now_s)
        if k < self.tick_count:
            raise InvalidParameterError(f"sim time went backwards: tick {k} after tick {self.tick_count - 1}")
        now = self.t0_s + k / self.base_rate_hz
        ran: list[str] = []
        frame_us = 0.0
        for s in self._slots:
            # release r is due at tick ceil(r · den / num); due now if next_release · den <= k · num
            if s.next_release * s.den > k * s.num:
                continue
            latest = (k * s.num) // s.den  # the newest release index that is due
            self.skipped_releases += latest - s.next_release
            s.next_release = latest + 1
            handler = self._handlers.get(s.task.name)
            spent = handler(now) if handler is not None else None
            us = float(spent) if spent is not None else 0.0
            st = s.stats
            st.invocations += 1
            st.total_us += us
            st.max_us = max(st.max_us, us)
            if us > s.task.budget_us:
                st.overruns += 1
            frame_us += us
            ran.append(s.task.name)
        if frame_us > self.period_us:
            self.frame_overruns += 1
        self.tick_count = k + 1
        return ran

    def run_for(self, duration_s: float) -> None:
        """Run ``round(duration_s · base_rate_hz)`` consecutive base ticks from the current one."""
        if duration_s < 0.0:
            raise InvalidParameterError(f"duration_s must be >= 0, got {duration_s}")
        for _ in range(round(duration_s * self.base_rate_hz)):
            self.tick()

    def run(self, duration_s: float) -> None:
        """Same as `run_for`."""
        self.run_for(duration_s)

    def run_until(self, t_end_s: float) -> None:
        """Run every base tick whose time is before ``t_end_s`` (sim time, s)."""
        end = self.tick_index(t_end_s)
        while self.tick_count < end:
            self.tick()

    @property
    def now_s(self) -> float:
        """Sim time of the next base tick, s."""
        return self.t0_s + self.tick_count / self.base_rate_hz

    def stats(self) -> dict[str, TaskStats]:
        """Task name → its counters (live objects, in execution order)."""
        return {s.task.name: s.stats for s in self._slots}

    def invocations(self) -> dict[str, int]:
        """Task name → number of runs so far."""
        return {s.task.name: s.stats.invocations for s in self._slots}

    def overruns(self) -> dict[str, int]:
        """Task name → number of runs over budget so far."""
        return {s.task.name: s.stats.overruns for s in self._slots}

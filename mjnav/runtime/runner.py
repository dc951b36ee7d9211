"""Runs the services of one process: signals, the Zenoh session, the rate loop, liveliness and the status topics.

A process hosts one service (``mjnav run sim``) or several (a *container*, ``mjnav run slam mapper …``: ROS 2's
composition). The services of a process share its Zenoh session, so what they send each other never leaves the
process (Zenoh delivers it locally, without the router), and, on sim time, one clock: each accepted clock commits
every service's staged input (:class:`~mjnav.runtime.simtime.SimTimeGate`) and the loop steps, in the order they
were given, the services whose step is due. Each service keeps what it has alone: its own bus (its subscriptions,
its staging, its counters, the receipts it signs), config, lifecycle, status topic, liveliness token and lockstep
slot. A mission gives the same result to the last bit however the services are packed: a step at sim time t sees
exactly what was sent before t, whether it came from the next process or from the same one.

Each service steps at its config's ``rate_hz`` on sim time (the ``clock`` topic; the loop waits for the first
clock message) or on wall time, on its own :class:`~mjnav.runtime.simtime.Schedule`. A due time that passes without
a step — a step took too long, the clock jumped — counts as an overrun. Every second (wall time) each service's
``mjnav_msgs/ServiceStatus`` goes out on ``<ns>/status/<service>``. SIGINT/SIGTERM end the loop cleanly
(deactivate, final status, session closed); a second signal exits at once.
"""

from __future__ import annotations

import json
import logging
import math
import os
import signal
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from types import FrameType
from typing import Any

from mjnav.bus import Bus, BusConfig
from mjnav.msgs import msg_class, ros
from mjnav.runtime.config import build_config, config_to_dict
from mjnav.runtime.service import Service
from mjnav.runtime.simtime import (
    ClockJumpedBack,
    LockstepReporter,
    Schedule,
    SimClock,
    SimTimeGate,
    StopRequested,
    WallClock,
)

#: Wall seconds between status messages.
STATUS_PERIOD_S = 1.0
#: Wall seconds one step may run while the status heartbeat still goes out (from a helper thread): a numba kernel
#: compiling on its first call (seconds; tens on a loaded machine with cold caches) is work, not a hang, and must not
#: get the service killed by the launcher's hang check. A step running longer than this is hung: the heartbeat stops.
STEP_HEARTBEAT_LIMIT_S = 60.0
log = logging.getLogger("mjnav.runtime")
#: Wall seconds between two looks at what a starting service still waits for (:meth:`Service.starting`).
_STARTING_POLL_S = 0.02
#: Seconds (of the loop's clock) a service must have lacked an input before its status says so: the inputs of a
#: stack that is starting arrive within a step or two of each other, and that is not starving.
STARVED_GRACE_S = 1.0

_STATE = {"unconfigured": 0, "inactive": 1, "active": 2, "finalized": 3}


@dataclass
class LoopStats:
    """Loop statistics reported in the status message."""

    steps: int = 0
    overruns: int = 0
    step_errors: int = 0
    step_time_sum_s: float = 0.0
    step_time_max_s: float = 0.0
    step_cpu_s: float = 0.0
    period_steps: int = 0
    period_start: float = math.nan
    last_error: str = ""


@dataclass(frozen=True)
class Unit:
    """A service a process runs: its class, validated config (with ``rate_hz``) and name."""

    service_cls: type[Service[Any]]
    config: Any
    name: str


@dataclass
class _Hosted:
    """A service in the process, with everything it has on its own."""

    unit: Unit
    config: Any
    bus: Bus
    log: logging.Logger
    service: Any = None
    status_pub: Any = None
    schedule: Schedule | None = None  # None until the first tick
    reporter: LockstepReporter | None = None
    stats: LoopStats = field(default_factory=LoopStats)
    state: str = "unconfigured"
    waiting_for: str = ""  # what it lacks (Service.starting, then Service.starved), for the status
    lacking_since: float = math.nan  # loop time since which Service.starved has said something
    next_config: Any = None  # a config set through set_param, swapped in before its next step

    @property
    def name(self) -> str:
        return self.unit.name


class ServiceRunner:
    """Owns the process-level concerns of the services of one process.

    Args:
        service_cls: the :class:`Service` subclass (one service), or a sequence of :class:`Unit` (a container).
        config: its validated config (must have ``rate_hz``); None with units.
        bus_config: how to join Zenoh.
        namespace: robot namespace.

    Raises:
        ValueError: no service, two with one name, or a container mixing sim time and wall time.
    """

    def __init__(
        self,
        service_cls: type[Service[Any]] | Sequence[Unit],
        config: Any = None,
        bus_config: BusConfig | None = None,
        namespace: str = "robot0",
    ) -> None:
        if isinstance(service_cls, type):
            units: list[Unit] = [Unit(service_cls, config, service_cls.name)]
            sim_time = service_cls.uses_sim_time
        else:
            units = list(service_cls)
            if not units:
                raise ValueError("a process runs at least one service")
            kinds = {u.service_cls.uses_sim_time for u in units}
            if len(kinds) > 1:
                clocks = ", ".join(f"{u.name} ({'sim' if u.service_cls.uses_sim_time else 'wall'})" for u in units)
                raise ValueError(f"the services of one process step on one clock, sim or wall time: {clocks}")
            sim_time = kinds.pop()
            alone = [u.name for u in units if u.service_cls.runs_alone]
            if alone and len(units) > 1:
                raise ValueError(f"{', '.join(alone)} must run in a process of its own (Service.runs_alone)")
        names = [u.name for u in units]
        if len(set(names)) != len(names):
            raise ValueError(f"two services of one process share a name: {names}")
        if bus_config is None:
            raise ValueError("bus_config is required")
        self.units = units
        self.bus_config = bus_config
        self.namespace = namespace
        self.name = "+".join(names)
        self.use_sim_time = sim_time
        self.log = logging.getLogger(f"mjnav.{names[0]}" if len(units) == 1 else "mjnav.runtime")
        self.stop_event = threading.Event()
        self._started = time.monotonic()
        self._signals = 0
        self._handle_signals = False
        self._config_lock = threading.Lock()
        self._step_started: float | None = None  # time.monotonic() when the running step began (None: between steps)
        self.hosted: list[_Hosted] = []
        #: The loop's clock (sim or wall time) once it runs.
        self.clock: WallClock | SimClock | None = None

    # -------------------------------------------------------------------------------------- one service's view

    @property
    def stats(self) -> LoopStats:
        """The first (for one service: the) service's loop statistics."""
        return self.hosted[0].stats if self.hosted else LoopStats()

    # ---------------------------------------------------------------------------------------------- signals

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self._signals += 1
        if self._signals > 1:
            self.log.warning("second %s: exiting now", signal.Signals(signum).name)
            os._exit(128 + signum)
        self.log.info("%s: stopping", signal.Signals(signum).name)
        self.stop_event.set()

    def install_signal_handlers(self) -> None:
        """SIGINT/SIGTERM request a clean stop; a second one forces exit (main thread only). The handlers take over
        once :meth:`run` has its session open: until then a signal ends the process at once, as by default — the
        opening of a client session waits in Zenoh for a router as long as it takes, where no Python handler runs,
        and a service whose launcher died (the launcher's parent-death SIGTERM) before its router answered lived on
        for ever."""
        self._handle_signals = True

    # ---------------------------------------------------------------------------------------------- status

    def _status_msg(self, h: _Hosted, now: float) -> Any:
        s = h.stats
        span = now - s.period_start if math.isfinite(now) and math.isfinite(s.period_start) else 0.0
        loop_rate = s.period_steps / span if span > 0 else 0.0
        stamp = now if math.isfinite(now) and 0 <= now < ros.MAX_STAMP_S else 0.0
        return msg_class("mjnav_msgs/msg/ServiceStatus")(
            header=ros.header(stamp, ""),
            service=h.name,
            robot_namespace=self.namespace,
            state=_STATE[h.state],
            pid=os.getpid(),
            uptime_s=time.monotonic() - self._started,
            target_rate_hz=float(h.config.rate_hz),
            loop_rate_hz=loop_rate,
            step_mean_ms=1e3 * s.step_time_sum_s / s.steps if s.steps else 0.0,
            step_max_ms=1e3 * s.step_time_max_s,
            step_cpu_s=s.step_cpu_s,
            process_cpu_s=time.process_time(),
            steps=s.steps,
            overruns=s.overruns,
            messages_received=h.bus.stats.received,
            messages_rejected=h.bus.stats.rejected,
            messages_published=h.bus.stats.published,
            last_error=s.last_error or h.bus.stats.last_rejection,
            waiting_for=h.waiting_for,
        )

    def _send_statuses(self, now: float, *, new_period: bool = False) -> None:
        for h in self.hosted:
            if h.status_pub is not None:
                h.status_pub.put(self._status_msg(h, now))
            if new_period:
                h.stats.period_steps = 0
                h.stats.period_start = now

    # ---------------------------------------------------------------------------------------------- main

    def run(self) -> int:
        """Run until stopped; returns the process exit code (0 after a clean stop)."""
        root = Bus.open(self.bus_config, self.namespace)
        if self._handle_signals:
            signal.signal(signal.SIGINT, self._on_signal)
            signal.signal(signal.SIGTERM, self._on_signal)
        try:
            return self._run(root)
        finally:
            for h in self.hosted:
                if h.bus is not root:
                    h.bus.close()
            root.close()

    def _host(self, root: Bus) -> None:
        """One bus per service on the process's session (the first service's is the session's own)."""
        string = msg_class("std_msgs/msg/String")
        for i, unit in enumerate(self.units):
            bus = root if i == 0 else root.sharing()
            h = _Hosted(unit, unit.config, bus, logging.getLogger(f"mjnav.{unit.name}"))
            h.status_pub = bus.publisher("status", service=unit.name)
            self._serve_endpoints(h, string)
            self.hosted.append(h)

    def _serve_endpoints(self, h: _Hosted, string: Any) -> None:
        """``<ns>/config/<service>`` and ``<ns>/set_param/<service>`` for one service."""

        def get_config(_request: Any) -> Any:
            return string(data=json.dumps(config_to_dict(h.config)))

        def set_param(request: Any) -> Any:
            return string(data=json.dumps(self._set_param(h, request.data)))

        h.bus.serve("config", get_config, service=h.name)
        h.bus.serve("set_param", set_param, service=h.name)

    def _run(self, root: Bus) -> int:
        self._host(root)
        clock: WallClock | SimClock
        if self.use_sim_time:
            gates = [SimTimeGate(h.bus) for h in self.hosted]
            clock = SimClock(root, gates)
        else:
            clock = WallClock()
        self.clock = clock
        for h in self.hosted:
            h.service = h.unit.service_cls(h.config, h.bus, h.log)
            h.service.configure()
            h.state = "inactive"
        for h in self.hosted:
            h.service.activate()
            h.state = "active"
            h.bus.declare_alive(h.name)
        try:
            self._wait_until_started(lambda: self._send_statuses(clock.now()))
        except StopRequested:
            self._finish(clock)
            return 0
        for h in self.hosted:
            if self.use_sim_time:
                h.reporter = LockstepReporter(h.bus, h.name)
            h.log.info(
                "active: %.1f Hz on %s time, namespace %s%s",
                h.config.rate_hz,
                "sim" if self.use_sim_time else "wall",
                self.namespace,
                f", with {', '.join(o.name for o in self.hosted if o is not h)} in process {os.getpid()}"
                if len(self.hosted) > 1
                else "",
            )
        heartbeat = threading.Thread(
            target=self._long_step_heartbeat, args=(lambda: self._send_statuses(clock.now()),),
            name=f"{self.name}-heartbeat", daemon=True,
        )  # fmt: skip
        heartbeat.start()
        try:
            self._loop(clock)
        finally:
            self.stop_event.set()  # ends the heartbeat thread (the loop has ended whatever the reason)
            heartbeat.join()
            self._finish(clock)
        for h in self.hosted:
            h.log.info("stopped after %d steps", h.stats.steps)
        return 0

    def _finish(self, clock: WallClock | SimClock) -> None:
        """Deactivate every service (the last first) and send its final status."""
        for h in reversed(self.hosted):
            h.state = "finalized"
            try:
                h.service.deactivate()
            except Exception:
                h.log.exception("deactivate failed")
        self._send_statuses(clock.now())

    def _loop(self, clock: WallClock | SimClock) -> None:
        next_status = time.monotonic()
        waited_for_clock = False
        # Restarts handled so far: a clock that goes back while the services step (between two waits) must not be
        # taken for the new baseline, or the loop would wait for a time the new timeline reaches only much later.
        seen_jumps = clock.jumps_back
        while not self.stop_event.is_set():
            if time.monotonic() >= next_status:
                self._send_statuses(clock.now(), new_period=True)
                next_status += STATUS_PERIOD_S
            if self.hosted[0].schedule is None:
                if math.isnan(clock.now()):
                    if not waited_for_clock:
                        key = self.hosted[0].bus.key("clock")
                        self.log.info("waiting for the clock on %s", key)
                        for h in self.hosted:
                            h.waiting_for = f"the clock on {key} (sim time has not started)"
                        waited_for_clock = True
                    try:
                        clock.wait_until(-math.inf, _StopAfter(self.stop_event, STATUS_PERIOD_S))
                    except StopRequested:
                        continue
                for h in self.hosted:  # every schedule starts at the first clock (or the restart's)
                    h.schedule = Schedule.every(float(h.config.rate_hz), clock.now())
            due = min(h.schedule.next_s for h in self.hosted if h.schedule is not None)
            try:
                now = clock.wait_until(due - 1e-9, _StopAfter(self.stop_event, STATUS_PERIOD_S), seen_jumps)
            except StopRequested:
                continue
            except ClockJumpedBack:
                now = clock.now()
            if clock.jumps_back != seen_jumps:
                seen_jumps = clock.jumps_back
                # The simulator restarted: time-dependent state is void. Re-activate the services (their activate()
                # resets that state) and re-sync the loop on the new timeline.
                self.log.warning("the clock went back to %.3f s: re-activating", now)
                for h in self.hosted:
                    h.service.deactivate()
                    h.service.activate()
                    h.schedule = None
                continue
            for h in self.hosted:
                schedule = h.schedule
                assert schedule is not None
                missed = schedule.missed(now)
                if not schedule.due(now):
                    continue
                h.stats.overruns += missed
                self._apply_config(h)
                self._step(h, now)
                self._note_starved(h, h.service.starved(), now)
                if h.reporter is not None:
                    h.reporter.ready(now, schedule.next_s)

    def _wait_until_started(self, send_status: Callable[[], None]) -> None:
        """Hold the services back, their statuses going out every second, until each has what it needs to step
        (:meth:`Service.starting`); each says once what it waits for.

        Raises:
            StopRequested: the runner was stopped meanwhile.
        """
        next_status = time.monotonic()
        while True:
            waiting = False
            for h in self.hosted:
                lacks = h.service.starting()
                if lacks and lacks != h.waiting_for:
                    h.log.info("waiting for %s", lacks)
                h.waiting_for = lacks
                waiting = waiting or bool(lacks)
            if not waiting:
                return
            if time.monotonic() >= next_status:
                send_status()
                next_status += STATUS_PERIOD_S
            if self.stop_event.wait(_STARTING_POLL_S):
                raise StopRequested

    @staticmethod
    def _note_starved(h: _Hosted, waiting: str, now: float) -> None:
        """Keep what a service lacks for its status, once it has lacked something for :data:`STARVED_GRACE_S`;
        log when that starts, changes and ends."""
        if not waiting:
            h.lacking_since = math.nan
        elif math.isnan(h.lacking_since):
            h.lacking_since = now
        if waiting and now - h.lacking_since < STARVED_GRACE_S:
            return
        if waiting == h.waiting_for:
            return
        if waiting:
            h.log.info("waiting for %s", waiting)
        else:
            h.log.info("no longer waiting for %s", h.waiting_for)
        h.waiting_for = waiting

    def _set_param(self, h: _Hosted, request: str) -> dict[str, Any]:
        """``set_param``: request JSON ``{"key": K, "value": V}``; validates V like the TOML file (type, range) for a
        key of the service's ``runtime_settable`` and queues the new config for its next step. Returns
        ``{"key", "value", "previous"}``.

        Raises:
            ValueError: malformed request, a key that is not settable at runtime, or a value the config rejects
                (the caller gets an error reply naming it).
        """
        try:
            data = json.loads(request)
            key, value = data["key"], data["value"]
        except (ValueError, TypeError, KeyError) as exc:
            raise ValueError(f'request must be JSON {{"key": ..., "value": ...}}: {exc}') from None
        settable = sorted(h.unit.service_cls.runtime_settable)
        if key not in settable:
            raise ValueError(f"{h.name}.{key} cannot be set while running; settable: {', '.join(settable) or 'none'}")
        with self._config_lock:
            current = h.next_config if h.next_config is not None else h.config
            values = config_to_dict(current)
            previous = values[key]
            values[key] = value
            new = build_config(type(current), values, where=f"{h.name}.{key}")  # ConfigError is a ValueError
            h.next_config = new
        return {"key": key, "value": config_to_dict(new)[key], "previous": previous}

    def _apply_config(self, h: _Hosted) -> None:
        """Swap in a config set through ``set_param`` (between two steps, in the loop's thread)."""
        with self._config_lock:
            new, h.next_config = h.next_config, None
        if new is None:
            return
        changed = {k: v for k, v in config_to_dict(new).items() if config_to_dict(h.config)[k] != v}
        h.config = h.service.config = new
        h.log.info("parameters set: %s", ", ".join(f"{k} = {v!r}" for k, v in changed.items()) or "no change")

    def _long_step_heartbeat(self, send_status: Callable[[], None]) -> None:
        """While a step runs longer than a status period (and at most :data:`STEP_HEARTBEAT_LIMIT_S`), send the
        statuses every period from this thread, and say once per step in the log what holds the loop."""
        warned: float | None = None
        while not self.stop_event.wait(STATUS_PERIOD_S):
            started = self._step_started
            if started is None:
                continue
            running = time.monotonic() - started
            if running < STATUS_PERIOD_S or running > STEP_HEARTBEAT_LIMIT_S:
                continue
            if warned != started and running >= 5 * STATUS_PERIOD_S:
                warned = started
                self.log.warning(
                    "one step has been running for %.0f s (a kernel compiling on first use?); the status goes on "
                    "for up to %.0f s of it",
                    running,
                    STEP_HEARTBEAT_LIMIT_S,
                )
            send_status()

    def _step(self, h: _Hosted, now: float) -> None:
        t0 = time.perf_counter()
        cpu0 = time.thread_time()
        self._step_started = time.monotonic()
        s = h.stats
        try:
            h.service.step(now)
        except Exception as exc:
            s.step_errors += 1
            s.last_error = f"{type(exc).__name__}: {exc}"
            if s.step_errors <= 10 or s.step_errors % 100 == 0:
                h.log.exception("step failed (%d so far)", s.step_errors)
        self._step_started = None
        dt = time.perf_counter() - t0
        s.step_cpu_s += time.thread_time() - cpu0
        s.steps += 1
        s.period_steps += 1
        s.step_time_sum_s += dt
        s.step_time_max_s = max(s.step_time_max_s, dt)


class _StopAfter:
    """A stop flag that also trips after ``timeout_s`` wall seconds, so the loop can publish status while idle."""

    def __init__(self, stop: threading.Event, timeout_s: float) -> None:
        self._stop = stop
        self._deadline = time.monotonic() + timeout_s

    def is_set(self) -> bool:
        return self._stop.is_set() or time.monotonic() >= self._deadline

    def wait(self, timeout: float) -> bool:
        remaining = self._deadline - time.monotonic()
        if remaining <= 0:
            return True
        return self._stop.wait(min(timeout, remaining)) or time.monotonic() >= self._deadline

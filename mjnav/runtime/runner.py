"""Runs one service: signals, the Zenoh session, the rate loop, liveliness and the status topic.

The loop steps the service at ``config.rate_hz`` on sim time (the ``clock`` topic; the service waits for the first
clock message) or on wall time. A period that passes without a step — because ``step`` took too long or the
clock jumped — counts as an overrun. Every second (wall time) a ``mjnav_msgs/ServiceStatus`` goes out on
``<ns>/status/<service>``. SIGINT/SIGTERM end the loop cleanly (deactivate, final status, session closed);
a second signal exits at once.
"""

from __future__ import annotations

import json
import logging
import math
import os
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import FrameType
from typing import Any, Protocol

from mjnav.bus import Bus, BusConfig
from mjnav.msgs import msg_class, ros
from mjnav.runtime.config import build_config, config_to_dict
from mjnav.runtime.service import Service

#: Wall seconds between status messages.
STATUS_PERIOD_S = 1.0
#: Wall seconds one step may run while the status heartbeat still goes out (from a helper thread): a numba kernel
#: compiling on its first call (seconds; tens on a loaded machine with cold caches) is work, not a hang, and must not
#: get the service killed by the launcher's hang check. A step running longer than this is hung: the heartbeat stops.
STEP_HEARTBEAT_LIMIT_S = 60.0
log = logging.getLogger("mjnav.runtime")
#: How long blocking waits sleep at most before re-checking for a stop request.
_POLL_S = 0.1
#: Tolerance on tick times, so that accumulated float error never defers a step to the next clock message.
_TICK_EPS_S = 1e-9
#: Wall seconds between two looks at what a starting service still waits for (:meth:`Service.starting`).
_STARTING_POLL_S = 0.02
#: Seconds (of the loop's clock) a service must have lacked an input before its status says so: the inputs of a
#: stack that is starting arrive within a step or two of each other, and that is not starving.
STARVED_GRACE_S = 1.0

_STATE = {"unconfigured": 0, "inactive": 1, "active": 2, "finalized": 3}


class StopRequested(Exception):
    """Raised inside waits when the runner was asked to stop."""


class _Stopper(Protocol):
    def is_set(self) -> bool: ...

    def wait(self, timeout: float) -> bool: ...


class _WallClock:
    jumps_back = 0

    def __init__(self) -> None:
        self._t0 = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self._t0

    def wait_until(self, t: float, stop: _Stopper, jumps: int | None = None) -> float:
        while True:
            now = self.now()
            if now >= t:
                return now
            if stop.wait(min(t - now, _POLL_S)):
                raise StopRequested


class ClockJumpedBack(Exception):
    """The sim clock went backwards (the simulator restarted); pending waits are abandoned."""


#: Largest forward step of sim time between two clock messages that is believed (sim s); a clock further ahead is
#: dropped as forged or corrupt (the sim ticks 0.05 s apart; a restarted sim goes back, never far forward).
MAX_CLOCK_JUMP_S = 5.0


class _SimClock:
    """Sim time from the ``clock`` topic; a wait is woken by the clock message that reaches its time (or goes back),
    not by every tick. A clock more than :data:`MAX_CLOCK_JUMP_S` ahead of the current time is dropped and
    counted (``rejected_jumps``): one forged message must not fast-forward the service out of the run.

    The bus is switched to staged delivery: every other message becomes visible to the service when the next clock
    message arrives (:meth:`~mjnav.bus.Bus.commit`), so a step at sim time t sees what was published before the
    sim reached t and nothing that peers publish while they step at t.
    """

    def __init__(self, bus: Bus) -> None:
        self._cond = threading.Condition()
        self._now = math.nan
        self._waiting_for = -math.inf  # the time a wait is blocked on (-inf: wake on any clock)
        self.jumps_back = 0
        self.rejected_jumps = 0
        self._bus = bus
        bus.staged = True
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
        self._bus.commit(t)
        with self._cond:
            back = t < self._now
            if back:
                self.jumps_back += 1
            self._now = t
            if back or t >= self._waiting_for:
                self._cond.notify_all()

    def now(self) -> float:
        with self._cond:
            return self._now

    def wait_until(self, t: float, stop: _Stopper, jumps: int | None = None) -> float:
        """Block until sim time >= ``t``; raises ClockJumpedBack once ``jumps_back`` differs from ``jumps``."""
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


@dataclass
class LoopStats:
    """Loop statistics reported in the status message."""

    steps: int = 0
    overruns: int = 0
    step_errors: int = 0
    step_time_sum_s: float = 0.0
    step_time_max_s: float = 0.0
    period_steps: int = 0
    period_start: float = math.nan
    last_error: str = ""


class ServiceRunner:
    """Owns the process-level concerns of one service.

    Args:
        service_cls: the :class:`Service` subclass.
        config: its validated config (must have ``rate_hz``).
        bus_config: how to join Zenoh.
        namespace: robot namespace.
        name: service name (default ``service_cls.name``).
        use_sim_time: override ``service_cls.uses_sim_time``.
    """

    def __init__(
        self,
        service_cls: type[Service[Any]],
        config: Any,
        bus_config: BusConfig,
        namespace: str,
        *,
        name: str | None = None,
        use_sim_time: bool | None = None,
    ) -> None:
        self.service_cls = service_cls
        self.config = config
        self.bus_config = bus_config
        self.namespace = namespace
        self.name = name or service_cls.name
        self.use_sim_time = service_cls.uses_sim_time if use_sim_time is None else use_sim_time
        self.log = logging.getLogger(f"mjnav.{self.name}")
        self.stop_event = threading.Event()
        self.stats = LoopStats()
        self._state = "unconfigured"
        self._started = time.monotonic()
        self._signals = 0
        self._config_lock = threading.Lock()
        self._next_config: Any = None  # a config set through set_param, swapped in before the next step
        self._step_started: float | None = None  # time.monotonic() when the running step began (None: between steps)
        self.waiting_for = ""  # what the service lacks (Service.starting, then Service.starved), for the status
        self._lacking_since = math.nan  # loop time since which Service.starved has said something

    # ---------------------------------------------------------------------------------------------- signals

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self._signals += 1
        if self._signals > 1:
            self.log.warning("second %s: exiting now", signal.Signals(signum).name)
            os._exit(128 + signum)
        self.log.info("%s: stopping", signal.Signals(signum).name)
        self.stop_event.set()

    def install_signal_handlers(self) -> None:
        """SIGINT/SIGTERM request a clean stop; a second one forces exit (main thread only)."""
        signal.signal(signal.SIGINT, self._on_signal)
        signal.signal(signal.SIGTERM, self._on_signal)

    # ---------------------------------------------------------------------------------------------- status

    def _status_msg(self, bus: Bus, now: float) -> Any:
        s = self.stats
        span = now - s.period_start if math.isfinite(now) and math.isfinite(s.period_start) else 0.0
        loop_rate = s.period_steps / span if span > 0 else 0.0
        stamp = now if math.isfinite(now) and 0 <= now < ros.MAX_STAMP_S else 0.0
        return msg_class("mjnav_msgs/msg/ServiceStatus")(
            header=ros.header(stamp, ""),
            service=self.name,
            robot_namespace=self.namespace,
            state=_STATE[self._state],
            pid=os.getpid(),
            uptime_s=time.monotonic() - self._started,
            target_rate_hz=float(self.config.rate_hz),
            loop_rate_hz=loop_rate,
            step_mean_ms=1e3 * s.step_time_sum_s / s.steps if s.steps else 0.0,
            step_max_ms=1e3 * s.step_time_max_s,
            steps=s.steps,
            overruns=s.overruns,
            messages_received=bus.stats.received,
            messages_rejected=bus.stats.rejected,
            messages_published=bus.stats.published,
            last_error=s.last_error or bus.stats.last_rejection,
            waiting_for=self.waiting_for,
        )

    # ---------------------------------------------------------------------------------------------- main

    def run(self) -> int:
        """Run until stopped; returns the process exit code (0 after a clean stop)."""
        bus = Bus.open(self.bus_config, self.namespace)
        try:
            return self._run(bus)
        finally:
            bus.close()

    def _run(self, bus: Bus) -> int:
        status_pub = bus.publisher("status", service=self.name)
        string = msg_class("std_msgs/msg/String")
        bus.serve("config", lambda _req: string(data=json.dumps(config_to_dict(self.config))), service=self.name)
        bus.serve("set_param", lambda req: string(data=json.dumps(self._set_param(req.data))), service=self.name)
        clock: _WallClock | _SimClock = _SimClock(bus) if self.use_sim_time else _WallClock()

        service = self.service_cls(self.config, bus, self.log)
        service.configure()
        self._state = "inactive"
        service.activate()
        self._state = "active"
        bus.declare_alive(self.name)
        try:
            self._wait_until_started(service, lambda: status_pub.put(self._status_msg(bus, clock.now())))
        except StopRequested:
            service.deactivate()
            status_pub.put(self._status_msg(bus, clock.now()))
            return 0
        lockstep = _LockstepReport(bus, self.name) if self.use_sim_time else None
        self.log.info(
            "active: %.1f Hz on %s time, namespace %s",
            self.config.rate_hz,
            "sim" if self.use_sim_time else "wall",
            self.namespace,
        )
        period = 1.0 / float(self.config.rate_hz)
        next_status = time.monotonic()
        next_tick = math.nan
        waited_for_clock = False
        heartbeat = threading.Thread(
            target=self._long_step_heartbeat, args=(lambda: status_pub.put(self._status_msg(bus, clock.now())),),
            name=f"{self.name}-heartbeat", daemon=True,
        )  # fmt: skip
        heartbeat.start()
        try:
            while not self.stop_event.is_set():
                if time.monotonic() >= next_status:
                    status_pub.put(self._status_msg(bus, clock.now()))
                    self.stats.period_steps = 0
                    self.stats.period_start = clock.now()
                    next_status += STATUS_PERIOD_S
                if math.isnan(next_tick):
                    if math.isnan(clock.now()):
                        if not waited_for_clock:
                            self.log.info("waiting for the clock on %s", bus.key("clock"))
                            self.waiting_for = f"the clock on {bus.key('clock')} (sim time has not started)"
                            waited_for_clock = True
                        try:
                            clock.wait_until(-math.inf, _StopAfter(self.stop_event, STATUS_PERIOD_S))
                        except StopRequested:
                            continue
                    next_tick = clock.now()
                jumps = clock.jumps_back
                try:
                    now = clock.wait_until(next_tick - _TICK_EPS_S, _StopAfter(self.stop_event, STATUS_PERIOD_S), jumps)
                except StopRequested:
                    continue
                except ClockJumpedBack:
                    now = clock.now()
                if clock.jumps_back != jumps:
                    # The simulator restarted: time-dependent state is void. Re-activate the service (its
                    # activate() resets that state) and re-sync the loop on the new timeline.
                    self.log.warning("the clock went back to %.3f s: re-activating", now)
                    service.deactivate()
                    service.activate()
                    next_tick = math.nan
                    continue
                missed = math.floor((now - next_tick) / period + _TICK_EPS_S)
                if missed > 0:
                    self.stats.overruns += missed
                    next_tick = now
                self._apply_config(service)
                self._step(service, now)
                self._note_starved(service.starved(), now)
                next_tick += period
                if lockstep is not None:
                    lockstep.ready(now, next_tick)
        finally:
            self._state = "finalized"
            self.stop_event.set()  # ends the heartbeat thread (the loop has ended whatever the reason)
            heartbeat.join()
            try:
                service.deactivate()
            finally:
                status_pub.put(self._status_msg(bus, clock.now()))
        self.log.info("stopped after %d steps", self.stats.steps)
        return 0

    def _wait_until_started(self, service: Service[Any], send_status: Callable[[], None]) -> None:
        """Hold the service back, its status going out every second, until it has what it needs to step
        (:meth:`Service.starting`); says once what it waits for.

        Raises:
            StopRequested: the runner was stopped meanwhile.
        """
        next_status = time.monotonic()
        while waiting := service.starting():
            if waiting != self.waiting_for:
                self.log.info("waiting for %s", waiting)
                self.waiting_for = waiting
            if time.monotonic() >= next_status:
                send_status()
                next_status += STATUS_PERIOD_S
            if self.stop_event.wait(_STARTING_POLL_S):
                raise StopRequested
        self.waiting_for = ""

    def _note_starved(self, waiting: str, now: float) -> None:
        """Keep what the service lacks for the status, once it has lacked something for :data:`STARVED_GRACE_S`;
        log when that starts, changes and ends."""
        if not waiting:
            self._lacking_since = math.nan
        elif math.isnan(self._lacking_since):
            self._lacking_since = now
        if waiting and now - self._lacking_since < STARVED_GRACE_S:
            return
        if waiting == self.waiting_for:
            return
        if waiting:
            self.log.info("waiting for %s", waiting)
        else:
            self.log.info("no longer waiting for %s", self.waiting_for)
        self.waiting_for = waiting

    def _set_param(self, request: str) -> dict[str, Any]:
        """``set_param``: request JSON ``{"key": K, "value": V}``; validates V like the TOML file (type, range) for a
        key of the service's ``runtime_settable`` and queues the new config for the next step. Returns
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
        settable = sorted(self.service_cls.runtime_settable)
        if key not in settable:
            raise ValueError(
                f"{self.name}.{key} cannot be set while running; settable: {', '.join(settable) or 'none'}"
            )
        with self._config_lock:
            current = self._next_config if self._next_config is not None else self.config
            values = config_to_dict(current)
            previous = values[key]
            values[key] = value
            new = build_config(type(current), values, where=f"{self.name}.{key}")  # ConfigError is a ValueError
            self._next_config = new
        return {"key": key, "value": config_to_dict(new)[key], "previous": previous}

    def _apply_config(self, service: Service[Any]) -> None:
        """Swap in a config set through ``set_param`` (between two steps, in the loop's thread)."""
        with self._config_lock:
            new, self._next_config = self._next_config, None
        if new is None:
            return
        changed = {k: v for k, v in config_to_dict(new).items() if config_to_dict(self.config)[k] != v}
        self.config = service.config = new
        self.log.info("parameters set: %s", ", ".join(f"{k} = {v!r}" for k, v in changed.items()) or "no change")

    def _long_step_heartbeat(self, send_status: Callable[[], None]) -> None:
        """While a step runs longer than a status period (and at most :data:`STEP_HEARTBEAT_LIMIT_S`), send the
        status every period from this thread, and say once per step in the log what holds the loop."""
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

    def _step(self, service: Service[Any], now: float) -> None:
        t0 = time.perf_counter()
        self._step_started = time.monotonic()
        try:
            service.step(now)
        except Exception as exc:
            self.stats.step_errors += 1
            self.stats.last_error = f"{type(exc).__name__}: {exc}"
            if self.stats.step_errors <= 10 or self.stats.step_errors % 100 == 0:
                self.log.exception("step failed (%d so far)", self.stats.step_errors)
        self._step_started = None
        dt = time.perf_counter() - t0
        s = self.stats
        s.steps += 1
        s.period_steps += 1
        s.step_time_sum_s += dt
        s.step_time_max_s = max(s.step_time_max_s, dt)


class _LockstepReport:
    """A sim-time service's part in the lockstep barrier: its token, and a report after every step."""

    def __init__(self, bus: Bus, participant: str) -> None:
        self._pub = bus.publisher("lockstep", service=participant)
        self._msg = msg_class("mjnav_msgs/msg/LockstepReady")
        self._participant = participant
        bus.declare_lockstep(participant)

    def ready(self, done: float, ready_until: float) -> None:
        """Report the step at sim time ``done`` finished; the next one is due at ``ready_until``."""
        self._pub.put(
            self._msg(header=ros.header(done, ""), participant=self._participant, ready_until=ros.time_msg(ready_until))
        )


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

"""The rate loop on sim time: steps at the configured rate of the clock topic, counts overruns."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import pytest

from mjnav.bus import Bus, BusConfig, Publisher, wait_until
from mjnav.msgs import ros
from mjnav.runtime import Service
from mjnav.runtime.runner import ServiceRunner

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers

STEPS: list[float] = []
ACTIVATIONS: list[int] = []
STEPPED = threading.Condition()


@dataclass(frozen=True)
class CountingConfig:
    rate_hz: float = 10.0


class Counting(Service[CountingConfig]):
    name = "counting"
    config_class = CountingConfig

    def activate(self) -> None:
        ACTIVATIONS.append(len(STEPS))

    def step(self, now: float) -> None:
        with STEPPED:
            STEPS.append(now)
            STEPPED.notify_all()


def _wait_steps(n: int) -> bool:
    with STEPPED:
        return STEPPED.wait_for(lambda: len(STEPS) >= n, timeout=5.0)


@contextmanager
def _stepping(
    service: type[Counting], peer: Callable[..., Bus], router_endpoint: str
) -> Iterator[tuple[ServiceRunner, Publisher]]:
    """``service`` run by a ServiceRunner in a thread, and a peer's clock publisher it has subscribed to; the
    runner is stopped (and its thread gone) afterwards."""
    STEPS.clear()
    ACTIVATIONS.clear()
    runner = ServiceRunner(service, CountingConfig(), BusConfig(connect=(router_endpoint,)), "robot0")
    thread = threading.Thread(target=runner.run)
    thread.start()
    try:
        sim = peer()
        clock = sim.publisher("clock")
        assert clock.wait_for_subscribers(5.0)
        assert wait_until(lambda: sim.alive_services() == [service.name], 5.0)
        yield runner, clock
    finally:
        runner.stop_event.set()
        thread.join(10.0)
    assert not thread.is_alive()


def test_steps_follow_sim_time_and_count_overruns(peer: Callable[..., Bus], router_endpoint: str) -> None:
    with _stepping(Counting, peer, router_endpoint) as (runner, clock):
        ticks = [round(0.1 * i, 10) for i in range(11)]
        for i, t in enumerate(ticks):
            clock.put(ros.clock(t))
            assert _wait_steps(i + 1), f"no step at sim time {t}"
            clock.put(ros.clock(t + 0.05))  # between ticks: no step due
        assert STEPS == ticks
        assert runner.stats.overruns == 0
        clock.put(ros.clock(1.55))  # the clock jumps: 1.1 … 1.5 are missed
        assert _wait_steps(12)
        assert STEPS[-1] == 1.55 and runner.stats.overruns == 4
        clock.put(ros.clock(1.65))
        assert _wait_steps(13) and STEPS[-1] == 1.65
        # The sim restarts: the clock goes back to 0. The service is re-activated and steps on the new timeline.
        clock.put(ros.clock(0.0))
        assert _wait_steps(14), "the loop froze after the clock went back"
        assert STEPS[-1] == 0.0 and ACTIVATIONS == [0, 13]
        clock.put(ros.clock(0.1))
        assert _wait_steps(15) and STEPS[-1] == 0.1


JUMP_AT = 0.3
RESTART: dict[str, object] = {}  # the test's clock publisher and the runner, for the service below


class RestartedWhileStepping(Counting):
    """At sim time JUMP_AT its step sends the sim's restart (clock 0) and returns only once the runner's clock has
    counted it: the jump lands between two waits of the loop, the moment that froze it."""

    name = "restarted"

    def step(self, now: float) -> None:
        if now == JUMP_AT and not ACTIVATIONS[1:]:
            RESTART["clock"].put(ros.clock(0.0))  # type: ignore[attr-defined]
            runner = RESTART["runner"]
            assert wait_until(lambda: runner.clock.jumps_back == 1, 5.0)  # type: ignore[attr-defined]
        super().step(now)


def test_a_restart_that_arrives_while_a_step_runs_is_not_missed(peer: Callable[..., Bus], router_endpoint: str) -> None:
    with _stepping(RestartedWhileStepping, peer, router_endpoint) as (runner, clock):
        RESTART.update(clock=clock, runner=runner)
        for i, t in enumerate((0.0, 0.1, 0.2, JUMP_AT)):
            clock.put(ros.clock(t))
            assert _wait_steps(i + 1), f"no step at sim time {t}"
        # The step at 0.3 sent clock 0: the service is re-activated and steps at 0 on the new timeline.
        assert _wait_steps(5), "the loop missed the restart that came while it stepped"
        assert STEPS == [0.0, 0.1, 0.2, JUMP_AT, 0.0] and ACTIVATIONS == [0, 4]

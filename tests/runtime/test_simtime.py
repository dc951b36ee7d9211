"""Time's one home (mjnav.runtime.simtime): schedules, pacing, staged delivery and the clock as participants read it."""

from __future__ import annotations

import math
import subprocess
import sys
import threading
from collections.abc import Callable

import pytest

from mjnav.bus import Bus, wait_until
from mjnav.geometry import Pose2D
from mjnav.msgs import ros
from mjnav.runtime.simtime import MAX_CLOCK_JUMP_S, Pacer, Schedule, SimClock, SimTimeGate
from tests.conftest import REPO

Peer = Callable[..., Bus]


# ---------------------------------------------------------------------------------------------------- Schedule


def test_a_schedule_is_due_on_its_grid_and_skips_what_it_missed() -> None:
    s = Schedule.every(20.0, origin_s=0.01)
    assert not s.due(0.0) and s.next_s == pytest.approx(0.01)
    assert s.due(0.01) and not s.due(0.01) and s.next_s == pytest.approx(0.06)
    assert not s.due(0.059)
    assert s.missed(0.21) == 3  # 0.06, 0.11, 0.16 passed without a call; 0.21 is reached
    assert s.due(0.21) and s.next_s == pytest.approx(0.26)  # missed ones are skipped, not made up
    s.reset(5.0)
    assert not s.due(4.99) and s.due(5.0)


def test_a_schedule_does_not_drift() -> None:
    """Due times come from the count: after a million periods of 0.1 s (not exact in binary) it is still on the
    grid, where summing the period would have drifted."""
    s = Schedule(0.1)
    calls = sum(s.due(k * 0.1) for k in range(1_000_000))
    assert calls == 1_000_000
    assert s.next_s == pytest.approx(100_000.0, abs=1e-6)


@pytest.mark.parametrize("period", [0.0, -1.0, math.nan, math.inf])
def test_a_schedule_refuses_a_period_that_is_not_a_positive_number(period: float) -> None:
    with pytest.raises(ValueError, match="positive"):
        Schedule(period)


# ------------------------------------------------------------------------------------------------------- Pacer


class FakeWall:
    """A wall clock the test moves."""

    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_the_pacer_allows_rtf_times_wall_time_ahead_of_its_start() -> None:
    wall = FakeWall()
    p = Pacer(4.0, lead_s=0.05, clock=wall)
    p.reset(2.0)
    assert p.allowed(2.0) == pytest.approx(2.05)  # the next tick at once
    wall.t += 0.5
    assert p.allowed(3.9) == pytest.approx(4.05)  # 0.15 s behind the line: within the slack (0.1 wall s)
    assert p.wait_s(5.05) == pytest.approx(0.25)  # 1 s of sim time more at 4x


def test_without_catch_up_a_stalled_sim_starts_the_line_again_and_with_it_sprints() -> None:
    wall = FakeWall()
    lockstep, free = Pacer(1.0, slack_s=0.1, clock=wall), Pacer(1.0, catch_up=True, clock=wall)
    lockstep.reset(0.0)
    free.reset(0.0)
    wall.t += 3.0  # a 3 s stall with the sim at 0
    assert lockstep.allowed(0.0) == pytest.approx(0.0)  # no sprint: real time from here
    assert free.allowed(0.0) == pytest.approx(3.0)  # like hardware: sim time follows the wall clock
    wall.t += 0.05  # within the slack, behind is not a stall
    assert lockstep.allowed(0.0) == pytest.approx(0.05)


def test_an_unbounded_pacer_allows_everything() -> None:
    for rtf in (None, 0.0):
        p = Pacer(rtf)
        assert p.rtf is None and p.allowed(1.0) == math.inf and p.wait_s(1e9) == 0.0
    with pytest.raises(ValueError, match="rtf"):
        Pacer(-1.0)


def test_the_schedule_and_the_pacer_import_without_the_transport() -> None:
    """mjnav.sim steps with them; importing the simulator must not pull Zenoh in (the sim is a layer below the
    bus)."""
    code = "import sys, mjnav.sim, mjnav.runtime.simtime as t; t.Schedule, t.Pacer; print('zenoh' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# ------------------------------------------------------------------------------------------------ SimTimeGate


def test_the_gate_delivers_a_message_only_at_a_clock_after_it_was_sent(peer: Peer) -> None:
    """A peer's output of its step at t reaches a subscriber before that subscriber's copy of clock t, sometimes
    (the router forwards the clock to each subscriber in turn): it must not be seen by the step at t."""
    a, b = peer(), peer()
    gate = SimTimeGate(b)
    twist = b.subscribe("cmd_vel")
    marker = b.subscribe("goal", immediate=True)  # sent after each twist on the same link: the twist is in
    pub, mark = a.publisher("cmd_vel"), a.publisher("goal")
    assert pub.wait_for_subscribers(5.0) and mark.wait_for_subscribers(5.0)

    def send(v: float, sim_time: float | None) -> None:
        a.sim_time = sim_time
        count = marker.count
        pub.put(ros.twist(v, 0.0))
        mark.put(ros.pose_stamped(0.0, "map", Pose2D(0.0, 0.0, 0.0)))
        assert wait_until(lambda: marker.count > count, 5.0)

    send(0.3, 1.0)  # sent by a peer stepping at t = 1.0
    gate.commit(1.0)
    assert twist.take() is None  # not for the step at 1.0 ...
    gate.commit(1.05)
    assert twist.take().linear.x == 0.3  # ... but for the next one
    assert b.sim_time == 1.05
    send(0.4, None)  # no sim time (an operator's command): at the next clock
    gate.commit(1.1)
    assert twist.take().linear.x == 0.4
    send(0.5, 7.0)  # sent before the sim restarted (the clock went back): old, not early
    gate.commit(0.0)
    assert twist.take().linear.x == 0.5


def test_a_deferred_action_runs_at_the_next_commit_in_order_with_the_messages(peer: Peer) -> None:
    b = peer()
    gate = SimTimeGate(b)
    ran: list[float] = []
    b.defer(lambda: ran.append(b.sim_time))
    assert ran == []
    gate.commit(0.5)
    assert ran == [0.5]


# --------------------------------------------------------------------------------------------------- SimClock


@pytest.mark.e2e
def test_the_clock_drops_forged_jumps_counts_restarts_and_commits_its_gates(peer: Peer) -> None:
    sim, me = peer(), peer()
    gate = SimTimeGate(me)
    ticks: list[tuple[float, bool]] = []
    ticked = threading.Condition()

    def on_tick(t: float, restarted: bool) -> None:
        with ticked:
            ticks.append((t, restarted))
            ticked.notify_all()

    clock = SimClock(me, [gate], on_tick)
    pub = sim.publisher("clock")
    assert pub.wait_for_subscribers(5.0)

    def tick(t: float, n: int) -> None:
        pub.put(ros.clock(t))
        with ticked:
            assert ticked.wait_for(lambda: len(ticks) >= n, 5.0), f"no tick at {t}"

    tick(1.0, 1)
    tick(1.05, 2)
    assert math.isnan(SimClock(peer(), []).now())  # no clock yet
    pub.put(ros.clock(1.05 + MAX_CLOCK_JUMP_S + 1.0))  # forged: far ahead
    tick(1.1, 3)  # sent after it on the same link: the forged one has been seen (and dropped) by now
    assert clock.rejected_jumps == 1 and clock.now() == 1.1
    tick(0.0, 4)  # the sim restarted
    assert ticks == [(1.0, True), (1.05, False), (1.1, False), (0.0, True)]
    assert clock.jumps_back == 1 and me.sim_time == 0.0  # the gate was committed at every accepted clock

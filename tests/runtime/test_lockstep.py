"""The lockstep barrier on a real in-process bus: start, reports, departures, hung participants, newcomers."""

from __future__ import annotations

import logging
from collections.abc import Callable

import pytest

from mjnav.bus import Bus, wait_until
from mjnav.msgs import msg_class, ros
from mjnav.runtime.simtime import LockstepBarrier

Peer = Callable[..., Bus]
READY = msg_class("mjnav_msgs/msg/LockstepReady")
TICK = 0.01


class Participant:
    """A participant as a service's runner would be: a token and a report after each step."""

    def __init__(self, bus: Bus, name: str) -> None:
        self.bus, self.name = bus, name
        self.pub = bus.publisher("lockstep", service=name)
        self.token = bus.declare_lockstep(name)

    def report(self, done: float, ready_until: float) -> None:
        self.pub.put(READY(header=ros.header(done, ""), participant=self.name, ready_until=ros.time_msg(ready_until)))

    def leave(self) -> None:
        self.token.undeclare()


def test_time_starts_with_the_expected_and_waits_for_each_due_step(
    peer: Peer, caplog: pytest.LogCaptureFixture
) -> None:
    barrier = LockstepBarrier(peer(), ["a", "b"], timeout_s=30.0, log=logging.getLogger("test.lockstep"))
    assert not barrier.started()
    a = Participant(peer(), "a")
    assert wait_until(lambda: barrier.participants() == ["a"], 10.0) and not barrier.started()
    b = Participant(peer(), "b")
    assert wait_until(barrier.started, 10.0)
    barrier.published(0.0, TICK)
    assert barrier.blocking(0.0) == ["a", "b"]  # both step at t = 0 before time may pass it
    a.report(0.0, 0.05)
    b.report(0.0, 0.2)
    assert barrier.wait(0.0, 10.0)
    for t in (0.01, 0.02, 0.03, 0.04):
        assert barrier.blocking(t) == []  # nobody is due: the sim runs on
    assert barrier.blocking(0.05) == ["a"] and barrier.blocking(0.2) == ["a", "b"]
    assert not barrier.wait(0.05, 0.05)  # a has not stepped at 0.05 yet
    # A report stamped after the sim's newest clock (from before a sim restart) is ignored.
    barrier.published(0.05, TICK)
    a.report(7.0, 7.05)
    a.report(0.05, 0.1)
    assert barrier.wait(0.05, 10.0) and barrier.blocking(0.1) == ["a"]
    # a leaves (killed): it no longer holds time; it is gone from the participants.
    a.leave()
    assert wait_until(lambda: barrier.participants() == ["b"], 10.0)
    assert barrier.blocking(0.1) == [] and barrier.blocking(0.2) == ["b"]
    assert "a left" in caplog.text


@pytest.mark.e2e
def test_a_hung_participant_is_named_and_left_out_then_rejoins(peer: Peer, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    barrier = LockstepBarrier(peer(), ["c"], timeout_s=0.3, log=logging.getLogger("test.lockstep"))
    c = Participant(peer(), "c")
    assert wait_until(barrier.started, 10.0)
    barrier.published(0.0, TICK)
    assert barrier.wait(0.0, 5.0)  # c never reports: after 0.3 s of wall time the sim goes on without it
    assert "c has not finished its step due at 0.000 s" in caplog.text
    assert barrier.blocking(0.5) == []
    barrier.published(0.5, TICK)
    c.report(0.5, 0.6)  # it comes back
    assert wait_until(lambda: barrier.blocking(0.6) == ["c"], 10.0)
    assert "c reports again and rejoins" in caplog.text


def test_a_newcomer_joins_at_the_next_clock(peer: Peer) -> None:
    barrier = LockstepBarrier(peer(), [], timeout_s=30.0, log=logging.getLogger("test.lockstep"))
    assert barrier.started()  # nobody expected: time may start at once
    barrier.published(3.0, TICK)
    Participant(peer(), "late")
    assert wait_until(lambda: barrier.participants() == ["late"], 10.0)
    # It may not have received the clock of 3.0 (published before it subscribed): time may pass 3.0 without it,
    # not 3.01.
    assert barrier.blocking(3.0) == [] and barrier.blocking(3.01) == ["late"]


def test_the_sim_can_wait_for_the_participants_that_command_it_alone(peer: Peer) -> None:
    """Within a round the physics needs only the robot's commanders (the controller) to have stepped; the clock
    needs everybody. A wait among a few ignores the others, and counts into the barrier's waiting time."""
    barrier = LockstepBarrier(peer(), ["controller", "slam"], timeout_s=30.0, log=logging.getLogger("test.lockstep"))
    controller, slam = Participant(peer(), "controller"), Participant(peer(), "slam")
    assert wait_until(barrier.started, 10.0)
    barrier.published(0.0, TICK)
    controller.report(0.0, 0.05)
    assert barrier.wait(0.0, 10.0, among={"controller"})  # slam still steps at 0: the physics may go on
    assert barrier.blocking(0.0) == ["slam"] and barrier.blocking(0.0, among={"controller"}) == []
    assert not barrier.wait(0.0, 0.05)  # but not the clock
    assert barrier.wait(0.0, 10.0, among={"teleop"})  # a commander that is not a participant holds nothing
    slam.report(0.0, 0.05)
    assert barrier.wait(0.0, 10.0)
    assert barrier.waited_s >= 0.05

"""UpstreamWatch over a real bus: a watched service is stale once sim time is past its due step by the grace."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from mjnav.bus import Bus, wait_until
from mjnav.msgs import msg_class, ros
from mjnav.runtime.upstream import UpstreamWatch


def _report(t: float, name: str, due: float) -> object:
    return msg_class("mjnav_msgs/msg/LockstepReady")(
        header=ros.header(t, ""), participant=name, ready_until=ros.time_msg(due)
    )


def test_a_service_is_stale_past_its_due_step_and_an_old_timeline_says_nothing(peer: Callable[..., Bus]) -> None:
    watcher, world = peer(), peer()
    watch = UpstreamWatch(watcher, ["planner", "smoother"], grace_s=0.15)
    assert watch.stale(100.0) == []  # never heard from: not watched
    planner = world.publisher("lockstep", service="planner")
    assert planner.wait_for_subscribers(10.0)
    planner.put(_report(1.0, "planner", 1.2))
    sub = watch._subs["planner"]
    assert wait_until(lambda: sub.latest() is not None, 10.0)
    assert watch.stale(1.34) == []
    assert watch.stale(1.36) == [("planner", pytest.approx(1.2))]
    # The sim restarted: at 0.5 s of the new timeline the report from 1.0 s is another timeline's.
    assert watch.stale(0.5) == []
    with pytest.raises(ValueError, match="grace_s"):
        UpstreamWatch(watcher, ["planner"], grace_s=0.0)

"""A lossy observer (the viewer) can fall behind without holding publishers back; loop participants still get
every message.

Publishers are reliable and blocking: a subscriber that stops reading in Zenoh's thread makes the router wait for
it, and with it the publisher, until the router gives up and closes that subscriber's link (its liveliness token
vanishes). A lossy subscription's samples go into a ring buffer in Zenoh itself, so the router never waits.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from mjnav.bus import Bus
from mjnav.msgs import msg_class, ros

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers

#: Scans published while the observer reads nothing: 64 MB, far more than the socket and Zenoh buffers hold.
COUNT = 4000
BEAMS = 4000


def _scan(seq: int) -> object:
    scan = msg_class("sensor_msgs/msg/LaserScan")
    return scan(
        header=ros.header(float(seq), "laser"),
        angle_min=-np.pi,
        angle_max=np.pi,
        angle_increment=2 * np.pi / BEAMS,
        time_increment=0.0,
        scan_time=0.1,
        range_min=0.1,
        range_max=12.0,
        ranges=np.full(BEAMS, 2.0, dtype=np.float32),
        intensities=np.zeros(0, dtype=np.float32),
    )


def test_a_lossy_observer_that_never_reads_holds_no_publisher_back(peer: Callable[..., Bus]) -> None:
    publisher, participant, observer, watcher = peer(), peer(), peer(), peer()
    vanished: list[str] = []
    watcher.watch_alive(lambda service, alive: None if alive else vanished.append(service))
    observer.declare_alive("viz")
    seqs: list[int] = []
    loop_sub = participant.subscribe("scan", callback=lambda m: seqs.append(m.header.stamp.sec))
    viewer = observer.subscribe("scan", lossy=True)
    pub = publisher.publisher("scan")
    assert pub.wait_for_subscribers(10.0)
    for _ in range(100):  # until both subscriptions are routed: a first scan reached each
        pub.put(_scan(0))
        if loop_sub.wait(0.1) is not None and viewer.latest() is not None:
            break
    assert seqs and viewer.latest() is not None
    seqs.clear()
    # A marker after the scans, from the same publisher's session on a topic the observer reads normally: one
    # session's messages arrive in the order they were sent, so once it is in, every scan has reached the observer.
    marks = observer.subscribe("cmd_vel")
    mark = publisher.publisher("cmd_vel")
    assert mark.wait_for_subscribers(10.0)
    for _ in range(100):
        mark.put(ros.twist(0.0, 0.0))
        if marks.wait(0.1) is not None:
            break
    routed = viewer.count

    for seq in range(1, COUNT + 1):  # the observer reads nothing meanwhile
        pub.put(_scan(seq))
    mark.put(ros.twist(1.0, 0.0))

    assert loop_sub.wait(30.0, lambda m: m.header.stamp.sec == COUNT) is not None
    assert [s for s in seqs if s] == list(range(1, COUNT + 1))  # every scan, in order
    assert marks.wait(30.0, lambda m: m.linear.x == 1.0) is not None
    assert viewer.count == routed  # nothing decoded while nobody read
    newest = viewer.latest()
    assert newest is not None and newest.header.stamp.sec == COUNT  # it kept up by dropping, and has the newest
    assert viewer.count == routed + 1  # the read decoded that one scan, not the 4000 that went by
    assert "viz" not in vanished  # its link was never closed for falling behind

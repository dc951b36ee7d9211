"""PoseInput: the navigation services' pose in ``map``, from SLAM through ``tf`` alone (as Nav2 looks it up)."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest

from mjnav.bus import Bus, Subscription, wait_until
from mjnav.geometry import Pose2D
from mjnav.msgs import ros
from mjnav.runtime.pose import PoseInput


def _send(me: Bus, reader: Bus, name: str, msgs: list[object]) -> None:
    """Publish ``msgs`` on ``name`` and wait until ``reader``'s subscription to it has them all."""
    sub = next(d for d in reader._declared if isinstance(d, Subscription) and d.key.endswith("/" + name))
    pub = me.publisher(name)
    assert pub.wait_for_subscribers(10.0)
    before = sub.count
    for msg in msgs:
        pub.put(msg)
    assert wait_until(lambda: sub.count >= before + len(msgs), 10.0)


def test_slam_source_composes_map_to_odom_with_odom_to_base_link_both_from_tf(peer: Callable[..., Bus]) -> None:
    reader, me = peer(), peer()
    pose_in = PoseInput(reader, "slam")
    odom_pose = Pose2D(1.0, 0.5, 0.3)
    correction = Pose2D(0.2, -0.1, 0.05)
    # odom -> base_link at 1.00 s and 1.05 s, then SLAM's map -> odom stamped 1.00 s
    _send(
        me,
        reader,
        "tf",
        [
            ros.tf_message(ros.transform_stamped(1.0, "odom", "base_link", Pose2D(0.9, 0.5, 0.3))),
            ros.tf_message(ros.transform_stamped(1.05, "odom", "base_link", odom_pose)),
            ros.tf_message(ros.transform_stamped(1.0, "map", "odom", correction)),
        ],
    )
    pose_in.update()
    latest = pose_in.latest()
    assert latest is not None
    stamp, pose = latest
    assert stamp == pytest.approx(1.0)  # the older of the two parts: a silent SLAM makes the pose stale
    expected = correction * odom_pose
    assert (pose.x, pose.y) == pytest.approx((expected.x, expected.y), abs=1e-9)
    assert math.isclose(pose.theta, expected.theta, abs_tol=1e-9)
    at = pose_in.at(1.025)  # halfway between the two odometry transforms
    assert at is not None
    assert at.x == pytest.approx((correction * Pose2D(0.95, 0.5, 0.3)).x, abs=1e-9)


@pytest.mark.e2e
def test_slam_source_needs_no_odom_topic_and_ignores_other_transforms(peer: Callable[..., Bus]) -> None:
    reader, me = peer(), peer()
    pose_in = PoseInput(reader, "slam")
    assert not any(isinstance(d, Subscription) and d.key.endswith("/odom") for d in reader._declared)
    _send(
        me,
        reader,
        "tf",
        [
            ros.tf_message(
                ros.transform_stamped(2.0, "base_link", "laser", Pose2D(0.1, 0.0, 0.0)),
                ros.transform_stamped(2.0, "map", "odom", Pose2D()),
            )
        ],
    )
    pose_in.update()
    assert pose_in.latest() is None  # no odom -> base_link yet: no pose, whatever else tf carries
    assert pose_in.map_to_odom is not None and pose_in.map_to_odom[0] == pytest.approx(2.0)

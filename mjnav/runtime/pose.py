"""The robot's pose in ``map`` as the navigation services read it, from one configured source.

``slam`` composes SLAM's newest ``map → odom`` with the sim's wheel odometry ``odom → base_link``, both read from
``tf``, the way Nav2 looks up ``map → base_link`` through TF: the pose is as fresh as the odometry, not one SLAM
step late, and a scan is placed at the odometry of its own stamp. (The ``odom`` topic carries the same transform;
subscribing to both cost every navigation service 20 callbacks per sim second for nothing.) ``ground_truth`` and
``odom`` read that topic as it is.

Subscription callbacks run in Zenoh's threads and only append; :meth:`PoseInput.update` (called at the start of a
service's step) moves what arrived into the histories, so a step sees one consistent state.
"""

from __future__ import annotations

from collections import deque
from typing import Any, Literal

from mjnav.bus import Bus
from mjnav.geometry import Pose2D, PoseHistory
from mjnav.msgs import ros

#: The pose sources a navigation service can be configured with.
PoseSource = Literal["slam", "ground_truth", "odom"]
POSE_SOURCES: tuple[str, ...] = ("slam", "ground_truth", "odom")


class PoseInput:
    """Stamped robot poses in ``map`` from ``source``, with a short history for stamp lookups.

    Args:
        bus: the service's bus (the subscriptions are made here).
        source: ``slam`` (``map → odom`` ∘ ``odom → base_link``, both on ``tf``), ``ground_truth`` or ``odom``.
        horizon_s: how much history to keep, seconds.
    """

    def __init__(self, bus: Bus, source: str, horizon_s: float = 2.0) -> None:
        if source not in POSE_SOURCES:
            raise ValueError(f"pose source must be one of {list(POSE_SOURCES)}, got {source!r}")
        self.source = source
        self._where = (
            f"map -> odom from slam and odom -> base_link on {bus.key('tf')}"
            if source == "slam"
            else f"{ros.POSE_TOPICS[source]} on {bus.key(ros.POSE_TOPICS[source])}"
        )
        self._pending: deque[tuple[float, Pose2D]] = deque(maxlen=1000)
        self._pending_tf: deque[tuple[float, Pose2D]] = deque(maxlen=100)
        self._horizon_s = horizon_s
        self.reset()
        if source == "slam":
            bus.subscribe("tf", callback=self._on_tf)
        else:
            bus.subscribe(ros.POSE_TOPICS[source], callback=self._on_pose)

    def describe(self) -> str:
        """Where the pose comes from, for a status that says it is missing."""
        return self._where

    def reset(self) -> None:
        """Forget every pose (the sim clock restarted)."""
        self.poses = PoseHistory(self._horizon_s)
        self.map_to_odom: tuple[float, Pose2D] | None = None
        self._pending.clear()
        self._pending_tf.clear()

    def _on_pose(self, msg: Any) -> None:
        self._pending.append((ros.seconds(msg.header.stamp), ros.pose_of(msg)))

    def _on_tf(self, msg: Any) -> None:
        for t in msg.transforms:
            if t.header.frame_id == "map" and t.child_frame_id == "odom":
                self._pending_tf.append((ros.seconds(t.header.stamp), ros.transform2d(t.transform)))
            elif t.header.frame_id == "odom" and t.child_frame_id == "base_link":
                self._pending.append((ros.seconds(t.header.stamp), ros.transform2d(t.transform)))

    def update(self) -> None:
        """Take in what arrived since the last call."""
        while self._pending:
            self.poses.add(*self._pending.popleft())
        while self._pending_tf:
            stamp, pose = self._pending_tf.popleft()
            if self.map_to_odom is None or stamp >= self.map_to_odom[0]:
                self.map_to_odom = (stamp, pose)

    def latest(self) -> tuple[float, Pose2D] | None:
        """The newest (stamp, pose in map), or None before the first one.

        From ``slam`` the stamp is the older of the odometry's and ``map → odom``'s, so a silent SLAM makes the
        pose stale (and the services that check its age stop) although odometry keeps coming.
        """
        newest = self.poses.latest()
        if newest is None:
            return None
        stamp, pose = newest
        if self.source != "slam":
            return newest
        if self.map_to_odom is None:
            return None
        return min(stamp, self.map_to_odom[0]), self.map_to_odom[1] * pose

    def at(self, t_s: float, max_extrapolation_s: float = 0.05) -> Pose2D | None:
        """The pose in map at ``t_s`` (interpolated; see :meth:`PoseHistory.at`), or None.

        From ``slam`` it is the newest ``map → odom`` (SLAM's best correction) ∘ the odometry at ``t_s``.
        """
        pose = self.poses.at(t_s, max_extrapolation_s)
        if pose is None or self.source != "slam":
            return pose
        return None if self.map_to_odom is None else self.map_to_odom[1] * pose

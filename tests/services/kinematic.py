"""Test fixture service: an ideal unicycle that integrates ``cmd_vel`` and publishes ``odom`` on wall time.

Small enough to reason about, real enough to exercise the runtime end to end: subscription, validation,
step loop, publication, status, liveliness, restarts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mjnav.geometry import Pose2D, wrap_angle
from mjnav.msgs import ros
from mjnav.runtime import Service


@dataclass(frozen=True)
class KinematicConfig:
    rate_hz: float = 50.0
    max_speed_mps: float = 1.0
    fail_in_configure: bool = False  # a valid setting that makes every start crash (the launcher's give-up test)

    def __post_init__(self) -> None:
        if not self.max_speed_mps > 0:
            raise ValueError("max_speed_mps must be > 0")


class KinematicRobot(Service[KinematicConfig]):
    name = "kinematic"
    config_class = KinematicConfig
    uses_sim_time = False
    runtime_settable = frozenset({"max_speed_mps"})  # read at every step

    def configure(self) -> None:
        if self.config.fail_in_configure:
            raise RuntimeError("configured to fail")
        self.cmd = self.bus.subscribe("cmd_vel")
        self.odom = self.bus.publisher("odom")
        self.pose = Pose2D()
        self.last = math.nan

    def step(self, now: float) -> None:
        dt = 0.0 if math.isnan(self.last) else now - self.last
        self.last = now
        cmd = self.cmd.latest()
        v = 0.0 if cmd is None else max(-self.config.max_speed_mps, min(self.config.max_speed_mps, cmd.linear.x))
        w = 0.0 if cmd is None else cmd.angular.z
        p = self.pose
        self.pose = Pose2D(
            p.x + v * dt * math.cos(p.theta), p.y + v * dt * math.sin(p.theta), wrap_angle(p.theta + w * dt)
        )
        self.odom.put(ros.odometry(now, self.pose, v, w))

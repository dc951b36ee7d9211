"""A robot edited in its MJCF alone — a chassis 5 cm wider in radius, the lidar moved 5 cm forward — is the robot
every service drives: the costmap's inscribed band, the controller's collision check and SLAM's sensor frame follow
the description the sim publishes, with no config edited. (The services run on a real bus; the last test drives
the whole stack on the edited robot.)"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from mjnav.bus import Bus
from mjnav.geometry import Pose2D
from mjnav.msgs import msg_class, ros
from mjnav.robot import parse_robot_description
from mjnav.services.controller import ControllerService
from mjnav.services.mapper import MapperService
from mjnav.services.slam import SlamService
from tests.conftest import REPO, free_port
from tests.estimation._scans import raycast
from tests.services.harness import DIFFBOT, Harness

Peer = Callable[..., Bus]
STATUS = msg_class("mjnav_msgs/msg/GoalStatus")
#: The edit: chassis radius 0.18 -> 0.24 m (the footprint radius 0.19 -> 0.24, past the wheels), lidar 5 cm forward.
EDITED = DIFFBOT.replace('size="0.18 0.045"', 'size="0.24 0.045"').replace(
    '<site name="laser" pos="0 0 0.2"', '<site name="laser" pos="0.05 0 0.2"'
)
#: A 6 m x 4 m room, (x0, y0, x1, y1) wall segments.
ROOM = np.array([(-3, -2, 3, -2), (3, -2, 3, 2), (3, 2, -3, 2), (-3, 2, -3, -2)], dtype=float)


def test_the_edit_is_what_the_description_says() -> None:
    stock, edited = parse_robot_description(DIFFBOT), parse_robot_description(EDITED)
    assert (stock.radius_m, edited.radius_m) == (pytest.approx(0.19), pytest.approx(0.24))
    assert stock.frame("laser").xyz_m == (0.0, 0.0, 0.2) and edited.frame("laser").xyz_m == (0.05, 0.0, 0.2)


def _scan(t: float, base: Pose2D, laser_x: float) -> object:
    """The scan of the room from a lidar ``laser_x`` ahead of ``base`` (stamped ``t``, frame ``laser``)."""
    sensor = base * Pose2D(laser_x, 0.0, 0.0)
    angles, ranges = raycast(ROOM, (sensor.x, sensor.y, sensor.theta), 360, 2 * math.pi, 12.0)
    return ros.laser_scan(
        t, "laser", angle_min_rad=float(angles[0]), angle_increment_rad=float(angles[1] - angles[0]),
        scan_time_s=0.1, range_min_m=0.05, range_max_m=12.0, ranges_m=ranges,
    )  # fmt: skip


def _inscribed_width(peer: Peer, robot: str) -> float:
    """How far from the west wall (x = -3) the costmap's inscribed band (cost >= 99) reaches, metres, after the
    mapper has seen the room a few times (the lidar at its place on ``robot``)."""
    laser_x = parse_robot_description(robot).frame("laser").xyz_m[0]
    h = Harness(MapperService, peer, ("costmap",), robot=robot, pose_source="ground_truth", checkpoint_period_s=0.0)
    base = Pose2D(-1.0, 0.0, 0.0)
    for k in range(8):
        t = 0.1 * k
        h.send("ground_truth", ros.pose_stamped(t, "map", base))
        h.send("scan", _scan(t, base, laser_x))
        h.step(t)
    costmap = h.service.costmap()
    h.close()
    frame = h.service.frame
    xs = np.arange(-2.975, -2.0, 0.05)  # cell centres east of the wall, along y = 0.025
    cost = frame.values_at(costmap, np.column_stack((xs, np.full_like(xs, 0.025))), outside=-1)
    inside = xs[cost >= 99]
    return float(inside.max() + 0.025 - (-3.0))


@pytest.mark.e2e
def test_the_costmaps_inscribed_band_is_the_robots_radius(peer: Peer) -> None:
    stock, edited = _inscribed_width(peer, DIFFBOT), _inscribed_width(peer, EDITED)
    assert stock == pytest.approx(0.2, abs=0.05)  # 0.19 m, to the 5 cm cell
    assert edited == pytest.approx(0.25, abs=0.05)  # 0.24 m
    assert edited - stock == pytest.approx(0.05, abs=1e-9)


def _speed_facing_a_wall(peer: Peer, robot: str) -> float:
    """The controller's command with the robot 0.25 m from a wall, driving a path straight at it."""
    h = Harness(ControllerService, peer, ("cmd_vel",), robot=robot, pose_source="ground_truth")
    base = Pose2D(2.75, 0.0, 0.0)  # the east wall at x = 3
    line = np.c_[np.linspace(2.75, 5.0, 30), np.zeros(30)]
    goal = ros.pose_stamped(0.0, "map", Pose2D(5.0, 0.0, 0.0))
    following = STATUS(
        header=ros.header(0.0, "map"), goal_id=1, state=STATUS.STATE_FOLLOWING, error_code=0, error_text="", goal=goal
    )
    h.send("goal_status", following)
    h.send("path", ros.path_msg(0.0, "map", line))
    for k in range(3):
        t = 0.1 * k
        h.send("ground_truth", ros.pose_stamped(t, "map", base))
        h.send("scan", _scan(t, base, 0.0))
        h.step(t, {"cmd_vel": k + 1})
    speed = float(h.received["cmd_vel"][-1].linear.x)
    h.close()
    return speed


@pytest.mark.e2e
def test_the_controllers_collision_check_keeps_the_robots_radius(peer: Peer) -> None:
    """0.25 m from the wall the stock robot (0.19 m + 0.02 m margin) may still creep on; the edited one (0.24 m)
    is already inside its margin and must not move towards the wall."""
    assert _speed_facing_a_wall(peer, DIFFBOT) > 0.0
    assert _speed_facing_a_wall(peer, EDITED) <= 0.0


def _slam_error(peer: Peer, robot: str, laser_x: float) -> float:
    """SLAM (described ``robot``) on scans taken from a lidar ``laser_x`` ahead of the base while the robot turns
    a quarter turn on the spot: the largest distance of its pose from the truth, metres."""
    h = Harness(SlamService, peer, ("pose",), robot=robot, use_gyro=False, initial_pose=(0.5, 0.3, 0.0))
    worst = 0.0
    for k in range(16):
        t = 0.1 * k
        yaw = min(k, 15) * (math.pi / 2) / 15
        truth = Pose2D(0.5, 0.3, yaw)
        h.send("odom", ros.odometry(t, Pose2D(0.0, 0.0, yaw), 0.0, 0.0))
        h.send("scan", _scan(t, truth, laser_x))
        h.step(t, {"pose": k + 1})
        est = ros.pose_of(h.received["pose"][-1])
        worst = max(worst, math.hypot(est.x - truth.x, est.y - truth.y))
    h.close()
    return worst


@pytest.mark.e2e
def test_slam_places_the_scans_at_the_lidar_the_description_names(peer: Peer) -> None:
    assert _slam_error(peer, EDITED, 0.05) < 0.01  # the lidar where the robot says it is
    assert _slam_error(peer, DIFFBOT, 0.05) > 0.02  # the same scans read as if from the base: the pose drifts


@pytest.mark.e2e
def test_the_whole_stack_drives_the_edited_robot(tmp_path: Path) -> None:
    """`mjnav demo` on the rooms world with the edited robot file: reached, no collision, the clearance measured
    with the new footprint, and SLAM's error as small as on the stock robot."""
    worlds = tmp_path / "mjcf"
    shutil.copytree(REPO / "mjcf", worlds)
    (worlds / "diffbot.xml").write_text(EDITED, encoding="utf-8")
    env = {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_ZENOH_")}
    proc = subprocess.run(
        [sys.executable, "-m", "mjnav", "demo", "--world", str(worlds / "rooms.xml"), "--rtf", "max", "--json",
         "--headless", "--seed", "1", "--port", str(free_port())],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert summary["reached"] and summary["collisions"] == 0, summary
    assert summary["min_clearance_m"] > 0.0 and summary["ate_rms_m"] < 0.02, summary


@pytest.mark.e2e
def test_slam_uses_no_scan_of_a_frame_the_robot_lacks(peer: Peer) -> None:
    """A scan stamped in a frame the description has not (another robot's lidar) is not placed anywhere: SLAM does
    not start on it, and its status says it has no scan to use."""
    h = Harness(SlamService, peer, ("pose",), use_gyro=False, initial_pose=(0.5, 0.3, 0.0))
    for k in range(60):
        t = 0.1 * k
        h.send("odom", ros.odometry(t, Pose2D(0.0, 0.0, 0.0), 0.0, 0.0))
        scan = _scan(t, Pose2D(0.5, 0.3, 0.0), 0.0)
        scan.header.frame_id = "front_laser"  # type: ignore[attr-defined]
        h.send("scan", scan)
        h.step(t)
    assert h.received["pose"] == [] and h.service.slam is None
    assert h.service.starved() == "scans on robot0/scan (none used for 5 s)"
    h.close()

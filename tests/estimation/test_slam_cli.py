"""``mjnav slam`` on a CARMEN slice (refdata) and on a synthetic bag: outputs readable and consistent."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from mjnav.cli import main
from mjnav.estimation import read_g2o
from mjnav.mapping import read_ros_map
from tests.conftest import refdata_dir
from tests.estimation._slam_world import ring_drive, scans


def _intel() -> Path:
    root = refdata_dir()
    path = None if root is None else root / "laser2d_carmen" / "intel-corrected.log.gz"
    if path is None or not path.is_file():
        pytest.skip("refdata laser2d_carmen/intel-corrected.log.gz is absent")
    return path


def _check_outputs(out: Path, scans_expected: int) -> dict:
    traj = np.loadtxt(out / "trajectory.txt", ndmin=2)
    assert traj.shape == (scans_expected, 4)
    assert np.all(np.isfinite(traj)) and np.all(np.abs(traj[:, 3]) <= math.pi)
    graph = read_g2o(out / "graph.g2o")
    summary = json.loads((out / "summary.json").read_text())
    assert graph.num_vertices == summary["keyframes"]
    assert graph.num_edges == summary["keyframes"] - 1 + summary["loop_closures"]
    ros_map = read_ros_map(out / "map.yaml")
    assert ros_map.resolution_m == pytest.approx(0.05)
    assert (ros_map.occupancy == 100).sum() > 50 and (ros_map.occupancy == 0).sum() > 500
    # Each keyframe vertex is the trajectory pose of its scan (a keyframe's pose is that scan's pose).
    dist = np.linalg.norm(traj[:, None, 1:3] - graph.poses[None, :, :2], axis=2)  # (scans, keyframes)
    assert dist.min(axis=0).max() < 1e-6
    return summary


@pytest.mark.e2e
def test_carmen_slice(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "intel"
    assert main(["slam", "--carmen", str(_intel()), "--limit", "120", "--seed", "1", "--quiet", "--out", str(out)]) == 0
    summary = _check_outputs(out, 120)
    assert summary["odom_noise"] == [0.05, 0.05, 0.02] and summary["seed"] == 1
    # The summary records the settings the SLAM ran with (here --max-range's default).
    assert summary["slam_config"]["max_range_m"] == 30.0 and summary["slam_config"]["map_resolution_m"] == 0.05
    rpe = summary["rpe_consecutive"]
    assert rpe["relations"] == 119
    # SLAM beats the noisy odometry it was given, on both parts of the error.
    assert rpe["trans_mean_m"] < rpe["odometry_trans_mean_m"]
    assert rpe["rot_mean_deg"] < rpe["odometry_rot_mean_deg"]
    assert "error consecutive:" in capsys.readouterr().out


@pytest.mark.e2e
def test_bag(tmp_path: Path) -> None:
    from mjnav.bag import BagWriter
    from mjnav.geometry import Pose2D
    from mjnav.msgs import encode, ros

    truth = ring_drive(0.25)
    rng = np.random.default_rng(0)
    angles, ranges = scans(truth, rng)
    bag = tmp_path / "run.mcap"
    with BagWriter(bag) as w:
        for k, p in enumerate(truth):
            t = 1.0 + 0.1 * k
            odom = ros.odometry(t, Pose2D(float(p[0]) - 9.0, float(p[1]) - 2.0, float(p[2])), 1.0, 0.0)
            w.add("robot0/odom", encode(odom, "nav_msgs/msg/Odometry"), log_time_ns=int(t * 1e9))
            scan = ros.laser_scan(
                t,
                "laser",
                angle_min_rad=float(angles[0]),
                angle_increment_rad=float(angles[1] - angles[0]),
                scan_time_s=0.1,
                range_min_m=0.1,
                range_max_m=12.0,
                ranges_m=ranges[k],
            )
            w.add("robot0/scan", encode(scan, "sensor_msgs/msg/LaserScan"), log_time_ns=int(t * 1e9) + 1)
    out = tmp_path / "out"
    assert main(["slam", "--bag", str(bag), "--quiet", "--out", str(out)]) == 0
    summary = _check_outputs(out, truth.shape[0])
    assert summary["namespace"] == "robot0"
    traj = np.loadtxt(out / "trajectory.txt")
    assert traj[0, 0] == pytest.approx(1.0)
    # The map frame is the odom frame at the start; odometry here is exact, so SLAM stays on it.
    assert np.allclose(traj[-1, 1:3], truth[-1, :2] - (9.0, 2.0), atol=0.05)


@pytest.mark.parametrize(
    "argv",
    [
        ["slam", "--carmen", "/nonexistent.log", "--out", "x"],
        ["slam", "--bag", "/nonexistent.mcap", "--out", "x"],
        ["slam", "--bag", "/nonexistent.mcap", "--seed", "3", "--out", "x"],
    ],
)
def test_bad_input_exits_2(argv: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = [a if a != "x" else str(tmp_path / "out") for a in argv]
    assert main(argv) == 2
    assert "mjnav slam: error:" in capsys.readouterr().err


def test_odom_noise_argument_is_checked() -> None:
    with pytest.raises(SystemExit):
        main(["slam", "--carmen", "x.log", "--odom-noise", "0.1,0.1", "--out", "y"])

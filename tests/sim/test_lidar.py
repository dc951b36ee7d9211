"""Lidar: ranges equal analytic wall distances within noise; REP-117 limits; self-exclusion; schedule."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mjnav.geometry import Pose2D
from mjnav.sim import LidarConfig, SimError, Simulator

from .helpers import box_room_xml, write

HALF_X, HALF_Y = 2.0, 1.5


def _analytic_ranges(origin_xy: np.ndarray, heading: float, angles: np.ndarray) -> np.ndarray:
    """Distance from origin to the inside of the rectangle |x| <= HALF_X, |y| <= HALF_Y along each beam."""
    a = heading + angles
    dx, dy = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore"):
        tx = np.where(dx > 0, (HALF_X - origin_xy[0]) / dx, np.where(dx < 0, (-HALF_X - origin_xy[0]) / dx, np.inf))
        ty = np.where(dy > 0, (HALF_Y - origin_xy[1]) / dy, np.where(dy < 0, (-HALF_Y - origin_xy[1]) / dy, np.inf))
    return np.minimum(tx, ty)


def _room_sim(tmp_path: Path, lidar: LidarConfig, start: tuple[float, float, float]) -> Simulator:
    path = write(tmp_path, "room.xml", box_room_xml(HALF_X, HALF_Y, start=start))
    return Simulator(path, seed=11, lidar=lidar)


def _lidar_origin(sim: Simulator) -> np.ndarray:
    return np.array(sim.data.site_xpos[sim.robot.lidar_site][:2])


def test_noise_free_ranges_equal_the_analytic_distances(tmp_path: Path) -> None:
    sim = _room_sim(tmp_path, LidarConfig(noise_std_m=0.0), start=(0.3, -0.2, 0.4))
    sim.step_until(0.5)  # settle on the casters
    scan = sim.lidar_scan()
    expected = _analytic_ranges(_lidar_origin(sim), sim.ground_truth_pose().theta, scan.angles_rad)
    # the chassis tilts < 0.5° on its caster: a horizontal beam is longer by at most 1/cos - 1 ≈ 4e-5
    assert np.max(np.abs(scan.ranges_m - expected)) < 2e-3


def test_noisy_ranges_are_unbiased_with_the_configured_sigma(tmp_path: Path) -> None:
    sigma = 0.02
    sim = _room_sim(tmp_path, LidarConfig(noise_std_m=sigma), start=(-0.5, 0.4, -1.0))
    sim.step_until(0.5)
    errors = []
    for _ in range(10):
        scan = sim.lidar_scan()
        expected = _analytic_ranges(_lidar_origin(sim), sim.ground_truth_pose().theta, scan.angles_rad)
        errors.append(scan.ranges_m - expected)
    err = np.concatenate(errors)
    assert np.all(np.abs(err) < 5 * sigma)
    assert abs(err.mean()) < 3 * sigma / math.sqrt(err.size) + 5e-4
    assert err.std() == pytest.approx(sigma, rel=0.1)


def test_rep117_out_of_range_is_plus_inf_and_too_close_is_minus_inf(tmp_path: Path) -> None:
    # robot near the east wall: ~0.6 m ahead, ≥ 1.5 m elsewhere
    lidar = LidarConfig(noise_std_m=0.0, range_min_m=1.0, range_max_m=3.0, num_beams=180)
    sim = _room_sim(tmp_path, lidar, start=(1.4, 0.0, 0.0))
    scan = sim.lidar_scan()
    expected = _analytic_ranges(_lidar_origin(sim), sim.ground_truth_pose().theta, scan.angles_rad)
    assert np.all(scan.ranges_m[expected < 0.99] == -np.inf)
    assert np.all(scan.ranges_m[expected > 3.01] == np.inf)
    inside = (expected > 1.01) & (expected < 2.99)
    assert inside.any()
    assert np.allclose(scan.ranges_m[inside], expected[inside], atol=2e-3)


def test_the_robot_never_sees_itself_and_open_space_is_inf() -> None:
    sim = Simulator("empty", seed=0, lidar=LidarConfig(range_min_m=0.0))
    scan = sim.pop_scan()
    assert scan is not None
    assert np.all(scan.ranges_m == np.inf)
    assert scan.points().shape == (0, 2)


def test_scans_follow_the_configured_rate() -> None:
    sim = Simulator("rooms", seed=0, lidar=LidarConfig(rate_hz=20.0, num_beams=90))
    stamps = []
    while sim.time_s < 1.0 - 1e-9:
        scan = sim.pop_scan()
        if scan is not None:
            stamps.append(scan.stamp_s)
            assert scan.ranges_m.shape == (90,)
        assert sim.pop_scan() is None  # popped once only
        sim.step(3)
    assert stamps[0] == 0.0
    assert np.allclose(np.diff(stamps), 0.05)
    assert len(stamps) == 20


def test_rooms_scan_sees_walls_and_the_cart_moves_in_warehouse_scans() -> None:
    sim = Simulator("rooms", seed=0)
    scan = sim.pop_scan()
    assert scan is not None and np.isfinite(scan.ranges_m).all()  # closed rooms: every beam hits
    wh = Simulator("warehouse", seed=0, start=Pose2D(-1.0, 0.0, 0.0))
    # the cart moves along x = 0; the beam straight ahead (angle 0) sees it only when it crosses y = 0
    ahead = int(np.argmin(np.abs(LidarConfig().angles())))
    ranges = []
    for t in (0.5, 6.0):
        wh.step_until(t)
        ranges.append(wh.lidar_scan().ranges_m[ahead])
    assert ranges[0] > 5.0  # across the central aisle into the east block
    assert ranges[1] == pytest.approx(1.0 - 0.5, abs=0.1)  # the cart's west face at x = -0.5


def test_lidar_config_layout_and_validation() -> None:
    cfg = LidarConfig()
    angles = cfg.angles()
    assert angles.shape == (360,)
    assert angles[0] == pytest.approx(-math.pi)
    assert cfg.angle_increment_rad == pytest.approx(math.radians(1.0))
    assert cfg.angle_max_rad == pytest.approx(math.pi - math.radians(1.0))
    partial = LidarConfig(num_beams=5, fov_rad=math.pi)
    assert np.allclose(partial.angles(), np.linspace(-math.pi / 2, math.pi / 2, 5))
    for bad in (
        {"num_beams": 0},
        {"rate_hz": 0.0},
        {"range_min_m": 5.0, "range_max_m": 1.0},
        {"noise_std_m": -1},
    ):
        with pytest.raises(ValueError):
            LidarConfig(**bad)  # type: ignore[arg-type]
    sim = Simulator("empty", seed=0, lidar=None)
    assert sim.pop_scan() is None
    with pytest.raises(SimError):
        sim.lidar_scan()

"""CorrelativeGridMatcher: branch and bound equals brute force; loop-closure search over a large window."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.estimation import CorrelativeGridMatcher, NoMatchError, ScanMatchError
from mjnav.estimation.scan_matching import likelihood_field
from mjnav.mapping import GridFrame, OccupancyGrid
from tests.estimation._scans import ROOM, raycast, relative, scan_points


def _room_grid(res: float) -> OccupancyGrid:
    grid = OccupancyGrid(int(11 / res), int(7 / res), res, (-0.5, -0.5))
    for pose in [(2.0, 1.5, 0.0), (5.0, 4.5, 1.0), (8.0, 3.0, 2.0), (3.5, 3.0, -1.0)]:
        a, r = raycast(ROOM, pose, 720)
        for _ in range(3):
            grid.integrate_scan(pose, a, r, 20.0)
    return grid


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_branch_and_bound_equals_brute_force_on_a_random_table(seed: int) -> None:
    rng = np.random.default_rng(seed)
    frame = GridFrame(0.1, (0.0, 0.0), (40, 50))
    values = rng.random((40, 50)) ** 4  # continuous values: ties have probability 0
    matcher = CorrelativeGridMatcher(values, frame, depth=4)
    scan = rng.uniform(-1.0, 1.0, (25, 2))
    init = (2.5, 2.0, 0.2)
    kw = {"linear_window_m": 0.9, "angular_window_rad": 0.3, "angular_step_rad": 0.05}
    bnb = matcher.match(scan, init, **kw)
    brute = matcher.match_brute_force(scan, init, **kw)
    assert bnb.score == brute.score
    assert np.array_equal(bnb.pose, brute.pose)


def test_branch_and_bound_equals_brute_force_on_an_occupancy_grid() -> None:
    grid = _room_grid(0.1)
    matcher = CorrelativeGridMatcher.from_occupancy_grid(grid, depth=3)
    truth = (4.0, 3.0, 0.4)
    scan = scan_points(ROOM, truth, n_beams=90)
    init = (4.25, 2.8, 0.4 + math.radians(6))
    kw = {"linear_window_m": 0.5, "angular_window_rad": math.radians(10)}
    bnb = matcher.match(scan, init, **kw)
    brute = matcher.match_brute_force(scan, init, **kw)
    assert bnb.score == pytest.approx(brute.score, abs=1e-12)
    assert np.allclose(bnb.pose, brute.pose)
    assert bnb.method == "bnb" and brute.method == "brute_force"
    assert bnb.iterations < brute.iterations / 5  # the bounds prune on a real map


@pytest.mark.parametrize("seed", [0, 1])
def test_branch_and_bound_equals_brute_force_with_a_prior(seed: int) -> None:
    rng = np.random.default_rng(seed)
    frame = GridFrame(0.1, (0.0, 0.0), (40, 50))
    matcher = CorrelativeGridMatcher(rng.random((40, 50)) ** 4, frame, depth=4)
    scan = rng.uniform(-1.0, 1.0, (25, 2))
    kw = {"linear_window_m": 0.9, "angular_window_rad": 0.3, "angular_step_rad": 0.05}
    prior = {"translation_cost": 0.3, "rotation_cost": 0.5}
    bnb = matcher.match(scan, (2.5, 2.0, 0.2), **kw, **prior)
    brute = matcher.match_brute_force(scan, (2.5, 2.0, 0.2), **kw, **prior)
    assert bnb.score == brute.score and np.array_equal(bnb.pose, brute.pose)
    plain = matcher.match(scan, (2.5, 2.0, 0.2), **kw)
    # The prior moves the answer towards the initial pose (or keeps it): never further.
    assert np.hypot(*(bnb.pose[:2] - (2.5, 2.0))) <= np.hypot(*(plain.pose[:2] - (2.5, 2.0))) + 1e-12
    with pytest.raises(ScanMatchError, match="translation_cost"):
        matcher.match(scan, (2.5, 2.0, 0.2), **kw, translation_cost=-1.0)


def test_a_prior_keeps_the_initial_pose_along_a_corridor() -> None:
    """Issue 30: seen side-on, two long walls score alike at every offset along them; without a prior the search
    took the first such offset, the window's edge (0.3 m off), scan after scan."""
    xs = np.arange(-12.0, 12.0, 0.02)
    walls = np.r_[np.c_[xs, np.full_like(xs, 1.5)], np.c_[xs, np.full_like(xs, -1.5)]]
    table, frame, scale = likelihood_field(walls, 0.05)
    matcher = CorrelativeGridMatcher(table, frame, depth=3, loglik_scale=scale)
    a = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    a = a[np.abs(np.sin(a)) > 0.13]  # returns within 12 m
    r = 1.5 / np.abs(np.sin(a))
    scan = np.c_[r * np.cos(a), r * np.sin(a)]
    kw = {"linear_window_m": 0.3, "angular_window_rad": math.radians(5), "angular_step_rad": math.radians(0.5)}
    assert abs(matcher.match(scan, (0.1, 0.0, 0.0), **kw).pose[0] - 0.1) > 0.25  # the edge of the window
    kept = matcher.match(scan, (0.1, 0.0, 0.0), **kw, translation_cost=0.1, rotation_cost=0.1)
    assert kept.pose == pytest.approx((0.1, 0.0, 0.0), abs=1e-9)


def test_loop_closure_window_finds_the_pose_far_from_the_initial_guess() -> None:
    grid = _room_grid(0.05)
    matcher = CorrelativeGridMatcher.from_occupancy_grid(grid)  # depth 7, Cartographer's default
    truth = np.array([6.5, 4.6, -2.0])
    scan = scan_points(ROOM, tuple(truth), n_beams=360)
    init = truth + np.array([-2.5, -1.8, math.radians(25)])
    res = matcher.match(scan, init)  # default window ±7 m, ±30°
    err = np.hypot(*(res.pose[:2] - truth[:2]))
    dth = abs((res.pose[2] - truth[2] + math.pi) % (2 * math.pi) - math.pi)
    assert err <= 0.05 * math.sqrt(2) and dth <= math.radians(0.5)
    assert res.score > 0.5
    cov = res.covariance
    assert np.allclose(cov, cov.T) and np.linalg.eigvalsh(cov).min() > 0


def test_min_score_rejects_with_a_typed_error() -> None:
    grid = _room_grid(0.1)
    matcher = CorrelativeGridMatcher.from_occupancy_grid(grid, depth=3)
    scan = scan_points(ROOM, (4.0, 3.0, 0.0), n_beams=60)
    with pytest.raises(NoMatchError):
        matcher.match(scan, (4.0, 3.0, 0.0), linear_window_m=0.3, angular_window_rad=0.1, min_score=0.999)


def test_relative_pose_helper_is_the_scan_in_reference_convention() -> None:
    a, b = (1.0, 2.0, 0.5), (1.5, 1.7, 0.9)
    rel = relative(a, b)
    pts = scan_points(ROOM, b, n_beams=8)
    c, s = math.cos(rel[2]), math.sin(rel[2])
    in_a = pts @ np.array([[c, s], [-s, c]]) + rel[:2]
    ca, sa = math.cos(a[2]), math.sin(a[2])
    world_from_a = in_a @ np.array([[ca, sa], [-sa, ca]]) + np.array(a[:2])
    cb, sb = math.cos(b[2]), math.sin(b[2])
    world_from_b = pts @ np.array([[cb, sb], [-sb, cb]]) + np.array(b[:2])
    assert np.allclose(world_from_a, world_from_b)


def test_bad_tables_are_rejected() -> None:
    frame = GridFrame(0.1, (0.0, 0.0), (4, 4))
    with pytest.raises(ScanMatchError):
        CorrelativeGridMatcher(np.full((4, 4), 2.0), frame)
    with pytest.raises(ScanMatchError):
        CorrelativeGridMatcher(np.zeros((3, 4)), frame)
    with pytest.raises(ScanMatchError):
        CorrelativeGridMatcher(np.zeros((4, 4)), GridFrame(0.1, (0.0, 0.0), (4, 4), yaw_rad=0.1))
    with pytest.raises(ScanMatchError):
        CorrelativeGridMatcher(np.zeros((4, 4)), frame, depth=0)

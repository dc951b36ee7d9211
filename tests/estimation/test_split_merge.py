"""split_and_merge: walls of a rectangle as (ρ, α) lines, their corners, gaps, covariances, typed errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.estimation import SplitMergeError, fit_line, line_corners, split_and_merge
from tests.estimation._scans import scan_points

# 6 m × 4 m rectangle; the sensor at (2, 1.5) facing +x sees the walls at y = −1.5 (α = −90°), x = 4 (0°),
# y = 2.5 (90°), x = −2 (180°) in its own frame.
RECT = np.array([(0, 0, 6, 0), (6, 0, 6, 4), (6, 4, 0, 4), (0, 4, 0, 0)], dtype=float)
SENSOR = (2.0, 1.5, 0.0)
WALLS = [(1.5, -math.pi / 2), (4.0, 0.0), (2.5, math.pi / 2), (2.0, math.pi)]
CORNERS = [(4.0, -1.5), (4.0, 2.5), (-2.0, 2.5), (-2.0, -1.5)]


def _angle_diff(a: float, b: float) -> float:
    return abs((a - b + math.pi) % (2 * math.pi) - math.pi)


def _match_walls(segs: tuple, tol_rho: float, tol_alpha: float) -> None:
    assert len(segs) == 4
    for rho, alpha in WALLS:
        hits = [s for s in segs if abs(s.rho - rho) < tol_rho and _angle_diff(s.alpha, alpha) < tol_alpha]
        assert len(hits) == 1, (rho, alpha, [(s.rho, s.alpha) for s in segs])


def test_rectangle_walls_are_recovered_exactly_without_noise() -> None:
    segs = split_and_merge(scan_points(RECT, SENSOR))
    _match_walls(segs, 1e-9, 1e-9)
    total = sum(s.n_points for s in segs)
    assert total >= 355  # every point but a few at the corners belongs to a wall


def test_rectangle_corners_are_found() -> None:
    segs = split_and_merge(scan_points(RECT, SENSOR))
    corners = line_corners(segs)
    assert len(corners) == 4
    for cx, cy in CORNERS:
        d = [math.hypot(c.xy[0] - cx, c.xy[1] - cy) for c in corners]
        assert min(d) < 1e-9
    for c in corners:
        assert c.angle_rad == pytest.approx(math.pi / 2)
        assert np.allclose(c.covariance, c.covariance.T) and np.linalg.eigvalsh(c.covariance).min() > 0


def test_noisy_rectangle_within_tolerance_and_covariance() -> None:
    rng = np.random.default_rng(3)
    segs = split_and_merge(scan_points(RECT, SENSOR, rng, 0.01), point_sigma_m=0.01)
    _match_walls(segs, 0.01, math.radians(1.0))
    for s in segs:
        cov = s.covariance
        assert np.allclose(cov, cov.T) and np.linalg.eigvalsh(cov).min() > 0
    assert len(line_corners(segs)) == 4


def test_line_covariance_matches_monte_carlo() -> None:
    rng = np.random.default_rng(4)
    t = np.linspace(0.0, 2.0, 40)
    clean = np.column_stack((1.0 + 0.3 * t, 2.0 + t))
    est = []
    for _ in range(400):
        rho, alpha, cov = fit_line(clean + rng.normal(0, 0.02, clean.shape), 0.02)
        est.append((rho, alpha))
    emp = np.cov(np.array(est).T)
    assert np.allclose(np.diag(cov), np.diag(emp), rtol=0.25)
    assert cov[0, 1] == pytest.approx(emp[0, 1], rel=0.35)


def test_a_gap_splits_a_straight_wall() -> None:
    x = np.concatenate((np.linspace(-2, -0.5, 30), np.linspace(0.5, 2, 30)))
    pts = np.column_stack((x, np.full_like(x, 3.0)))
    segs = split_and_merge(pts, max_gap_m=0.3)
    assert len(segs) == 2
    assert all(abs(s.rho - 3.0) < 1e-12 and _angle_diff(s.alpha, math.pi / 2) < 1e-12 for s in segs)
    assert line_corners(segs) == ()  # collinear: no corner
    assert len(split_and_merge(pts, max_gap_m=2.0)) == 1


def test_short_and_sparse_input() -> None:
    assert split_and_merge(np.zeros((0, 2))) == ()
    assert split_and_merge(np.array([[1.0, 0.0], [1.0, 0.1], [1.0, 0.2]])) == ()  # below min_points


def test_repeated_points_are_not_an_error() -> None:
    wall = [[1.0, 0.1 * i] for i in range(10)]
    pts = np.array([[1.0, 0.0]] * 10 + wall + [[2.0, 2.0]] * 8)
    segs = split_and_merge(pts)
    assert len(segs) == 1 and abs(segs[0].rho - 1.0) < 1e-12
    assert split_and_merge(np.array([[1.0, 0.0]] * 10)) == ()


def test_bad_input_raises() -> None:
    with pytest.raises(SplitMergeError):
        split_and_merge(np.zeros((5, 3)))
    with pytest.raises(SplitMergeError):
        split_and_merge(np.zeros((5, 2)), split_threshold_m=0.0)
    with pytest.raises(SplitMergeError):
        fit_line(np.ones((4, 2)))
    assert issubclass(SplitMergeError, ValueError)

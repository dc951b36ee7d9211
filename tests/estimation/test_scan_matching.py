"""scan_match (ICP, PL-ICP, CSM): known transforms recovered, covariances, degenerate input, typed errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.estimation import (
    InsufficientPointsError,
    ScanMatchError,
    ScanMatchResult,
    scan_match,
    scan_to_points,
)
from tests.estimation._scans import CORRIDOR, ROOM, relative, scan_points

POSE_A = (3.0, 2.5, 0.3)
POSE_B = (3.15, 2.42, 0.36)


def _transform(pose: np.ndarray, pts: np.ndarray) -> np.ndarray:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return pts @ np.array([[c, s], [-s, c]]) + pose[:2]


def _errors(result: ScanMatchResult, truth: np.ndarray) -> tuple[float, float]:
    d = result.pose - truth
    return math.hypot(d[0], d[1]), abs((d[2] + math.pi) % (2 * math.pi) - math.pi)


def test_icp_recovers_a_known_transform_of_the_same_points() -> None:
    ref = scan_points(ROOM, POSE_A)
    truth = np.array([0.12, -0.07, math.radians(4.0)])
    # The reference points expressed in the moved frame: p_scan = R(θ)ᵀ (p_ref − t).
    c, s = math.cos(truth[2]), math.sin(truth[2])
    scan = (ref - truth[:2]) @ np.array([[c, -s], [s, c]])
    res = scan_match(ref, scan, truth + np.array([0.05, 0.03, math.radians(-2.0)]), method="icp")
    et, er = _errors(res, truth)
    assert et < 1e-4 and er < 1e-5
    assert res.converged and res.method == "icp" and res.score > 0.95
    # The convention: the scan transformed by the pose lands on the reference.
    assert np.max(np.abs(_transform(res.pose, scan) - ref)) < 1e-4


def test_plicp_recovers_the_motion_between_two_views_to_sub_mm() -> None:
    ref = scan_points(ROOM, POSE_A)
    scan = scan_points(ROOM, POSE_B)  # a different sampling of the same walls
    truth = relative(POSE_A, POSE_B)
    res = scan_match(ref, scan, truth + np.array([0.04, -0.03, math.radians(2.0)]), method="plicp")
    et, er = _errors(res, truth)
    assert et < 1e-3 and er < math.radians(0.01)
    assert res.converged and not res.degenerate and res.iterations < 30


def test_point_to_point_icp_is_biased_by_sampling_where_plicp_is_not() -> None:
    """A different sampling of the walls leaves point-to-point ICP millimetres off; PL-ICP removes it."""
    ref = scan_points(ROOM, POSE_A)
    scan = scan_points(ROOM, POSE_B)
    truth = relative(POSE_A, POSE_B)
    init = truth + np.array([0.04, -0.03, math.radians(2.0)])
    e_icp, _ = _errors(scan_match(ref, scan, init, method="icp"), truth)
    e_pl, _ = _errors(scan_match(ref, scan, init, method="plicp"), truth)
    assert e_pl < e_icp < 0.02


def test_noisy_scans_are_matched_to_millimetres() -> None:
    rng = np.random.default_rng(5)
    truth = relative(POSE_A, POSE_B)
    errs = []
    for _ in range(10):
        ref = scan_points(ROOM, POSE_A, rng, 0.01)
        scan = scan_points(ROOM, POSE_B, rng, 0.01)
        res = scan_match(ref, scan, truth + np.array([-0.05, 0.0, math.radians(2.0)]), method="plicp")
        errs.append(_errors(res, truth))
    e = np.array(errs)
    assert np.median(e[:, 0]) < 0.003 and np.median(e[:, 1]) < math.radians(0.05)


def test_csm_is_exact_to_its_resolution() -> None:
    ref = scan_points(ROOM, POSE_A)
    scan = scan_points(ROOM, POSE_B)
    truth = relative(POSE_A, POSE_B)
    res = scan_match(ref, scan, truth + np.array([0.08, -0.06, math.radians(4.0)]), method="csm", csm_resolution_m=0.02)
    et, er = _errors(res, truth)
    assert et <= 0.02 * math.sqrt(2) and er <= math.radians(0.3)
    assert res.method == "csm" and 0.5 < res.score <= 1.0
    # Its covariance reflects the lattice: at least the quantisation variance, at most a few cells.
    assert res.covariance[0, 0] >= 0.02**2 / 12 - 1e-12
    assert res.covariance[0, 0] < 0.05**2


@pytest.mark.parametrize("method", ["icp", "plicp", "csm"])
def test_covariance_is_symmetric_positive_semidefinite(method: str) -> None:
    rng = np.random.default_rng(1)
    ref = scan_points(ROOM, POSE_A, rng, 0.01)
    scan = scan_points(ROOM, POSE_B, rng, 0.01)
    res = scan_match(ref, scan, relative(POSE_A, POSE_B), method=method)  # type: ignore[arg-type]
    cov = res.covariance
    assert cov.shape == (3, 3) and np.allclose(cov, cov.T)
    assert np.linalg.eigvalsh(cov).min() >= -1e-15
    assert np.all(np.diag(cov) > 0)
    assert not res.pose.flags.writeable


def test_plicp_noise_covariance_matches_the_spread_of_estimates() -> None:
    """σ²(JᵀJ)⁻¹ predicts the x spread over repeated noisy matches within a factor of 3."""
    rng = np.random.default_rng(2)
    truth = relative(POSE_A, POSE_B)
    xs, var = [], []
    for _ in range(20):
        ref = scan_points(ROOM, POSE_A, rng, 0.01)
        scan = scan_points(ROOM, POSE_B, rng, 0.01)
        res = scan_match(ref, scan, truth, method="plicp")
        xs.append(res.pose[0])
        var.append(res.covariance[0, 0])
    ratio = np.std(xs) / math.sqrt(np.mean(var))
    assert 1 / 3 < ratio < 3


def test_corridor_is_flagged_degenerate_and_keeps_the_initial_along_track_position() -> None:
    a, b = (0.0, 0.0, 0.0), (0.3, 0.1, 0.05)
    ref = scan_points(CORRIDOR, a)
    scan = scan_points(CORRIDOR, b)
    truth = relative(a, b)
    init = truth + np.array([0.2, 0.05, 0.02])
    res = scan_match(ref, scan, init, method="plicp")
    assert res.degenerate
    # Lateral position and heading are observable; the along-corridor direction is not and is not invented.
    assert abs(res.pose[2] - truth[2]) < 1e-3
    assert abs(res.pose[1] - truth[1]) < 1e-3
    assert abs(res.pose[0] - init[0]) < 1e-9
    w, V = np.linalg.eigh(res.covariance[:2, :2])
    assert w[1] > 1e4 * max(w[0], 1e-30)
    assert abs(V[0, 1]) > 0.99  # the well-determined direction is across the corridor (y)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_noisy_corridor_keeps_the_initial_along_track_position_too(seed: int) -> None:
    """With 1 cm of range noise the iterations stepped along the corridor anyway (up to 0.5 m from the
    initial pose; issue 30: a SLAM estimate 4 m behind the robot after 13 m along a wall): the unobservable
    direction's share of the move is taken back."""
    rng = np.random.default_rng(seed)
    a, b = (0.0, 0.0, 0.0), (0.3, 0.1, 0.05)
    ref = scan_points(CORRIDOR, a, rng, 0.01)
    scan = scan_points(CORRIDOR, b, rng, 0.01)
    truth = relative(a, b)
    init = truth + np.array([0.2, 0.05, 0.02])
    res = scan_match(ref, scan, init, method="plicp")
    assert res.degenerate
    assert abs(res.pose[0] - init[0]) < 1e-3  # the heading's correction moves x by a hair at most
    assert abs(res.pose[1] - truth[1]) < 0.01 and abs(res.pose[2] - truth[2]) < 0.005


def test_corridor_is_flagged_degenerate_for_point_to_point_icp_too() -> None:
    a, b = (0.0, 0.0, 0.0), (0.3, 0.1, 0.05)
    res = scan_match(scan_points(CORRIDOR, a), scan_points(CORRIDOR, b), relative(a, b), method="icp")
    assert res.degenerate
    assert res.covariance[0, 0] > 1e3 * res.covariance[1, 1]


def test_far_away_coordinates_are_rejected() -> None:
    ref = scan_points(ROOM, POSE_A)
    with pytest.raises(ScanMatchError):
        scan_match(ref + 1e6, ref, (0.0, 0.0, 0.0))


def test_room_is_not_degenerate() -> None:
    res = scan_match(scan_points(ROOM, POSE_A), scan_points(ROOM, POSE_B), relative(POSE_A, POSE_B), "plicp")
    assert not res.degenerate


def test_too_few_points_raise_a_typed_error() -> None:
    ref = scan_points(ROOM, POSE_A)
    with pytest.raises(InsufficientPointsError):
        scan_match(ref, ref[:2], (0.0, 0.0, 0.0))
    with pytest.raises(InsufficientPointsError):
        scan_match(np.array([[1.0, 0.0], [np.nan, 1.0], [np.inf, 0.0]]), ref, (0.0, 0.0, 0.0))


def test_no_overlap_raises_instead_of_returning_nonsense() -> None:
    ref = scan_points(ROOM, POSE_A)
    with pytest.raises(InsufficientPointsError):
        scan_match(ref, ref + 100.0, (0.0, 0.0, 0.0), method="plicp")


def test_bad_arguments_raise_scan_match_error() -> None:
    ref = scan_points(ROOM, POSE_A)
    with pytest.raises(ScanMatchError):
        scan_match(ref, ref, (0.0, 0.0, 0.0), method="ndt")  # type: ignore[arg-type]
    with pytest.raises(ScanMatchError):
        scan_match(ref, ref, (0.0, 0.0))
    with pytest.raises(ScanMatchError):
        scan_match(ref[:, :1], ref, (0.0, 0.0, 0.0))
    with pytest.raises(ScanMatchError):
        scan_match(ref, ref, (0.0, 0.0, 0.0), max_correspondence_m=-1.0)
    assert issubclass(ScanMatchError, ValueError)


def test_scan_to_points_drops_invalid_beams() -> None:
    pts = scan_to_points([1.0, np.inf, np.nan, 0.0, 2.0, 90.0], np.linspace(0, 1, 6), max_range_m=80.0)
    assert pts.shape == (2, 2)
    assert np.allclose(pts[0], [1.0, 0.0])
    assert np.allclose(np.hypot(*pts[1]), 2.0)

"""EKFSLAM: motion and measurement steps, landmark initialisation, gating, and a 50-run Monte Carlo check."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.estimation import EKFSLAM, InvalidMeasurement, InvalidModel
from mjnav.estimation.simulation import (
    LOOP_WORLD_ALPHAS,
    LOOP_WORLD_BEARING_STD_RAD,
    LOOP_WORLD_RANGE_STD_M,
    evaluate_slam,
    nees_bounds,
    simulate_loop_world,
)
from mjnav.motion import sample_velocity_motion, velocity_motion

ALPHAS = (0.01, 0.001, 0.002, 0.02, 0.001, 0.0005)


def _slam(**kw: object) -> EKFSLAM:
    return EKFSLAM(LOOP_WORLD_ALPHAS, LOOP_WORLD_RANGE_STD_M, LOOP_WORLD_BEARING_STD_RAD, **kw)  # type: ignore[arg-type]


def test_predict_moves_the_mean_with_the_velocity_model_and_matches_sampled_covariance() -> None:
    start = np.array([1.0, -2.0, 0.4])
    P0 = np.diag([0.01, 0.02, 0.003])
    slam = EKFSLAM(ALPHAS, 0.1, 0.01, initial_pose=start, initial_covariance=P0)
    slam.predict(1.2, 0.8, 0.5)
    assert np.allclose(slam.pose, velocity_motion(start, 1.2, 0.8, 0.5), atol=1e-12)
    rng = np.random.default_rng(5)
    starts = rng.multivariate_normal(start, P0, 200_000)
    samples = sample_velocity_motion(starts, 1.2, 0.8, 0.5, ALPHAS, rng)
    emp = np.cov(samples.T)
    assert np.allclose(slam.pose_covariance, emp, rtol=0.03, atol=2e-4)


def test_first_update_initialises_landmarks_from_the_observations() -> None:
    slam = _slam(initial_pose=(1.0, 2.0, math.pi / 2))
    z = np.array([[2.0, 0.0], [3.0, math.pi / 2]])
    a = slam.update(z)
    assert a.is_new.tolist() == [True, True] and a.landmark.tolist() == [0, 1]
    assert a.origin.tolist() == [[0, 0], [0, 1]] and np.isnan(a.distance2).all()
    assert np.allclose(slam.landmarks, [[1.0, 4.0], [-2.0, 2.0]], atol=1e-12)
    # pose known exactly: landmark covariance is G_z R G_zᵀ, e.g. the first is diag(σ_φ² r², σ_r²) rotated to +y
    c0 = slam.landmark_covariances[0]
    assert np.allclose(c0, np.diag([(2.0 * LOOP_WORLD_BEARING_STD_RAD) ** 2, LOOP_WORLD_RANGE_STD_M**2]), atol=1e-12)
    assert slam.covariance.shape == (7, 7)
    assert slam.landmark_origins.tolist() == [[0, 0], [0, 1]]


def test_reobserving_matches_the_landmarks_and_shrinks_their_covariance() -> None:
    slam = _slam(initial_covariance=np.diag([0.01, 0.01, 0.001]))
    z = np.array([[2.0, 0.3], [4.0, -1.0], [3.0, 2.5]])
    slam.update(z)
    before = slam.landmark_covariances
    a = slam.update(z[[2, 0, 1]] + [[0.05, 0.01], [-0.05, 0.0], [0.0, -0.01]])
    assert a.landmark.tolist() == [2, 0, 1] and not a.is_new.any()
    assert a.origin.tolist() == [[0, 2], [0, 0], [0, 1]]
    assert (a.distance2 < 9.21).all() and slam.landmarks.shape == (3, 2)
    after = slam.landmark_covariances
    assert all(np.linalg.det(after[i]) < np.linalg.det(before[i]) for i in range(3))
    # landmarks mapped from this same pose carry no new information about the pose itself
    assert np.trace(slam.pose_covariance) == pytest.approx(0.021, abs=1e-12)


def test_ambiguous_observation_between_the_gates_is_discarded_not_duplicated() -> None:
    slam = _slam()
    slam.update([[3.0, 0.0]])
    # distance² ≈ (δr / σ_r)² with S ≈ 2R on a second sighting: pick δr for d² ≈ 16, between 13.8 and 23.0
    dr = math.sqrt(16.0 * 2.0) * LOOP_WORLD_RANGE_STD_M
    a = slam.update([[3.0 + dr, 0.0]])
    assert a.landmark.tolist() == [-1] and a.discarded.all() and not a.is_new.any()
    assert slam.landmarks.shape == (1, 2)
    far = slam.update([[3.0 + 3.0 * dr, 0.0]])
    assert far.is_new.tolist() == [True] and slam.landmarks.shape == (2, 2)


def test_empty_and_bad_observations() -> None:
    slam = _slam()
    a = slam.update(np.zeros((0, 2)))
    assert a.landmark.shape == (0,) and slam.landmarks.shape == (0, 2)
    for bad in ([[1.0, 2.0, 3.0]], [[-1.0, 0.0]], [[math.nan, 0.0]]):
        with pytest.raises(InvalidMeasurement):
            slam.update(bad)
    with pytest.raises(InvalidModel):
        _slam(association="icp")
    with pytest.raises(InvalidModel):
        _slam(gate_probability=0.99, new_landmark_probability=0.9)
    with pytest.raises(InvalidModel):
        EKFSLAM((0.1, 0.1, 0.1), 0.1, 0.01)
    with pytest.raises(ValueError):
        slam.predict(1.0, 0.0, -0.1)


@pytest.mark.e2e
def test_monte_carlo_nees_and_associations_on_the_loop_world() -> None:
    """50 seeded runs of one 80-step loop: pose ANEES inside the 95% χ² band, ≥ 99% correct associations."""
    runs = 50
    scores = [evaluate_slam(_slam(), simulate_loop_world(np.random.default_rng(seed))) for seed in range(runs)]
    anees = np.mean([s.nees for s in scores], axis=0)
    lo, hi = nees_bounds(3, runs)
    assert lo < float(anees.mean()) < hi
    assert np.mean((anees > lo) & (anees < hi)) >= 0.9
    total = sum(s.total for s in scores)
    assert sum(s.correct for s in scores) / total >= 0.99
    assert sum(s.wrong for s in scores) / total <= 0.002
    assert float(np.mean([s.landmark_rmse_m for s in scores])) < 0.4


@pytest.mark.e2e
def test_jcbb_association_on_the_loop_world() -> None:
    scores = [
        evaluate_slam(_slam(association="jcbb"), simulate_loop_world(np.random.default_rng(seed)))
        for seed in range(100, 108)
    ]
    total = sum(s.total for s in scores)
    assert sum(s.correct for s in scores) / total >= 0.99
    assert float(np.mean([s.nees.mean() for s in scores])) < 6.0


def test_defaults_are_the_documented_noise() -> None:
    slam = EKFSLAM()
    assert np.allclose(slam.alphas, LOOP_WORLD_ALPHAS)
    assert np.allclose(slam.R, np.diag([LOOP_WORLD_RANGE_STD_M**2, LOOP_WORLD_BEARING_STD_RAD**2]))
    assert slam.pose.tolist() == [0.0, 0.0, 0.0] and slam.covariance.shape == (3, 3)


def test_sparse_joint_update_equals_the_dense_kalman_update() -> None:
    from mjnav.estimation.ekf_slam import _sparse_joint_update

    rng = np.random.default_rng(4)
    n, p = 11, 3
    A = rng.normal(size=(n, n))
    P = A @ A.T + np.eye(n)
    x = rng.normal(size=n)
    idx = np.array([[0, 1, 2, 3, 4], [0, 1, 2, 7, 8], [0, 1, 2, 9, 10]])
    Hs = rng.normal(size=(p, 2, 5))
    R = np.diag([0.04, 0.001])
    nu = rng.normal(size=2 * p)
    H = np.zeros((2 * p, n))
    for i in range(p):
        H[2 * i : 2 * i + 2, idx[i]] = Hs[i]
    S = H @ P @ H.T + np.kron(np.eye(p), R)
    K = P @ H.T @ np.linalg.inv(S)
    xn, Pn, ok = _sparse_joint_update(x, P, Hs, idx, nu, R)
    assert ok
    assert np.allclose(xn, x + K @ nu, atol=1e-10)
    assert np.allclose(Pn, (np.eye(n) - K @ H) @ P, atol=1e-10)
    assert not _sparse_joint_update(x, P, Hs, idx, nu, -10.0 * np.eye(2) * P.max())[2]

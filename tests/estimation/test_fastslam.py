"""FastSLAM 1.0: motion sampling, per-particle landmark EKFs, resampling, association and a 50-run NEES check."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.estimation import EKFSLAM, FastSLAM, InvalidMeasurement, InvalidModel
from mjnav.estimation.fastslam import low_variance_indices
from mjnav.estimation.simulation import (
    FASTSLAM_WORLD_ALPHAS,
    FASTSLAM_WORLD_BEARING_STD_RAD,
    FASTSLAM_WORLD_RANGE_STD_M,
    LOOP_WORLD_ALPHAS,
    LOOP_WORLD_BEARING_STD_RAD,
    LOOP_WORLD_RANGE_STD_M,
    evaluate_slam,
    nees_bounds,
    simulate_loop_world,
    truncate_run,
)

ALPHAS = (0.01, 0.001, 0.002, 0.02, 0.001, 0.0005)


def _fast(seed: int = 0, **kw: object) -> FastSLAM:
    return FastSLAM(
        LOOP_WORLD_ALPHAS,
        LOOP_WORLD_RANGE_STD_M,
        LOOP_WORLD_BEARING_STD_RAD,
        rng=np.random.default_rng(seed),
        **kw,  # type: ignore[arg-type]
    )


def test_low_variance_resampling_keeps_each_particle_floor_or_ceil_times() -> None:
    rng = np.random.default_rng(0)
    w = np.array([0.5, 0.3, 0.15, 0.05])
    for _ in range(50):
        idx = low_variance_indices(w, rng)
        counts = np.bincount(idx, minlength=4)
        assert np.all(counts >= np.floor(4 * w)) and np.all(counts <= np.ceil(4 * w))
        assert np.all(np.diff(idx) >= 0)
    assert low_variance_indices([0.0, 1.0, 0.0], rng).tolist() == [1, 1, 1]


def test_predict_samples_the_velocity_model_like_the_ekf_propagates_it() -> None:
    P0 = np.diag([0.01, 0.02, 0.003])
    start = (1.0, -2.0, 0.4)
    fast = FastSLAM(
        ALPHAS, 0.1, 0.01, rng=np.random.default_rng(1), num_particles=20_000, initial_pose=start, initial_covariance=P0
    )
    ekf = EKFSLAM(ALPHAS, 0.1, 0.01, initial_pose=start, initial_covariance=P0)
    fast.predict(1.2, 0.8, 0.5)
    ekf.predict(1.2, 0.8, 0.5)
    assert np.allclose(fast.pose, ekf.pose, atol=3e-3)
    assert np.allclose(fast.pose_covariance, ekf.pose_covariance, rtol=0.05, atol=3e-4)
    assert np.allclose(fast.covariance, fast.pose_covariance)


def test_landmarks_start_from_the_first_observation_and_tighten_on_reobservation() -> None:
    fast = _fast(num_particles=20, initial_pose=(1.0, 2.0, math.pi / 2))
    z = np.array([[2.0, 0.0], [3.0, math.pi / 2]])
    a = fast.update(z)
    assert a.is_new.tolist() == [True, True] and a.landmark.tolist() == [0, 1]
    assert a.origin.tolist() == [[0, 0], [0, 1]]
    assert np.allclose(fast.landmarks, [[1.0, 4.0], [-2.0, 2.0]], atol=1e-12)
    c0 = np.diag([(2.0 * LOOP_WORLD_BEARING_STD_RAD) ** 2, LOOP_WORLD_RANGE_STD_M**2])
    assert np.allclose(fast.landmark_covariances[0], c0, atol=1e-12)
    b = fast.update(z[::-1])
    assert b.landmark.tolist() == [1, 0] and not b.is_new.any() and b.origin.tolist() == [[0, 1], [0, 0]]
    assert np.allclose(fast.landmark_covariances[0], 0.5 * c0, atol=1e-12)  # two equal measurements: half
    assert np.allclose(fast.landmarks, [[1.0, 4.0], [-2.0, 2.0]], atol=1e-12)


def test_weights_favour_the_particle_that_explains_the_observation_and_resampling_is_seeded() -> None:
    m2 = np.array([4.0 * math.cos(1.0), 4.0 * math.sin(1.0)])
    z2 = [[2.0, 0.0], [float(np.hypot(m2[0] - 1.0, m2[1])), math.atan2(m2[1], m2[0] - 1.0)]]  # after 1 m ahead

    def run(seed: int, threshold: float = 0.5) -> tuple[FastSLAM, np.ndarray]:
        f = _fast(seed, num_particles=200, initial_covariance=np.diag([0.05, 0.05, 0.01]), resample_threshold=threshold)
        f.update([[3.0, 0.0], [4.0, 1.0]])
        before = f.particles
        f.predict(1.0, 0.0, 1.0)
        f.update(z2)
        return f, before

    a, _ = run(7)
    b, _ = run(7)
    assert np.array_equal(a.particles, b.particles) and np.array_equal(a.weights, b.weights)
    assert not np.array_equal(run(8)[0].particles, a.particles)
    assert a.weights.sum() == pytest.approx(1.0)
    f, before = run(3, 0.0)
    assert not f.resampled and f.effective_sample_size < 200
    # each particle mapped the landmarks from its own start, so the observations measure its sampled motion: the
    # highest-weight particle moved close to the true 1 m straight ahead (in its own frame)
    d = f.particles - before
    c, s = np.cos(before[:, 2]), np.sin(before[:, 2])
    err = np.hypot(c * d[:, 0] + s * d[:, 1] - 1.0, -s * d[:, 0] + c * d[:, 1])
    assert err[f.best_particle] <= np.quantile(err, 0.1)
    g, _ = run(3, 1.0)
    assert g.resampled and np.allclose(g.weights, 1.0 / 200)
    # the best particle (pose and map together) survives resampling: its map still explains the last observations
    pose, lms = g.particles[g.best_particle], g.landmarks[g.last_association.landmark]
    r = np.hypot(lms[:, 0] - pose[0], lms[:, 1] - pose[1])
    assert np.allclose(r, np.asarray(z2)[:, 0], atol=3 * LOOP_WORLD_RANGE_STD_M)


def test_ambiguous_observation_is_discarded_and_bad_input_rejected() -> None:
    fast = _fast(num_particles=10)
    fast.update([[3.0, 0.0]])
    dr = math.sqrt(16.0 * 2.0) * LOOP_WORLD_RANGE_STD_M
    a = fast.update([[3.0 + dr, 0.0]])
    assert a.discarded.all() and fast.landmarks.shape == (1, 2)
    assert fast.update(np.zeros((0, 2))).landmark.shape == (0,)
    with pytest.raises(InvalidMeasurement):
        fast.update([[0.0, 1.0]])
    with pytest.raises(InvalidModel):
        _fast(num_particles=0)
    with pytest.raises(InvalidModel):
        _fast(resample_threshold=1.5)


@pytest.mark.e2e
def test_monte_carlo_nees_on_the_low_odometry_noise_half_loop() -> None:
    """50 seeded runs, 500 particles, the first 40 steps of the loop at FASTSLAM_WORLD_* noise: ANEES in band."""
    runs = 50
    scores = []
    for seed in range(runs):
        world = simulate_loop_world(
            np.random.default_rng(seed),
            motion_alphas=FASTSLAM_WORLD_ALPHAS,
            range_std_m=FASTSLAM_WORLD_RANGE_STD_M,
            bearing_std_rad=FASTSLAM_WORLD_BEARING_STD_RAD,
        )
        fast = FastSLAM(
            FASTSLAM_WORLD_ALPHAS,
            FASTSLAM_WORLD_RANGE_STD_M,
            FASTSLAM_WORLD_BEARING_STD_RAD,
            rng=np.random.default_rng(1000 + seed),
            num_particles=500,
        )
        scores.append(evaluate_slam(fast, truncate_run(world, 40)))
    anees = np.mean([s.nees for s in scores], axis=0)
    lo, hi = nees_bounds(3, runs)
    assert lo < float(anees.mean()) < hi
    assert np.mean((anees > lo) & (anees < hi)) >= 0.9
    total = sum(s.total for s in scores)
    assert sum(s.correct for s in scores) / total >= 0.99
    assert float(np.mean([s.landmark_rmse_m for s in scores])) < 0.5


def test_associations_on_the_full_loop_at_the_documented_noise() -> None:
    scores = [
        evaluate_slam(_fast(100 + seed, num_particles=100), simulate_loop_world(np.random.default_rng(seed)))
        for seed in range(10)
    ]
    total = sum(s.total for s in scores)
    assert sum(s.correct for s in scores) / total >= 0.99


def test_default_rng_is_seeded() -> None:
    a, b, c = FastSLAM(), FastSLAM(rng=0), FastSLAM(rng=1)
    for f in (a, b, c):
        f.predict(1.0, 0.2, 0.5)
    assert np.array_equal(a.particles, b.particles) and not np.array_equal(a.particles, c.particles)
    with pytest.raises(InvalidModel):
        FastSLAM(rng="seed")  # type: ignore[arg-type]

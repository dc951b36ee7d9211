"""KalmanFilter / ExtendedKalmanFilter against the robot.mat reference and the textbook equations."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.io import loadmat
from scipy.stats import multivariate_normal

from mjnav.estimation import (
    EstimationError,
    ExtendedKalmanFilter,
    InvalidMeasurement,
    InvalidModel,
    KalmanFilter,
    NotPositiveDefinite,
)


def _robot(refdata: Path) -> dict[str, np.ndarray]:
    m = loadmat(str(refdata / "kalman" / "robot.mat"))
    return {k: np.asarray(v) for k, v in m.items() if not k.startswith("_")}


@pytest.mark.parametrize("joseph", [False, True])
def test_robot_mat_filtered_means_and_covariances(refdata: Path, joseph: bool) -> None:
    """refdata README: xfilt[:, 0] = x0, P_0; for t >= 1 predict with b[:, t-1], update with y[:, t-1] and d."""
    m = _robot(refdata)
    kf = KalmanFilter(
        m["A"], m["C"], m["Q"], m["R"], x0=m["x0"].astype(float).ravel(), P0=m["P_0"].astype(float), joseph=joseph
    )
    d = m["d"].ravel()
    xfilt, vfilt = m["xfilt"], m["Vfilt"]
    assert np.array_equal(kf.x, xfilt[:, 0]) and np.array_equal(kf.P, vfilt[0, 0])
    worst_x = worst_p = 0.0
    for t in range(1, xfilt.shape[1]):
        kf.predict(offset=m["b"][:, t - 1])
        kf.update(m["y"][:, t - 1], offset=d)
        worst_x = max(worst_x, float(np.abs(kf.x - xfilt[:, t]).max()))
        worst_p = max(worst_p, float(np.abs(kf.P - vfilt[0, t]).max()))
    assert worst_x < 1e-9
    assert worst_p < 1e-9


def test_batch_filter_matches_the_step_loop(refdata: Path) -> None:
    m = _robot(refdata)
    args = (m["A"], m["C"], m["Q"], m["R"])
    kf = KalmanFilter(*args, x0=np.zeros(5), P0=np.eye(5))
    means, covs = kf.filter(m["y"].T, predict_offsets=m["b"].T, update_offsets=m["d"].ravel())
    assert means.shape == (500, 5) and covs.shape == (500, 5, 5)
    assert np.abs(means - m["xfilt"][:, 1:].T).max() < 1e-9
    assert np.abs(covs[-1] - m["Vfilt"][0, -1]).max() < 1e-9
    assert np.array_equal(kf.x, means[-1])


def _small(seed: int = 0) -> tuple[KalmanFilter, np.random.Generator]:
    rng = np.random.default_rng(seed)
    dt = 0.1
    F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    H = np.array([[1, 0, 0, 0], [0, 1, 0, 0]], float)
    G = np.array([[0.5 * dt * dt, 0], [0, 0.5 * dt * dt], [dt, 0], [0, dt]])
    Q = 0.01 * np.eye(4)
    R = np.array([[0.2, 0.05], [0.05, 0.3]])
    P0 = np.diag([1.0, 2.0, 0.5, 0.7])
    return KalmanFilter(F, H, Q, R, G=G, x0=np.array([1.0, -1.0, 0.5, 0.2]), P0=P0), rng


def test_predict_and_update_follow_the_equations() -> None:
    kf, rng = _small()
    F, H, Q, R, G = kf.F, kf.H, kf.Q, kf.R, kf.G
    assert G is not None
    x, P = kf.x.copy(), kf.P.copy()
    u = np.array([0.3, -0.4])
    b = np.array([0.01, 0.02, 0.03, 0.04])
    kf.predict(u, offset=b)
    x = F @ x + G @ u + b
    P = F @ P @ F.T + Q
    assert np.allclose(kf.x, x, atol=1e-14) and np.allclose(kf.P, P, atol=1e-14)
    y = rng.normal(size=2)
    d = np.array([0.1, -0.2])
    kf.update(y, offset=d)
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    nu = y - H @ x - d
    assert np.allclose(kf.S, S, atol=1e-13) and np.allclose(kf.K, K, atol=1e-13)
    assert np.allclose(kf.innovation, nu, atol=1e-14)
    assert np.allclose(kf.x, x + K @ nu, atol=1e-13)
    assert np.allclose(kf.P, (np.eye(4) - K @ H) @ P, atol=1e-13)
    assert kf.nis == pytest.approx(float(nu @ np.linalg.solve(S, nu)), rel=1e-12)
    assert kf.log_likelihood == pytest.approx(multivariate_normal(np.zeros(2), S).logpdf(nu), rel=1e-12)


def test_joseph_form_equals_the_short_form_for_the_optimal_gain() -> None:
    a, rng = _small()
    b, _ = _small()
    b.joseph = True
    for _ in range(20):
        y = rng.normal(size=2)
        for kf in (a, b):
            kf.predict()
            kf.update(y)
    assert np.allclose(a.x, b.x, atol=1e-12) and np.allclose(a.P, b.P, atol=1e-12)
    assert np.array_equal(b.P, b.P.T)


def test_steps_return_fresh_arrays() -> None:
    kf, rng = _small()
    saved = kf.x
    kf.predict()
    kf.update(rng.normal(size=2))
    assert not np.array_equal(saved, kf.x)
    assert np.array_equal(saved, [1.0, -1.0, 0.5, 0.2])


@pytest.mark.e2e
def test_nis_is_chi2_on_a_consistent_simulation() -> None:
    """The filter run on data drawn from its own model gives mean NIS ≈ m (= 2)."""
    kf, rng = _small(1)
    x_true = kf.x + rng.multivariate_normal(np.zeros(4), kf.P)
    nis = []
    for _ in range(2000):
        x_true = kf.F @ x_true + rng.multivariate_normal(np.zeros(4), kf.Q)
        y = kf.H @ x_true + rng.multivariate_normal(np.zeros(2), kf.R)
        kf.predict()
        kf.update(y)
        nis.append(kf.nis)
    assert 1.85 < float(np.mean(nis)) < 2.15


def test_bad_input_raises_typed_errors() -> None:
    kf, _ = _small()
    with pytest.raises(InvalidMeasurement):
        kf.update([1.0, 2.0, 3.0])
    with pytest.raises(InvalidMeasurement):
        kf.update([1.0, math.nan])
    with pytest.raises(InvalidMeasurement):
        kf.predict([1.0])
    x, P = kf.x, kf.P
    with pytest.raises(InvalidMeasurement):  # float64 arrays take the fast path: the kernel checks them
        kf.update(np.array([1.0, np.inf]))
    with pytest.raises(InvalidMeasurement):
        kf.update(np.array([1.0, 2.0]), offset=np.array([np.nan, 0.0]))
    with pytest.raises(InvalidMeasurement):
        kf.predict(np.array([0.0, np.nan]))
    with pytest.raises(InvalidMeasurement):
        kf.predict(offset=np.array([0.0, 0.0, np.inf, 0.0]))
    assert kf.x is x and kf.P is P  # a refused step leaves the state alone
    plain = KalmanFilter(np.eye(2), np.eye(2), np.eye(2), np.eye(2))
    with pytest.raises(InvalidMeasurement, match="needs a control matrix"):
        plain.predict([1.0, 2.0])
    with pytest.raises(InvalidModel):
        KalmanFilter(np.eye(2), np.eye(3), np.eye(2), np.eye(3))
    with pytest.raises(InvalidModel, match="symmetric"):
        KalmanFilter(np.eye(2), np.eye(2), [[1.0, 0.5], [0.0, 1.0]], np.eye(2))
    with pytest.raises(InvalidModel, match="semi-definite"):
        KalmanFilter(np.eye(2), np.eye(2), np.eye(2), -np.eye(2))
    degenerate = KalmanFilter(np.eye(2), np.eye(2), np.zeros((2, 2)), np.zeros((2, 2)), P0=np.zeros((2, 2)))
    with pytest.raises(NotPositiveDefinite) as err:
        degenerate.update([0.0, 0.0])
    assert isinstance(err.value, EstimationError)


def test_ekf_with_linear_models_equals_the_kalman_filter() -> None:
    kf, rng = _small()
    F, H = kf.F, kf.H
    ekf = ExtendedKalmanFilter(lambda x, u: F @ x, lambda x, u: F, lambda x: H @ x, lambda x: H, kf.Q, kf.R, kf.x, kf.P)
    for _ in range(10):
        y = rng.normal(size=2)
        kf.predict()
        kf.update(y)
        ekf.predict()
        ekf.update(y)
    assert np.allclose(kf.x, ekf.x, atol=1e-12) and np.allclose(kf.P, ekf.P, atol=1e-12)
    assert ekf.nis == pytest.approx(kf.nis) and ekf.log_likelihood == pytest.approx(kf.log_likelihood)


def test_ekf_range_bearing_update_linearises_at_the_prior_and_wraps_bearing() -> None:
    """One update of a 2-D position from a range-bearing beacon at the origin, bearing near ±π."""

    def h(x: np.ndarray) -> np.ndarray:
        return np.array([math.hypot(x[0], x[1]), math.atan2(x[1], x[0])])

    def h_jac(x: np.ndarray) -> np.ndarray:
        r2 = x[0] ** 2 + x[1] ** 2
        r = math.sqrt(r2)
        return np.array([[x[0] / r, x[1] / r], [-x[1] / r2, x[0] / r2]])

    def wrap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        d = a - b
        d[1] = (d[1] + math.pi) % (2 * math.pi) - math.pi
        return d

    x0 = np.array([-5.0, 0.01])
    P0 = np.diag([0.5, 0.5])
    R = np.diag([0.01, 0.001])
    ekf = ExtendedKalmanFilter(
        lambda x, u: x, lambda x, u: np.eye(2), h, h_jac, np.zeros((2, 2)), R, x0, P0, residual=wrap
    )
    z = np.array([5.1, -math.pi + 0.01])  # just across the ±π cut from the prediction (≈ +π − 0.002)
    ekf.update(z)
    H = h_jac(x0)
    S = H @ P0 @ H.T + R
    nu = wrap(z, h(x0))
    assert abs(nu[1]) < 0.05
    assert np.allclose(ekf.x, x0 + P0 @ H.T @ np.linalg.solve(S, nu), atol=1e-12)
    assert ekf.x[0] < -5.05  # moved outwards along the range


def test_scalar_model_and_derived_quantities() -> None:
    """A 1-state filter from scalars: predict P = 1 + 0.1, S = 1.6, K = 0.6875."""
    kf = KalmanFilter(1.0, 1.0, 0.1, 0.5)
    kf.predict()
    kf.update(2.0)
    assert kf.x.tolist() == pytest.approx([1.375]) and kf.P[0, 0] == pytest.approx(0.34375)
    assert kf.K[0, 0] == pytest.approx(0.6875) and kf.S[0, 0] == pytest.approx(1.6)
    assert kf.mahalanobis == pytest.approx(2.0 / math.sqrt(1.6))
    assert kf.likelihood == pytest.approx(math.exp(-0.5 * 4.0 / 1.6) / math.sqrt(2 * math.pi * 1.6))
    row = KalmanFilter(np.eye(2), [1.0, 0.0], 0.1, 0.5)  # a 1-D H is one measurement row
    row.update(1.0)
    assert row.x == pytest.approx([2.0 / 3.0, 0.0])

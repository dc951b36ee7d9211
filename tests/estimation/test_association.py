"""χ² gates, Mahalanobis distances, greedy nearest neighbour and JCBB."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.estimation.association import chi2_gate, jcbb, nearest_neighbor, pairwise_mahalanobis
from mjnav.estimation.errors import InvalidModel, NotPositiveDefinite


def test_chi2_gate_values() -> None:
    assert chi2_gate(0.95, 2) == pytest.approx(5.991464547, rel=1e-9)
    assert chi2_gate(0.99, 1) == pytest.approx(6.634896601, rel=1e-9)
    for bad in [(0.0, 2), (1.0, 2), (0.9, 0)]:
        with pytest.raises(InvalidModel):
            chi2_gate(*bad)


def test_pairwise_mahalanobis_matches_a_loop_and_wraps_angles() -> None:
    rng = np.random.default_rng(0)
    z = rng.normal(size=(4, 2))
    zp = rng.normal(size=(3, 2))
    A = rng.normal(size=(3, 2, 2))
    S = A @ A.transpose(0, 2, 1) + 0.1 * np.eye(2)
    d2 = pairwise_mahalanobis(z, zp, S)
    for k in range(4):
        for j in range(3):
            nu = z[k] - zp[j]
            assert d2[k, j] == pytest.approx(nu @ np.linalg.solve(S[j], nu), rel=1e-10)
    wrapped = pairwise_mahalanobis([[5.0, math.pi - 0.01]], [[5.0, -math.pi + 0.01]], [np.eye(2)], angle_dims=(1,))
    assert wrapped[0, 0] == pytest.approx(0.02**2, rel=1e-6)
    with pytest.raises(NotPositiveDefinite):
        pairwise_mahalanobis(z, zp, -S)


def test_nearest_neighbor_is_one_to_one_and_gated() -> None:
    d2 = np.array(
        [
            [1.0, 2.0, 50.0],  # observation 0 prefers landmark 0 ...
            [0.5, 3.0, 50.0],  # ... but observation 1 is closer to it, so 0 takes landmark 1
            [40.0, 40.0, 30.0],  # outside the gate
        ]
    )
    assert nearest_neighbor(d2, 9.21).tolist() == [1, 0, -1]
    assert nearest_neighbor(d2, 1.5).tolist() == [-1, 0, -1]  # obs 0: landmark 0 taken, landmark 1 outside
    assert nearest_neighbor(np.zeros((2, 0)), 9.21).tolist() == [-1, -1]


def _row_of_landmarks() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Robot position state (n = 2) with 1 m uncertainty, landmarks 1 m apart, relative-position measurements.

    The robot is really 0.6 m to the left of its estimate, so every observation appears shifted right by 0.6 m:
    each is individually nearest the next landmark, but only the true pairing explains all four at once.
    """
    lms = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])
    x_est = np.zeros(2)
    x_true = np.array([-0.6, 0.0])
    z = lms - x_true
    zp = lms - x_est
    H = np.broadcast_to(-np.eye(2), (4, 2, 2)).copy()
    P = np.eye(2)
    R = (0.02**2) * np.eye(2)
    return z, zp, H, P, R


def test_jcbb_finds_the_jointly_compatible_pairing_where_nearest_neighbor_fails() -> None:
    z, zp, H, P, R = _row_of_landmarks()
    S = H @ P @ H.transpose(0, 2, 1) + R
    nn = nearest_neighbor(pairwise_mahalanobis(z, zp, S), chi2_gate(0.99, 2))
    assert nn.tolist() != [0, 1, 2, 3]
    assert nn[0] == 1  # shifted by one landmark
    assert jcbb(z, zp, H, P, R, gate_probability=0.99).tolist() == [0, 1, 2, 3]


def test_jcbb_leaves_an_outlier_unpaired_and_respects_order() -> None:
    z, zp, H, P, R = _row_of_landmarks()
    z = np.vstack([z[[2, 0]], [[1.1, 3.0]], z[[3, 1]]])  # shuffled, plus a spurious observation off the row
    assert jcbb(z, zp, H, P, R).tolist() == [2, 0, -1, 3, 1]
    assert jcbb(np.zeros((0, 2)), zp, H, P, R).tolist() == []
    assert jcbb(z, np.zeros((0, 2)), np.zeros((0, 2, 2)), P, R).tolist() == [-1] * 5


def test_jcbb_rejects_an_individually_compatible_but_jointly_inconsistent_pair() -> None:
    """Irregular landmarks 0..2 seen shifted by +0.6 m (the pose error); a spurious return 0.5 m left of landmark 3's
    prediction is individually compatible with it, but not with the common shift the other three imply."""
    _, _, H, P, R = _row_of_landmarks()
    lms = np.array([[0.0, 0.0], [1.0, 0.0], [2.3, 0.0], [3.9, 0.0]])
    zp = lms.copy()  # estimated robot at the origin
    shift = np.array([0.6, 0.0])
    z = np.vstack([lms[:3] + shift, zp[3] - np.array([0.5, 0.0])])
    S = H @ P @ H.transpose(0, 2, 1) + R
    assert pairwise_mahalanobis(z, zp, S)[3, 3] < chi2_gate(0.99, 2)
    assert jcbb(z, zp, H, P, R).tolist() == [0, 1, 2, -1]

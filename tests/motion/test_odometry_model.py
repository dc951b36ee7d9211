"""Odometry motion model: decomposition, sampling statistics and likelihood."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.motion import apply_odometry_delta, odometry_delta, odometry_likelihood, sample_odometry_motion


def test_delta_hand_worked() -> None:
    np.testing.assert_allclose(
        odometry_delta((0.0, 0.0, 0.0), (1.0, 1.0, math.pi / 2)), [math.pi / 4, math.sqrt(2), math.pi / 4]
    )


def test_delta_pure_rotation_puts_turn_in_rot2() -> None:
    np.testing.assert_allclose(odometry_delta((1.0, 2.0, 0.3), (1.0, 2.0, 1.0)), [0.0, 0.0, 0.7], atol=1e-15)


def test_delta_backwards_motion_wraps() -> None:
    rot1, trans, rot2 = odometry_delta((0.0, 0.0, 0.0), (-1.0, 0.0, 0.0))
    assert abs(rot1) == pytest.approx(math.pi)
    assert trans == pytest.approx(1.0)
    assert abs(rot2) == pytest.approx(math.pi)


def test_apply_inverts_delta() -> None:
    rng = np.random.default_rng(5)
    for _ in range(20):
        a = rng.uniform(-3, 3, 3)
        b = rng.uniform(-3, 3, 3)
        out = apply_odometry_delta(a, odometry_delta(a, b))
        np.testing.assert_allclose(out[:2], b[:2], atol=1e-12)
        assert math.isclose(math.remainder(out[2] - b[2], 2 * math.pi), 0.0, abs_tol=1e-12)


def test_noise_free_sample_moves_pose_by_relative_motion() -> None:
    # odometry says "1 m forward"; a particle facing +y moves 1 m along +y
    out = sample_odometry_motion(
        np.array([[5.0, 5.0, math.pi / 2]]), (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), [0, 0, 0, 0], np.random.default_rng(0)
    )
    np.testing.assert_allclose(out, [[5.0, 6.0, math.pi / 2]], atol=1e-12)


def test_translation_noise_variance() -> None:
    # (0,0,0) -> (2,0,0): δ_rot1 = δ_rot2 = 0, δ_trans = 2; only α3 -> var(trans) = α3·4
    rng = np.random.default_rng(21)
    out = sample_odometry_motion(np.zeros((40_000, 3)), (0, 0, 0), (2, 0, 0), [0, 0, 0.01, 0], rng)
    assert np.all(out[:, 1] == 0.0)
    assert out[:, 0].mean() == pytest.approx(2.0, abs=0.004)
    assert out[:, 0].var() == pytest.approx(0.04, rel=0.04)


def test_rotation_noise_variance_from_translation() -> None:
    # only α2: var(rot1) = var(rot2) = α2 δ_trans², the final heading has the sum of both variances
    rng = np.random.default_rng(22)
    out = sample_odometry_motion(np.zeros((40_000, 3)), (0, 0, 0), (1, 0, 0), [0, 0.02, 0, 0], rng)
    assert out[:, 2].var() == pytest.approx(0.04, rel=0.04)


def test_likelihood_peak_hand_worked() -> None:
    # odometry 1 m straight; hypothesis identical; α = 0.1 each: the three variances are 0.1
    p = odometry_likelihood((1.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0, 0, 0), (1, 0, 0), [0.1, 0.1, 0.1, 0.1])
    assert float(p) == pytest.approx((2 * math.pi * 0.1) ** -1.5, rel=1e-12)


def test_likelihood_prefers_consistent_poses_and_vectorises() -> None:
    alphas = [0.05, 0.05, 0.05, 0.05]
    cands = np.array([[1.0, 0.0, 0.0], [1.3, 0.0, 0.0], [1.0, 0.4, 0.0], [1.0, 0.0, 0.5]])
    p = odometry_likelihood(cands, (0.0, 0.0, 0.0), (0, 0, 0), (1, 0, 0), alphas)
    assert p.shape == (4,)
    assert p[0] > p[1] and p[0] > p[2] and p[0] > p[3]
    assert float(odometry_likelihood(cands[1], (0, 0, 0), (0, 0, 0), (1, 0, 0), alphas)) == pytest.approx(p[1])


def test_bad_alphas() -> None:
    with pytest.raises(ValueError, match="4 alpha"):
        sample_odometry_motion((0, 0, 0), (0, 0, 0), (1, 0, 0), [0.1, 0.1], np.random.default_rng(0))

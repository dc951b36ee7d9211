"""The seed's simplified model and the differential-drive kinematics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.motion import DiffDriveKinematics, sample_simple_motion, simple_motion, velocity_motion


def test_simple_motion_straight_then_rotate() -> None:
    np.testing.assert_allclose(simple_motion((1.0, 2.0, math.pi / 2), 2.0, 0.5), [1.0, 4.0, math.pi / 2 + 0.5])
    np.testing.assert_allclose(simple_motion((0.0, 0.0, 0.0), -1.0, 0.0), [-1.0, 0.0, 0.0])


def test_simple_motion_sampling_statistics() -> None:
    rng = np.random.default_rng(2)
    out = sample_simple_motion(np.zeros((40_000, 3)), 1.0, 0.2, 0.1, 0.05, rng)
    assert out[:, 0].std() == pytest.approx(0.1, rel=0.03)
    assert out[:, 2].mean() == pytest.approx(0.2, abs=0.002)
    assert out[:, 2].std() == pytest.approx(0.05, rel=0.03)


DD = DiffDriveKinematics(wheel_diameter_m=0.1, wheel_separation_m=0.3)


def test_forward_kinematics_hand_worked() -> None:
    assert DD.body_twist(10.0, 10.0) == pytest.approx((0.5, 0.0))  # v = 0.1/4 · 20
    assert DD.body_twist(10.0, -10.0) == pytest.approx((0.0, 0.1 / 0.6 * 20.0))  # ω = W/(2L) · 20
    v, w = DD.body_twist(12.0, 8.0)
    assert (v, w) == pytest.approx((0.5, 0.1 / 0.6 * 4.0))
    assert DD.turning_radius(v, w) == pytest.approx(0.75)
    v, w = DD.body_twist(8.0, 12.0)  # mirrored: right turn, negative radius
    assert DD.turning_radius(v, w) == pytest.approx(-0.75)


def test_turning_radius_edge_cases() -> None:
    assert DD.turning_radius(0.5, 0.0) == math.inf
    assert DD.turning_radius(-0.5, 0.0) == -math.inf
    assert DD.turning_radius(0.0, 1.0) == 0.0


def test_inverse_round_trip() -> None:
    for right, left in [(3.0, 7.0), (-2.0, 5.0), (0.0, 0.0), (10.0, 10.0)]:
        assert DD.wheel_rates(*DD.body_twist(right, left)) == pytest.approx((right, left))
    assert DD.wheel_rates(0.5, 0.0) == pytest.approx((10.0, 10.0))
    v, w = DD.body_twists(np.array([12.0, 10.0]), np.array([8.0, -10.0]))
    np.testing.assert_allclose(v, [0.5, 0.0])
    np.testing.assert_allclose(w, [0.1 / 0.6 * 4.0, 0.1 / 0.6 * 20.0])


def test_limit_wheel_rates_keeps_curvature() -> None:
    v, w = DD.limit_wheel_rates(1.0, 2.0, 10.0)  # wheels (2+0.6)/0.1 = 26 and 14 rad/s -> scale 10/26
    assert max(abs(r) for r in DD.wheel_rates(v, w)) == pytest.approx(10.0)
    assert w / v == pytest.approx(2.0)
    assert DD.limit_wheel_rates(0.1, 0.1, 10.0) == (0.1, 0.1)


def test_encoder_odometry_quarter_circle() -> None:
    # quarter circle of radius 1: Δs = π/2, Δθ = π/2 -> ΔR + ΔL = 4Δs/W = 20π, ΔR - ΔL = 2LΔθ/W = 3π
    out = DD.integrate_encoders((0.0, 0.0, 0.0), 11.5 * math.pi, 8.5 * math.pi)
    np.testing.assert_allclose(out, [1.0, 1.0, math.pi / 2], atol=1e-12)
    np.testing.assert_allclose(out, velocity_motion((0.0, 0.0, 0.0), 1.0, 1.0, math.pi / 2), atol=1e-12)


def test_encoder_odometry_straight_and_spin() -> None:
    np.testing.assert_allclose(DD.integrate_encoders((1.0, 1.0, math.pi), 20.0, 20.0), [0.0, 1.0, -math.pi], atol=1e-12)
    out = DD.integrate_encoders((2.0, 3.0, 0.5), 6 * math.pi, -6 * math.pi)  # Δθ = 2π on the spot
    np.testing.assert_allclose(out[:2], [2.0, 3.0], atol=1e-12)
    assert math.isclose(math.remainder(out[2] - 0.5, 2 * math.pi), 0.0, abs_tol=1e-12)


def test_bad_geometry() -> None:
    with pytest.raises(ValueError, match="wheel_diameter_m"):
        DiffDriveKinematics(0.0, 0.3)
    with pytest.raises(ValueError, match="wheel_separation_m"):
        DiffDriveKinematics(0.1, math.nan)

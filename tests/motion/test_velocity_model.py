"""Velocity motion model: hand-worked arcs and sampling statistics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.geometry import Pose2D
from mjnav.motion import sample_velocity_motion, velocity_motion


def test_quarter_circle_left() -> None:
    # v = 1 m/s, ω = 1 rad/s -> radius 1 m, centre (0, 1); after π/2 s the robot is at (1, 1) facing +y
    np.testing.assert_allclose(velocity_motion((0.0, 0.0, 0.0), 1.0, 1.0, math.pi / 2), [1.0, 1.0, math.pi / 2])


def test_quarter_circle_right() -> None:
    np.testing.assert_allclose(
        velocity_motion((0.0, 0.0, 0.0), 1.0, -1.0, math.pi / 2), [1.0, -1.0, -math.pi / 2], atol=1e-12
    )


def test_arc_from_rotated_pose_matches_book_formula() -> None:
    x, y, th, v, w, dt = 2.0, -1.0, 0.7, 0.8, 0.4, 1.3
    r = v / w
    expected = [
        x - r * math.sin(th) + r * math.sin(th + w * dt),
        y + r * math.cos(th) - r * math.cos(th + w * dt),
        th + w * dt,
    ]
    np.testing.assert_allclose(velocity_motion(Pose2D(x, y, th), v, w, dt), expected, atol=1e-12)


def test_straight_line_and_its_limit() -> None:
    np.testing.assert_allclose(velocity_motion((1.0, 2.0, math.pi / 2), 0.5, 0.0, 4.0), [1.0, 4.0, math.pi / 2])
    tiny = velocity_motion((1.0, 2.0, 0.3), 0.5, 1e-10, 4.0)
    np.testing.assert_allclose(tiny, velocity_motion((1.0, 2.0, 0.3), 0.5, 0.0, 4.0), atol=1e-9)


def test_spin_in_place_and_wrap() -> None:
    out = velocity_motion((3.0, 4.0, 3.0), 0.0, 1.0, 1.0)
    np.testing.assert_allclose(out, [3.0, 4.0, 4.0 - 2 * math.pi])


def test_vectorised_rows_match_single_calls() -> None:
    poses = np.array([[0.0, 0.0, 0.0], [1.0, -2.0, 2.5], [-3.0, 0.5, -1.0]])
    out = velocity_motion(poses, 0.7, -0.3, 2.0)
    for row, pose in zip(out, poses, strict=True):
        np.testing.assert_allclose(row, velocity_motion(pose, 0.7, -0.3, 2.0))


def test_sampling_translation_noise_variance() -> None:
    # only α1: v̂ ~ N(v, α1 v²); with ω̂ = 0 the robot moves v̂·Δt along +x
    rng = np.random.default_rng(7)
    v, dt, a1 = 2.0, 0.5, 0.04
    out = sample_velocity_motion(np.zeros((40_000, 3)), v, 0.0, dt, [a1, 0, 0, 0, 0, 0], rng)
    assert np.all(out[:, 1] == 0.0) and np.all(out[:, 2] == 0.0)
    assert out[:, 0].mean() == pytest.approx(v * dt, abs=0.003)
    assert out[:, 0].var() == pytest.approx(a1 * v * v * dt * dt, rel=0.04)


def test_sampling_final_rotation_noise_variance() -> None:
    # only α5, α6: γ̂ ~ N(0, α5 v² + α6 ω²) changes θ' by γ̂Δt but not the position
    rng = np.random.default_rng(11)
    v, w, dt = 1.0, 0.5, 2.0
    a = [0, 0, 0, 0, 0.01, 0.04]
    out = sample_velocity_motion(np.zeros((40_000, 3)), v, w, dt, a, rng)
    expected_xy = velocity_motion((0.0, 0.0, 0.0), v, w, dt)[:2]
    np.testing.assert_allclose(out[:, :2], np.broadcast_to(expected_xy, (40_000, 2)), atol=1e-12)
    assert out[:, 2].mean() == pytest.approx(w * dt, abs=0.005)
    assert out[:, 2].var() == pytest.approx((0.01 * v * v + 0.04 * w * w) * dt * dt, rel=0.04)


def test_sampling_is_reproducible_with_seed() -> None:
    a = [0.1, 0.01, 0.02, 0.1, 0.01, 0.01]
    s1 = sample_velocity_motion(np.zeros((5, 3)), 1.0, 0.5, 0.1, a, np.random.default_rng(3))
    s2 = sample_velocity_motion(np.zeros((5, 3)), 1.0, 0.5, 0.1, a, np.random.default_rng(3))
    np.testing.assert_array_equal(s1, s2)


def test_bad_input() -> None:
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="6 alpha"):
        sample_velocity_motion((0, 0, 0), 1.0, 0.0, 0.1, [0.1] * 5, rng)
    with pytest.raises(ValueError, match=">= 0"):
        sample_velocity_motion((0, 0, 0), 1.0, 0.0, 0.1, [-0.1] + [0.0] * 5, rng)
    with pytest.raises(ValueError, match="non-finite"):
        velocity_motion((0, math.nan, 0), 1.0, 0.0, 0.1)
    with pytest.raises(ValueError, match="shape"):
        velocity_motion((0, 0), 1.0, 0.0, 0.1)
    with pytest.raises(ValueError, match="dt"):
        velocity_motion((0, 0, 0), 1.0, 0.0, -0.1)

"""The regulation terms of pure pursuit, one by one, on hand-worked numbers."""

from __future__ import annotations

import math

import pytest

from mjnav.control import (
    adaptive_lookahead,
    angular_velocity,
    approach_regulated_speed,
    clamp_yaw_rate,
    curvature_regulated_speed,
    proximity_regulated_speed,
    pursuit_curvature,
    rotate_in_place_rate,
)


def test_adaptive_lookahead_clamps() -> None:
    assert adaptive_lookahead(0.5, 1.5, 0.3, 1.5) == pytest.approx(0.75)
    assert adaptive_lookahead(0.1, 1.5, 0.3, 1.5) == pytest.approx(0.3)
    assert adaptive_lookahead(2.0, 1.5, 0.3, 1.5) == pytest.approx(1.5)
    assert adaptive_lookahead(-0.5, 1.5, 0.3, 1.5) == pytest.approx(0.75)


def test_pursuit_curvature_and_yaw_rate() -> None:
    assert pursuit_curvature(0.2, 1.0) == pytest.approx(0.4)  # 2 y' / L²
    assert pursuit_curvature(-0.3, 0.5) == pytest.approx(-2.4)
    assert angular_velocity(-2.4, 0.25) == pytest.approx(-0.6)


def test_curvature_heuristic_both_directions() -> None:
    assert curvature_regulated_speed(0.5, 0.8, 1.0) == 0.5  # below κ_h: unchanged
    assert curvature_regulated_speed(0.5, 2.0, 1.0) == pytest.approx(0.25)  # v κ_h / κ
    assert curvature_regulated_speed(0.5, -2.0, 1.0) == pytest.approx(0.25)  # right turn, |κ|
    assert curvature_regulated_speed(0.5, 10.0, 1.0, 0.1) == pytest.approx(0.1)  # floor
    assert curvature_regulated_speed(0.05, 10.0, 1.0, 0.1) == pytest.approx(0.05)  # floor never exceeds v


def test_proximity_heuristic() -> None:
    assert proximity_regulated_speed(0.5, math.inf, 0.7) == 0.5
    assert proximity_regulated_speed(0.5, 0.7, 0.7) == pytest.approx(0.5)
    assert proximity_regulated_speed(0.5, 0.35, 0.7) == pytest.approx(0.25)  # v d_O / d_prox
    assert proximity_regulated_speed(0.5, -0.1, 0.7) == 0.0


def test_approach_slow_down() -> None:
    assert approach_regulated_speed(0.5, 2.0, 0.6, 0.05) == 0.5
    assert approach_regulated_speed(0.5, 0.3, 0.6, 0.05) == pytest.approx(0.25)
    assert approach_regulated_speed(0.5, 0.01, 0.6, 0.05) == pytest.approx(0.05)


def test_rotate_in_place_and_clamp() -> None:
    assert rotate_in_place_rate(0.2, 2.0, 1.0) == pytest.approx(0.4)
    assert rotate_in_place_rate(-2.0, 2.0, 1.0) == pytest.approx(-1.0)
    v, w = clamp_yaw_rate(0.5, 3.0, 1.5)  # κ = 6 kept: v = 0.25
    assert (v, w) == pytest.approx((0.25, 1.5))
    assert clamp_yaw_rate(0.5, -3.0, 1.5) == pytest.approx((0.25, -1.5))
    assert clamp_yaw_rate(0.5, 1.0, 1.5) == (0.5, 1.0)

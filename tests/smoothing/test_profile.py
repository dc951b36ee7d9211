"""Speed profile from curvature and acceleration limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.smoothing import SpeedLimits, cumulative_length, profile_times, velocity_profile


def test_straight_line_trapezoid_hand_worked() -> None:
    p = np.c_[np.linspace(0.0, 4.0, 41), np.zeros(41)]
    lim = SpeedLimits(max_speed_mps=1.0, max_accel_mps2=0.5, max_decel_mps2=0.25, max_lateral_accel_mps2=1.0)
    v = velocity_profile(p, lim)
    s = cumulative_length(p)
    expected = np.minimum.reduce([np.full_like(s, 1.0), np.sqrt(2 * 0.5 * s), np.sqrt(2 * 0.25 * (4.0 - s))])
    np.testing.assert_allclose(v, expected, atol=1e-12)
    assert v[0] == 0.0 and v[-1] == 0.0
    assert v.max() == pytest.approx(1.0)


def test_start_and_end_speeds() -> None:
    p = np.c_[np.linspace(0.0, 10.0, 101), np.zeros(101)]
    v = velocity_profile(p, SpeedLimits(max_speed_mps=1.0), start_speed_mps=0.6, end_speed_mps=0.3)
    assert v[0] == pytest.approx(0.6)
    assert v[-1] == pytest.approx(0.3)
    assert v[50] == pytest.approx(1.0)


def test_curvature_and_yaw_rate_caps_both_directions() -> None:
    a = np.linspace(0.0, 2 * math.pi, 400)
    ccw = np.c_[np.cos(a), np.sin(a)]  # radius 1, κ = +1
    cw = ccw * [1.0, -1.0]  # κ = -1
    lim = SpeedLimits(max_speed_mps=2.0, max_accel_mps2=10.0, max_decel_mps2=10.0, max_lateral_accel_mps2=0.25)
    for path in (ccw, cw):
        v = velocity_profile(path, lim, start_speed_mps=2.0, end_speed_mps=2.0)
        np.testing.assert_allclose(v[5:-5], 0.5, rtol=1e-4)  # sqrt(a_lat / |κ|)
    lim_w = SpeedLimits(
        max_speed_mps=2.0,
        max_accel_mps2=10.0,
        max_decel_mps2=10.0,
        max_lateral_accel_mps2=100.0,
        max_yaw_rate_radps=0.3,
    )
    np.testing.assert_allclose(velocity_profile(cw, lim_w, start_speed_mps=2.0)[5:-5], 0.3, rtol=1e-4)


def test_profile_times() -> None:
    p = np.c_[np.linspace(0.0, 1.0, 11), np.zeros(11)]
    np.testing.assert_allclose(profile_times(p, np.full(11, 0.5)), np.linspace(0.0, 2.0, 11))
    # accelerating from 0 at 0.5 m/s²: 1 m takes 2 s
    v = velocity_profile(p, SpeedLimits(max_speed_mps=5.0, max_accel_mps2=0.5, max_decel_mps2=50.0), end_speed_mps=5.0)
    assert profile_times(p, v)[-1] == pytest.approx(2.0, rel=1e-9)


def test_bad_limits_and_speeds() -> None:
    with pytest.raises(ValueError, match="max_accel_mps2"):
        SpeedLimits(max_accel_mps2=0.0)
    p = np.c_[np.linspace(0.0, 1.0, 5), np.zeros(5)]
    with pytest.raises(ValueError, match="start_speed_mps"):
        velocity_profile(p, start_speed_mps=-1.0)
    with pytest.raises(ValueError, match="curvature_invm"):
        velocity_profile(p, curvature_invm=np.zeros(3))

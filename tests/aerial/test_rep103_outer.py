"""REP-103 boundary conversions and the LQR / H∞ outer loops."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.aerial import (
    PID,
    CascadeController,
    CascadeGains,
    InvalidParameterError,
    QuadrotorParams,
    RptController,
    check_loop_separation,
    euler_from_quat,
    quat_to_rotation,
    rpt_poles,
)
from mjnav.aerial.outer import hinf_outer_gains, lqr_outer_gains, outer_plant, pid_outer_gains
from mjnav.aerial.rep103 import (
    enu_to_ned,
    flu_to_frd,
    kinematic_accel_ned,
    ned_to_enu,
    quat_enu_flu_to_ned_frd,
    quat_ned_frd_to_enu_flu,
)


def test_kinematic_accel_ned_matches_converting_each_sample_to_ned_frd() -> None:
    rng = np.random.default_rng(4)
    quats = rng.normal(size=(6, 4))
    quats /= np.linalg.norm(quats, axis=1)[:, None]
    forces = rng.normal(size=(6, 3)) * 5.0
    got = kinematic_accel_ned(quats * 2.0, forces, 9.81)  # the attitudes are normalised first
    for q, f, a in zip(quats, forces, got, strict=True):
        expected = quat_to_rotation(quat_enu_flu_to_ned_frd(q)) @ flu_to_frd(f) + [0.0, 0.0, 9.81]
        np.testing.assert_allclose(a, expected, atol=1e-12)
    level = kinematic_accel_ned([[1.0, 0.0, 0.0, 0.0]], [[0.0, 0.0, 9.81]], 9.81)  # at rest: no acceleration
    np.testing.assert_allclose(level, [[0.0, 0.0, 0.0]], atol=1e-12)
    with pytest.raises(ValueError, match="as many"):
        kinematic_accel_ned(quats, forces[:2], 9.81)


def test_enu_ned_and_flu_frd_swap_axes() -> None:
    np.testing.assert_array_equal(enu_to_ned([1.0, 2.0, 3.0]), [2.0, 1.0, -3.0])
    np.testing.assert_array_equal(ned_to_enu(enu_to_ned([[1.0, 2.0, 3.0]])), [[1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(flu_to_frd([1.0, 2.0, 3.0]), [1.0, -2.0, -3.0])


def test_attitude_conversion_rotates_vectors_consistently() -> None:
    # level, nose east in ENU/FLU = yaw +90° in NED/FRD
    np.testing.assert_allclose(euler_from_quat(quat_enu_flu_to_ned_frd([1.0, 0.0, 0.0, 0.0])), [0, 0, math.pi / 2])
    rng = np.random.default_rng(4)
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        v = rng.normal(size=3)
        qn = quat_enu_flu_to_ned_frd(q)
        # a body vector mapped to the world agrees in both conventions
        np.testing.assert_allclose(quat_to_rotation(qn) @ flu_to_frd(v), enu_to_ned(quat_to_rotation(q) @ v))
        back = quat_ned_frd_to_enu_flu(qn)
        np.testing.assert_allclose(back * math.copysign(1.0, back @ q), q, atol=1e-12)


@pytest.mark.parametrize("design", [lqr_outer_gains, hinf_outer_gains])
def test_outer_loop_designs_are_stable_and_fit_the_cascade(design: object) -> None:
    gains = design()  # type: ignore[operator]
    a, b = outer_plant()
    k = np.array([[gains.ki, gains.kp, gains.kd]])
    closed = np.linalg.eigvals(a - b @ k)
    assert np.all(closed.real < 0)
    np.testing.assert_allclose(np.sort_complex(closed), np.sort_complex(rpt_poles(gains)), atol=1e-9)
    stiff = CascadeGains(att_p=(20.0, 20.0, 3.0), rate_p=(60.0, 60.0, 10.0), rate_d=(0.5, 0.5, 0.0))
    CascadeController(QuadrotorParams(), stiff, outer=RptController(gains))  # passes the separation check


def test_outer_loop_tracks_a_ramp_under_a_constant_disturbance() -> None:
    """Integral action: a ramp reference under a constant acceleration disturbance is tracked without offset."""
    for gains in (lqr_outer_gains(), hinf_outer_gains()):
        ctl = RptController(gains)
        pos, vel, dt = np.zeros(3), np.zeros(3), 0.002
        for k in range(round(15.0 / dt)):
            t = k * dt
            ref, vref = np.full(3, 0.5 * t), np.full(3, 0.5)
            u = ctl.update(ref, vref, np.zeros(3), pos, vel, dt) + np.array([0.4, -0.3, 0.2])
            vel = vel + u * dt
            pos = pos + vel * dt
        assert np.max(np.abs(pos - 0.5 * 15.0)) < 0.01


def test_outer_loop_weights_are_checked() -> None:
    with pytest.raises(InvalidParameterError):
        lqr_outer_gains(r=0.0)
    with pytest.raises(InvalidParameterError):
        hinf_outer_gains(q_pos=-1.0)


def test_pid_cascade_gains_follow_from_loop_separation() -> None:
    stiff = CascadeGains(att_p=(20.0, 20.0, 3.0), rate_p=(60.0, 60.0, 10.0), rate_d=(0.5, 0.5, 0.0))
    bandwidth = CascadeController(QuadrotorParams(), stiff).attitude_bandwidth_rad_s()
    g = pid_outer_gains(bandwidth, separation=4.0, integral_separation=5.0)
    assert g.vel_p == pytest.approx(bandwidth / 4.0) and g.pos_p == pytest.approx(bandwidth / 16.0)
    assert g.vel_i / g.vel_p == pytest.approx(g.vel_p / 5.0)
    # the law a = a_r + vel_p (pos_p e + ė) + vel_i ∫(pos_p e + ė) on the double integrator: stable, and every pole
    # well inside the attitude loop's bandwidth
    poles = np.roots([1.0, g.vel_p, g.vel_p * g.pos_p + g.vel_i, g.vel_i * g.pos_p])
    assert np.all(poles.real < 0)
    check_loop_separation(poles, bandwidth, 1.5)
    slower = pid_outer_gains(bandwidth, separation=5.0)
    assert slower.vel_p < g.vel_p and slower.pos_p < g.pos_p


def test_pid_cascade_tracks_a_ramp_under_a_constant_disturbance() -> None:
    """The velocity integrator removes a constant acceleration disturbance (wind) from a ramp's tracking."""
    g = pid_outer_gains(40.0)
    vel_loop = PID(g.vel_p, g.vel_i)
    pos, vel, dt = np.zeros(3), np.zeros(3), 0.002
    for k in range(round(15.0 / dt)):
        t = k * dt
        ref, vref = np.full(3, 0.5 * t), np.full(3, 0.5)
        u = vel_loop.update(g.pos_p * (ref - pos) + vref, vel, dt) + np.array([0.4, -0.3, 0.2])
        vel = vel + u * dt
        pos = pos + vel * dt
    assert np.max(np.abs(pos - 0.5 * 15.0)) < 0.01


@pytest.mark.parametrize(("bandwidth", "separation"), [(0.0, 4.0), (math.inf, 4.0), (40.0, 1.0), (40.0, math.nan)])
def test_pid_cascade_gains_are_checked(bandwidth: float, separation: float) -> None:
    with pytest.raises(InvalidParameterError):
        pid_outer_gains(bandwidth, separation)

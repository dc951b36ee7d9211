"""Quadrotor model: hover equilibrium, the X mixer, motor lag, and the hover linearisation against the model."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mjnav.aerial import (
    InvalidParameterError,
    QuadrotorParams,
    euler_rates,
    hover_linearization,
    hover_state,
    mix,
    mixer_matrix,
    quadrotor_derivative,
    quadrotor_step,
    quat_from_euler,
    rotor_speeds_for_thrusts,
    wrench_from_rotor_speeds,
)

P = QuadrotorParams()


def test_defaults_are_a_one_kilogram_x_quad() -> None:
    assert P.mass_kg == 1.0 and P.arm_length_m > 0.1
    assert 2.0 < 4 * P.max_rotor_thrust_n / P.hover_thrust_n < 6.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        P.mass_kg = 2.0  # type: ignore[misc]
    with pytest.raises(InvalidParameterError):
        QuadrotorParams(mass_kg=-1.0)
    with pytest.raises(InvalidParameterError):
        QuadrotorParams(inertia_kgm2=(0.01, 0.0, 0.01))
    with pytest.raises(InvalidParameterError):
        QuadrotorParams(mass_kg=20.0)  # cannot lift itself


def test_hover_is_an_equilibrium_and_free_fall_falls() -> None:
    x = hover_state(P, np.array([1.0, 2.0, -3.0]), yaw=0.7)
    np.testing.assert_allclose(quadrotor_derivative(x, x[13:17], P), 0.0, atol=1e-12)
    off = x.copy()
    off[13:17] = 0.0
    d = quadrotor_derivative(off, np.zeros(4), P)
    np.testing.assert_allclose(d[3:6], [0, 0, P.gravity_mps2], atol=1e-12)
    for _ in range(100):
        x = quadrotor_step(x, x[13:17], 0.01, P)
    np.testing.assert_allclose(x[0:3], [1.0, 2.0, -3.0], atol=1e-9)


def test_yaw_only_command_gives_zero_roll_and_pitch_torque() -> None:
    thrusts = mix(P, P.hover_thrust_n, np.array([0.0, 0.0, 0.05]))
    wrench = mixer_matrix(P) @ thrusts
    assert wrench[0] == pytest.approx(P.hover_thrust_n)
    assert abs(wrench[1]) < 1e-12 and abs(wrench[2]) < 1e-12
    assert wrench[3] == pytest.approx(0.05)
    # through the rotor speeds and the rigid body: no roll or pitch acceleration, positive yaw acceleration
    x = hover_state(P)
    x[13:17] = rotor_speeds_for_thrusts(P, thrusts)
    d = quadrotor_derivative(x, x[13:17], P)
    assert abs(d[10]) < 1e-9 and abs(d[11]) < 1e-9 and d[12] > 0.0
    thrust, torque = wrench_from_rotor_speeds(P, x[13:17])
    assert thrust == pytest.approx(P.hover_thrust_n) and torque == pytest.approx([0.0, 0.0, 0.05], abs=1e-12)


def test_mixer_geometry_and_signs() -> None:
    m = mixer_matrix(P)
    d = P.arm_length_m / math.sqrt(2)
    # positive roll torque (right side down) comes from the left rotors (2 front-left, 1 rear-left)
    t = mix(P, P.hover_thrust_n, np.array([0.1, 0.0, 0.0]))
    assert t[1] > t[0] and t[2] > t[3]
    np.testing.assert_allclose(m[1], [-d, d, d, -d])
    # positive pitch (nose up) from the front rotors
    t = mix(P, P.hover_thrust_n, np.array([0.0, 0.1, 0.0]))
    assert t[0] > t[1] and t[2] > t[3]
    # the counter-clockwise pair (0, 1) yaws the body positive
    np.testing.assert_allclose(np.sign(m[3]), [1, 1, -1, -1])


def test_mixer_gives_up_yaw_first_when_saturated() -> None:
    tau = np.array([0.05, -0.03, 0.5])
    t = mix(P, 3.8 * P.max_rotor_thrust_n, tau)
    assert np.all(t >= 0.0) and np.all(t <= P.max_rotor_thrust_n + 1e-12)
    w = mixer_matrix(P) @ t
    np.testing.assert_allclose(w[1:3], tau[:2], atol=1e-12)  # roll and pitch kept exactly
    assert 0.0 <= w[3] < tau[2]
    with pytest.raises(InvalidParameterError):
        mix(P, 1.0, np.zeros(2))


def test_motor_lag_is_first_order() -> None:
    x = hover_state(P)
    w0 = x[13]
    cmd = np.full(4, w0 + 100.0)
    tau = P.motor_time_constant_s
    n = 100
    for _ in range(n):
        x = quadrotor_step(x, cmd, tau / n, P)
    assert x[13] - w0 == pytest.approx(100.0 * (1 - math.exp(-1.0)), rel=1e-6)
    for _ in range(100):
        x = quadrotor_step(x, np.full(4, 5000.0), 0.005, P)
    assert x[13] == pytest.approx(P.max_rotor_speed_rad_s, rel=1e-3)  # commands clipped to the maximum


def _f12(x12: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The nonlinear model in the linearisation's coordinates, rotors at the speeds that make the wrench u."""
    full = np.zeros(17)
    full[0:6] = x12[0:6]
    full[6:10] = quat_from_euler(*x12[6:9])
    full[10:13] = x12[9:12]
    thrusts = np.linalg.solve(mixer_matrix(P), np.array([P.hover_thrust_n + u[0], *u[1:]]))
    full[13:17] = rotor_speeds_for_thrusts(P, thrusts)
    d = quadrotor_derivative(full, full[13:17], P)
    return np.concatenate([d[0:6], euler_rates(x12[6], x12[7], *x12[9:12]), d[10:13]])


def test_hover_linearization_matches_the_model() -> None:
    a, b = hover_linearization(P)
    x0, u0 = np.zeros(12), np.zeros(4)
    h = 1e-6
    a_num = np.column_stack([(_f12(x0 + h * e, u0) - _f12(x0 - h * e, u0)) / (2 * h) for e in np.eye(12)])
    b_num = np.column_stack([(_f12(x0, u0 + h * e) - _f12(x0, u0 - h * e)) / (2 * h) for e in np.eye(4)])
    np.testing.assert_allclose(a, a_num, atol=1e-6)
    np.testing.assert_allclose(b, b_num, atol=1e-6)
    assert a[3, 7] == pytest.approx(-P.gravity_mps2) and a[4, 6] == pytest.approx(P.gravity_mps2)

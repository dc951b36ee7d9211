"""Control: PID details, the cascade on the nonlinear model, LQR/H∞ synthesis, margins, RPT and loop separation."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg

from mjnav.aerial import (
    PID,
    CascadeController,
    DesignError,
    LoopSeparationError,
    QuadrotorParams,
    RptController,
    check_loop_separation,
    closed_loop_bandwidth,
    euler_from_quat,
    hinf_norm,
    hinf_state_feedback,
    hover_linearization,
    hover_lqr,
    hover_state,
    loop_margins,
    lqr,
    quadrotor_step,
    quat_from_euler,
    rpt_gains,
    rpt_poles,
)

P = QuadrotorParams()


def _attitude_axis() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Roll axis with the motor lag: x = [roll, p, torque], u = torque command, w = disturbance torque."""
    j, tm = P.inertia_kgm2[0], P.motor_time_constant_s
    a = np.array([[0, 1, 0], [0, 0, 1 / j], [0, 0, -1 / tm]])
    return a, np.array([[0], [0], [1 / tm]]), np.array([[0], [1 / j], [0]])


def test_pid_derivative_on_measurement_and_filter() -> None:
    pid = PID(1.0, 0.0, 0.5, dim=1)
    pid.update([0.0], [0.0], 0.01)
    out = pid.update([10.0], [0.0], 0.01)  # a setpoint step: no derivative kick
    assert out[0] == pytest.approx(10.0)
    out = pid.update([10.0], [0.1], 0.01)  # measurement rising at 10/s: derivative -5
    assert out[0] == pytest.approx(9.9 - 5.0)
    filt = PID(0.0, 0.0, 1.0, dim=1, d_cutoff_hz=5.0)
    raw = PID(0.0, 0.0, 1.0, dim=1)
    rng = np.random.default_rng(0)
    f_out, r_out = [], []
    for _ in range(500):
        y = rng.normal(scale=0.01, size=1)
        f_out.append(filt.update([0.0], y, 0.002)[0])
        r_out.append(raw.update([0.0], y, 0.002)[0])
    assert np.std(f_out) < 0.2 * np.std(r_out)


def test_pid_anti_windup() -> None:
    pid = PID(1.0, 10.0, 0.0, dim=1, output_limit=1.0, integral_limit=0.5)
    for _ in range(1000):
        out = pid.update([5.0], [0.0], 0.01)
    assert out[0] == 1.0
    assert pid.integral[0] == pytest.approx(0.0)  # never integrated while saturated (error pushing outwards)
    pid2 = PID(0.1, 10.0, 0.0, dim=1, integral_limit=0.5)
    for _ in range(1000):
        pid2.update([1.0], [0.0], 0.01)
    assert pid2.integral[0] == pytest.approx(0.5)  # clamped
    with pytest.raises(ValueError):
        pid2.update([1.0], [0.0], 0.0)


def _fly(
    ctl: CascadeController, plant: QuadrotorParams, x: np.ndarray, seconds: float, sp: np.ndarray, yaw_sp: float
) -> tuple[np.ndarray, np.ndarray]:
    dt = 0.002
    traj = []
    for _ in range(round(seconds / dt)):
        u = ctl.update(x, sp, yaw_sp, dt)
        x = quadrotor_step(x, u, dt, plant)
        traj.append(x[0:3].copy())
    return x, np.array(traj)


def test_cascade_recovers_and_holds_hover() -> None:
    x = hover_state(P, np.array([0.3, -0.2, -1.0]))
    x[6:10] = quat_from_euler(0.3, -0.25, 0.2)
    x[10:13] = [1.0, -0.5, 0.3]
    ctl = CascadeController(P)
    x, traj = _fly(ctl, P, x, 8.0, np.array([0.0, 0.0, -1.0]), 0.0)
    assert np.max(np.abs(traj[-500:] - [0.0, 0.0, -1.0])) < 0.02
    np.testing.assert_allclose(euler_from_quat(x[6:10]), 0.0, atol=1e-2)
    assert np.max(np.abs(x[3:6])) < 0.02


def test_cascade_tracks_a_position_step_with_a_heavier_plant() -> None:
    heavy = QuadrotorParams(mass_kg=1.2)  # the controller believes 1.0 kg: the integrators must absorb it
    x = hover_state(heavy)
    ctl = CascadeController(P)
    sp = np.array([2.0, -1.0, -1.5])
    x, traj = _fly(ctl, heavy, x, 8.0, sp, 0.5)
    err = np.linalg.norm(traj - sp, axis=1)
    settled = np.flatnonzero(err > 0.05 * np.linalg.norm(sp))
    assert settled[-1] * 0.002 < 6.0  # within 5% after 6 s
    overshoot = np.max((traj[:, 0] - sp[0]) / sp[0])
    assert overshoot < 0.15
    assert np.max(np.abs(traj[-250:] - sp)) < 0.02
    assert euler_from_quat(x[6:10])[2] == pytest.approx(0.5, abs=0.01)


def test_lqr_matches_scipy_and_has_guaranteed_margins() -> None:
    a, b = hover_linearization(P)
    q = np.diag([1, 1, 1, 0.5, 0.5, 0.5, 1, 1, 1, 0.1, 0.1, 0.1])
    r = np.diag([0.1, 10.0, 10.0, 10.0])
    d = hover_lqr(P, q, r)
    s = scipy.linalg.solve_continuous_are(a, b, q, r)
    np.testing.assert_allclose(d.S, s, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(d.K, np.linalg.solve(r, b.T @ s), rtol=1e-8, atol=1e-10)
    assert np.all(d.poles.real < 0)
    for ch in range(4):
        m = loop_margins(a, b, d.K, channel=ch)
        assert m.phase_margin_deg >= 60.0 - 1e-6  # Kalman's inequality: PM >= 60°, GM in [-6 dB, inf)
        assert m.gain_reduction_margin_db <= -6.0 + 1e-6 and m.meets()
    with pytest.raises(DesignError):
        lqr(np.eye(2), np.zeros((2, 1)), np.eye(2), np.eye(1))  # unstable and uncontrollable


def test_margins_of_a_known_loop() -> None:
    """L(s) = 2/(s+1)³: GM = 20 log10(8/2) dB at √3 rad/s, PM = 180° - 3 atan(ωc) with (ωc²+1)^1.5 = 2."""
    a = np.array([[-1.0, 1.0, 0.0], [0.0, -1.0, 1.0], [0.0, 0.0, -1.0]])
    b = np.array([[0.0], [0.0], [1.0]])
    m = loop_margins(a, b, np.array([[2.0, 0.0, 0.0]]))
    wc = math.sqrt(2 ** (2 / 3) - 1)
    assert m.gain_margin_db == pytest.approx(20 * math.log10(4.0), abs=1e-6)
    assert m.crossover_rad_s == pytest.approx(wc, rel=1e-6)
    assert m.phase_margin_deg == pytest.approx(180 - 3 * math.degrees(math.atan(wc)), abs=1e-6)
    lagged = loop_margins(a, b, np.array([[2.0, 0.0, 0.0]]), actuator_lag_s=0.5)
    assert lagged.phase_margin_deg < m.phase_margin_deg and lagged.gain_margin_db < m.gain_margin_db


def test_hinf_state_feedback_bound_and_optimum() -> None:
    a, b2, b1 = _attitude_axis()
    q, r = np.diag([1.0, 0.01, 0.0]), np.array([[3e-3]])
    d = hinf_state_feedback(a, b2, b1, q, r)
    assert d.gamma == pytest.approx(1.2 * d.gamma_opt)
    assert np.all(d.poles.real < 0)
    # the closed loop w -> z = [Q½ x; R½ u] has H∞ norm below γ, and close to γ_opt for a design at it
    cz = np.vstack([np.sqrt(q), -np.sqrt(r) @ d.K])
    norm = hinf_norm(a - b2 @ d.K, b1, cz)
    assert norm <= d.gamma
    with pytest.raises(DesignError):
        hinf_state_feedback(a, b2, b1, q, r, gamma=0.98 * d.gamma_opt)
    tight = hinf_state_feedback(a, b2, b1, q, r, gamma=1.01 * d.gamma_opt)
    assert hinf_norm(a - b2 @ tight.K, b1, np.vstack([np.sqrt(q), -np.sqrt(r) @ tight.K])) > 0.8 * d.gamma_opt
    # a very loose bound gives back the LQR gain
    loose = hinf_state_feedback(a, b2, b1, q, r, gamma=1e6)
    np.testing.assert_allclose(loose.K, lqr(a, b2, q, r).K, rtol=1e-6)
    m = loop_margins(a, b2, d.K)
    assert m.meets(6.0, 45.0)


def test_rpt_gains_scale_with_epsilon_and_track() -> None:
    g1, g2 = rpt_gains(1.0), rpt_gains(0.25)
    assert g2.kp == pytest.approx(16 * g1.kp) and g2.kd == pytest.approx(4 * g1.kd)
    assert g2.ki == pytest.approx(64 * g1.ki)
    np.testing.assert_allclose(np.sort_complex(rpt_poles(g2)), np.sort_complex(rpt_poles(g1) / 0.25), rtol=1e-9)
    assert np.all(rpt_poles(g1).real < 0)

    def track(eps: float) -> float:
        ctl = RptController(rpt_gains(eps))
        pos, vel, dt, worst = np.zeros(3), np.zeros(3), 0.001, 0.0
        for k in range(8000):
            t = k * dt
            ref = np.array([np.sin(t), 0.5 * t, 0.0])
            vref = np.array([np.cos(t), 0.5, 0.0])
            aref = np.array([-np.sin(t), 0.0, 0.0])
            u = ctl.update(ref, vref, aref, pos, vel, dt) + np.array([0.3, -0.2, 0.1])  # constant disturbance
            vel = vel + u * dt
            pos = pos + vel * dt
            if t > 6.0:
                worst = max(worst, float(np.max(np.abs(pos - ref))))
        return worst

    assert track(0.2) < 0.1 * track(1.0)
    with pytest.raises(ValueError):
        rpt_gains(0.0)


def test_loop_separation_check() -> None:
    a, b2, _ = _attitude_axis()
    d = lqr(a, b2, np.diag([1.0, 0.01, 0.0]), np.array([[3e-3]]))
    acl = a - b2 @ d.K
    bw = closed_loop_bandwidth(acl, b2 * d.K[0, 0], np.array([[1.0, 0.0, 0.0]]))
    assert 3.0 < bw < 50.0
    assert check_loop_separation(rpt_poles(rpt_gains(1.0)), bw) >= 1.5
    with pytest.raises(LoopSeparationError):
        check_loop_separation(rpt_poles(rpt_gains(0.1)), bw)
    assert check_loop_separation([-bw / 1.5 + 1e-9], bw) == pytest.approx(1.5)
    # a first-order loop 1/(s/5 + 1) has bandwidth 5 rad/s
    assert closed_loop_bandwidth([[-5.0]], [[5.0]], [[1.0]]) == pytest.approx(5.0, rel=1e-6)


def test_rpt_outer_loop_flies_the_cascade_and_fast_ones_are_rejected() -> None:
    base = CascadeController(P)
    bw = base.attitude_bandwidth_rad_s()
    assert 5.0 < bw < 30.0
    ctl = CascadeController(P, outer=RptController(rpt_gains(0.5), accel_limit=6.0))
    sp = np.array([2.0, -1.0, -1.5])
    _, traj = _fly(ctl, P, hover_state(P), 8.0, sp, 0.0)
    assert np.max(np.abs(traj[-250:] - sp)) < 0.02
    # poles at 1/ε rad/s: ε = 0.1 puts them at 10 rad/s, within 1.5x of the attitude bandwidth
    assert np.max(np.abs(rpt_poles(rpt_gains(0.1)))) * 1.5 > bw
    with pytest.raises(LoopSeparationError):
        CascadeController(P, outer=RptController(rpt_gains(0.1)))
    # a stiffer attitude loop accepts the same outer loop
    from mjnav.aerial import CascadeGains

    stiff = CascadeGains(att_p=(20.0, 20.0, 3.0), rate_p=(60.0, 60.0, 10.0), rate_d=(0.5, 0.5, 0.0))
    assert CascadeController(P, stiff).attitude_bandwidth_rad_s() > 1.5 * 10.0
    CascadeController(P, stiff, outer=RptController(rpt_gains(0.1)))


def test_care_matches_scipy_on_random_systems() -> None:
    from mjnav.aerial import care

    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(40):
        n, m = int(rng.integers(2, 10)), int(rng.integers(1, 4))
        a, b = rng.normal(size=(n, n)), rng.normal(size=(n, m))
        q, r = np.diag(rng.uniform(0.1, 5.0, n)), np.diag(rng.uniform(0.1, 5.0, m))
        ref = scipy.linalg.solve_continuous_are(a, b, q, r)
        if np.linalg.cond(ref) > 1e6:
            continue
        x = care(a, b @ np.linalg.solve(r, b.T), q)
        assert x is not None
        np.testing.assert_allclose(x, ref, rtol=1e-7, atol=1e-9 * np.abs(ref).max())
        checked += 1
    assert checked >= 20
    # no stabilising solution: an unstable mode the input cannot reach
    assert care(np.diag([1.0, -1.0]), np.diag([0.0, 1.0]), np.eye(2)) is None


def test_cascade_flies_on_the_gps_ins_estimate() -> None:
    """INS in the loop: the cascade uses GpsIns position/velocity (noisy IMU, 5 Hz GPS 150 ms late)."""
    from mjnav.aerial import GpsIns, GpsInsConfig, quadrotor_derivative

    rng = np.random.default_rng(8)
    cfg = GpsInsConfig(imu_rate_hz=250.0)
    dt = 1.0 / cfg.imu_rate_hz
    ins = GpsIns(cfg, x0=np.zeros(10))
    ctl = CascadeController(P)
    x = hover_state(P)
    bias = np.array([0.05, -0.03, 0.08])
    sp = np.array([1.0, 0.5, -1.0])
    pending: list[tuple[int, float, np.ndarray]] = []
    est_err, pos_err = [], []
    for k in range(round(30.0 / dt)):
        est = x.copy()
        est[0:6] = ins.x[0:6]
        u = ctl.update(est, sp, 0.0, dt)
        accel = quadrotor_derivative(x, u, P)[3:6]  # the acceleration during the next step (commands held)
        x = quadrotor_step(x, u, dt, P)
        ins.predict(accel + bias + rng.normal(scale=cfg.accel_noise_mps2, size=3))
        if k % 50 == 49:
            pending.append((k + round(0.15 / dt), ins.t_s, x[0:3] + rng.normal(scale=cfg.gps_sigma_m, size=3)))
        while pending and pending[0][0] <= k:
            _, stamp, fix = pending.pop(0)
            ins.update_gps(fix, stamp_s=stamp)
        if k * dt > 20.0:
            est_err.append(np.linalg.norm(ins.position - x[0:3]))
            pos_err.append(np.linalg.norm(x[0:3] - sp))
    assert np.sqrt(np.mean(np.square(est_err))) < 0.8
    assert np.max(pos_err) < 1.5
    assert np.all(np.isfinite(x))

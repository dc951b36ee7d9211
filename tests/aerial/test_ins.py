"""GPS/INS: the Kalman equations, delayed fusion equal to on-time fusion, consistency (NEES) and accuracy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from mjnav.aerial import (
    GpsIns,
    GpsInsConfig,
    StaleMeasurementError,
    accel_ned_from_specific_force,
    gps_ins_model,
    run_filter,
    synthetic_flight,
)

CFG = GpsInsConfig()


def test_model_matrices() -> None:
    f, g, q, h, r = gps_ins_model(CFG)
    dt = 1.0 / CFG.imu_rate_hz
    x = np.arange(9.0)
    u = np.array([0.3, -0.2, 0.1])
    nxt = f @ x + g @ u
    acc = u - x[6:9]
    np.testing.assert_allclose(nxt[0:3], x[0:3] + x[3:6] * dt + 0.5 * acc * dt * dt)
    np.testing.assert_allclose(nxt[3:6], x[3:6] + acc * dt)
    np.testing.assert_allclose(nxt[6:9], x[6:9])
    assert q[6, 6] == pytest.approx(CFG.accel_bias_walk_mps2_per_sqrt_s**2 * dt)
    assert q[3, 3] == pytest.approx((CFG.accel_noise_mps2 * dt) ** 2)
    np.testing.assert_allclose(h @ x, x[0:3])
    np.testing.assert_allclose(r, np.eye(3) * 1.5**2)


def test_matches_textbook_kalman_filter() -> None:
    """predict/update reproduce x = Fx + Gu, P = FPFᵀ + Q and the standard update step by step."""
    rng = np.random.default_rng(4)
    f, g, q, h, r = gps_ins_model(CFG)
    x0 = rng.normal(size=9)
    p0 = np.diag(rng.uniform(0.1, 2.0, 9))
    ins = GpsIns(CFG, x0=x0, P0=p0)
    x, p = x0.copy(), p0.copy()
    for k in range(120):
        u = rng.normal(size=3)
        ins.predict(u)
        x = f @ x + g @ u
        p = f @ p @ f.T + q
        if k % 40 == 39:
            y = rng.normal(size=3) * 3.0
            s = h @ p @ h.T + r
            gain = p @ h.T @ np.linalg.inv(s)
            innov = y - h @ x
            nis = ins.update_gps(y)
            assert nis == pytest.approx(innov @ np.linalg.solve(s, innov))
            x = x + gain @ innov
            p = (np.eye(9) - gain @ h) @ p
    np.testing.assert_allclose(ins.x, x, atol=1e-10)
    np.testing.assert_allclose(ins.P, p, atol=1e-10)
    assert ins.t_s == pytest.approx(120 / CFG.imu_rate_hz)


def test_delayed_fusion_equals_on_time_fusion() -> None:
    # fixes every 0.2 s arriving 0.15 s late: at each arrival both filters have seen the same fixes
    fl = synthetic_flight(np.random.default_rng(7), CFG, duration_s=12.0, gps_rate_hz=5.0, gps_delay_s=0.15)
    on_time, late = GpsIns(CFG), GpsIns(CFG)
    naive = GpsIns(CFG)  # fuses late fixes as if they were current
    taken = {int(i): m for m, i in enumerate(fl.gps_index)}
    arriving = {int(a): m for m, a in enumerate(fl.gps_arrival_index)}
    worst = 0.0
    naive_err, late_err = [], []
    for i in range(fl.t_s.size):
        for f in (on_time, late, naive):
            f.predict(fl.accel_meas[i])
        if i in taken:
            on_time.update_gps(fl.gps_position[taken[i]])
        if i in arriving:
            m = arriving[i]
            late.update_gps(fl.gps_position[m], stamp_s=float(fl.t_s[fl.gps_index[m]]))
            naive.update_gps(fl.gps_position[m])
            worst = max(worst, float(np.max(np.abs(late.x - on_time.x))))
            np.testing.assert_allclose(late.P, on_time.P, atol=1e-9)
        late_err.append(np.linalg.norm(late.position - fl.position[i]))
        naive_err.append(np.linalg.norm(naive.position - fl.position[i]))
    assert len(arriving) > 50
    assert worst < 1e-9
    assert np.mean(late_err[200:]) < np.mean(naive_err[200:])


def test_stale_and_future_fixes_are_refused() -> None:
    ins = GpsIns(GpsInsConfig(history_s=0.2))
    for _ in range(100):
        ins.predict(np.zeros(3))
    ins.update_gps(np.zeros(3), stamp_s=ins.t_s - 0.19)
    with pytest.raises(StaleMeasurementError):
        ins.update_gps(np.zeros(3), stamp_s=ins.t_s - 0.3)
    with pytest.raises(ValueError):
        ins.update_gps(np.zeros(3), stamp_s=ins.t_s + 0.1)


@pytest.mark.e2e
def test_nees_within_chi2_bounds() -> None:
    """Monte Carlo over 40 seeded flights: the run-averaged NEES stays inside the 95% χ²₉ bounds."""
    runs, nees = 40, []
    rng = np.random.default_rng(2024)
    for _ in range(runs):
        fl = synthetic_flight(rng, CFG, duration_s=12.0)
        xs, ps = run_filter(fl, CFG)
        e = np.column_stack([fl.position, fl.velocity, fl.bias]) - xs
        nees.append(np.einsum("ki,kij,kj->k", e, np.linalg.inv(ps), e))
    avg = np.mean(nees, axis=0)[:: round(CFG.imu_rate_hz) // 10]  # every 0.1 s
    lo, hi = chi2.ppf([0.025, 0.975], runs * 9) / runs
    inside = np.mean((avg >= lo) & (avg <= hi))
    assert inside >= 0.9, f"only {inside:.0%} of the run-averaged NEES inside [{lo:.2f}, {hi:.2f}]"
    assert lo <= np.mean(avg) <= hi


def test_position_four_times_better_than_gps() -> None:
    fl = synthetic_flight(np.random.default_rng(0), CFG, duration_s=120.0)
    xs, _ = run_filter(fl, CFG)
    settle = 20 * int(CFG.imu_rate_hz)
    rms = np.sqrt(np.mean(np.sum((xs[settle:, :3] - fl.position[settle:]) ** 2, axis=1)))
    gps = np.sqrt(np.mean(np.sum((fl.gps_position - fl.position[fl.gps_index]) ** 2, axis=1)))
    assert gps == pytest.approx(1.5 * np.sqrt(3), rel=0.1)
    assert gps / rms >= 4.0
    assert np.max(np.abs(xs[-1, 6:9] - fl.bias[-1])) < 0.05  # the bias was learnt


def test_accel_from_specific_force() -> None:
    np.testing.assert_allclose(accel_ned_from_specific_force([0.0, 0.0, -9.80665], 0.0, 0.0, 1.0), 0.0, atol=1e-12)
    # pitched up 90°: the body x axis points up, a reading of +g along it is rest
    a = accel_ned_from_specific_force([9.80665, 0.0, 0.0], 0.0, np.pi / 2, 0.0)
    np.testing.assert_allclose(a, 0.0, atol=1e-12)
    np.testing.assert_allclose(
        accel_ned_from_specific_force([1.0, 0.0, -9.80665], 0.0, 0.0, np.pi / 2), [0, 1, 0], atol=1e-12
    )

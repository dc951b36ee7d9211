"""GPS/baro/INS: the Kalman equations, delayed fusion equal to on-time fusion, consistency (NEES), accuracy, the
χ² gates, the resets after a long run of rejections and the barometer."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from mjnav.aerial import (
    GpsIns,
    GpsInsConfig,
    InvalidParameterError,
    StaleMeasurementError,
    SyntheticFlight,
    accel_ned_from_specific_force,
    gps_ins_model,
    isa_altitude_m,
    isa_pressure_pa,
    run_filter,
    synthetic_flight,
)

CFG = GpsInsConfig()


def test_model_matrices() -> None:
    f, g, q, h, r = gps_ins_model(CFG)
    dt = 1.0 / CFG.imu_rate_hz
    x = np.arange(10.0)
    u = np.array([0.3, -0.2, 0.1])
    nxt = f @ x + g @ u
    acc = u - x[6:9]
    np.testing.assert_allclose(nxt[0:3], x[0:3] + x[3:6] * dt + 0.5 * acc * dt * dt)
    np.testing.assert_allclose(nxt[3:6], x[3:6] + acc * dt)
    np.testing.assert_allclose(nxt[6:10], x[6:10])
    assert q[6, 6] == pytest.approx(CFG.accel_bias_walk_mps2_per_sqrt_s**2 * dt)
    assert q[3, 3] == pytest.approx((CFG.accel_noise_mps2 * dt) ** 2)
    assert q[9, 9] == pytest.approx(CFG.baro_offset_walk_m_per_sqrt_s**2 * dt)
    np.testing.assert_allclose(h @ x, x[0:3])
    np.testing.assert_allclose(r, np.eye(3) * 1.5**2)


def test_matches_textbook_kalman_filter() -> None:
    """predict/update reproduce x = Fx + Gu, P = FPFᵀ + Q and the standard update step by step (no gate)."""
    rng = np.random.default_rng(4)
    cfg = GpsInsConfig(gps_gate_nis=math.inf)
    f, g, q, h, r = gps_ins_model(cfg)
    x0 = rng.normal(size=10)
    p0 = np.diag(rng.uniform(0.1, 2.0, 10))
    ins = GpsIns(cfg, x0=x0, P0=p0)
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
            nis = ins.update_gps(y).nis
            assert nis == pytest.approx(innov @ np.linalg.solve(s, innov))
            x = x + gain @ innov
            p = (np.eye(10) - gain @ h) @ p
    np.testing.assert_allclose(ins.x, x, atol=1e-10)
    np.testing.assert_allclose(ins.P, p, atol=1e-10)
    assert ins.t_s == pytest.approx(120 / cfg.imu_rate_hz)


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
    """Monte Carlo over 40 seeded flights (GPS and barometer): the run-averaged NEES stays inside the 95% χ²₁₀
    bounds."""
    runs, nees = 40, []
    rng = np.random.default_rng(2024)
    for _ in range(runs):
        fl = synthetic_flight(rng, CFG, duration_s=12.0)
        xs, ps = run_filter(fl, CFG)
        e = np.column_stack([fl.position, fl.velocity, fl.bias, fl.baro_offset]) - xs
        nees.append(np.einsum("ki,kij,kj->k", e, np.linalg.inv(ps), e))
    avg = np.mean(nees, axis=0)[:: round(CFG.imu_rate_hz) // 10]  # every 0.1 s
    lo, hi = chi2.ppf([0.025, 0.975], runs * 10) / runs
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


def _fly(
    cfg: GpsInsConfig,
    fl: SyntheticFlight,
    fix_at: dict[int, np.ndarray | None],
    baro: bool = True,
    samples: int | None = None,
) -> GpsIns:
    """Run a filter over (the first ``samples`` IMU samples of) a synthetic flight; ``fix_at`` replaces (an array)
    or removes (None) fixes by index."""
    ins = GpsIns(cfg, x0=fl.x0, P0=None)
    arriving = {int(a): m for m, a in enumerate(fl.gps_arrival_index)}
    baros = dict(zip(fl.baro_index.tolist(), fl.baro_altitude.tolist(), strict=True))
    for i in range(fl.t_s.size if samples is None else samples):
        ins.predict(fl.accel_meas[i])
        if baro and i in baros:
            ins.update_baro(baros[i], stamp_s=float(fl.t_s[i]))
        if i in arriving:
            m = arriving[i]
            fix = fix_at.get(m, fl.gps_position[m])
            if fix is not None:
                ins.update_gps(fix, stamp_s=float(fl.t_s[fl.gps_index[m]]))
    return ins


def test_an_outlier_fix_is_gated_out_and_leaves_no_trace() -> None:
    fl = synthetic_flight(np.random.default_rng(11), CFG, duration_s=20.0)
    m = 60  # a fix 12 s in
    outlier = fl.gps_position[m] + np.array([55.0, 0.0, 0.0])
    without = _fly(CFG, fl, {m: None})
    gated = _fly(CFG, fl, {m: outlier})
    assert gated.gps.rejected == 1 and gated.gps.resets == 0 and gated.gps.fused == without.gps.fused
    np.testing.assert_array_equal(gated.x, without.x)  # rejected: as if the fix had never come
    np.testing.assert_array_equal(gated.P, without.P)
    # the same fix through no gate drags the estimate off by metres
    arrived = int(fl.gps_arrival_index[m]) + 1
    ungated = _fly(GpsInsConfig(gps_gate_nis=math.inf), fl, {m: outlier}, samples=arrived)
    assert ungated.gps.rejected == 0
    assert np.linalg.norm(ungated.position - _fly(CFG, fl, {m: None}, samples=arrived).position) > 1.0


def test_a_gated_fix_reports_its_nis_and_a_good_one_passes() -> None:
    ins = GpsIns(CFG)
    for _ in range(10):
        ins.predict(np.zeros(3))
    good = ins.update_gps([0.5, -0.5, 0.2])
    bad = ins.update_gps([40.0, 0.0, 0.0], stamp_s=ins.t_s - 0.01)
    assert good.fused and not good.reset and good.nis < CFG.gps_gate_nis
    assert not bad.fused and bad.nis > CFG.gps_gate_nis
    assert ins.gps.fused == 1 and ins.gps.rejected == 1 and ins.gps.last_nis == bad.nis


def test_a_gps_that_jumps_for_good_resets_the_filter_after_the_timeout() -> None:
    # the receiver's position jumps 30 m east at 10 s and stays there: the filter rejects it for reset_timeout_s,
    # then resets to it instead of rejecting it for ever
    cfg = GpsInsConfig(reset_timeout_s=3.0)
    fl = synthetic_flight(np.random.default_rng(12), cfg, duration_s=20.0)
    jump = np.array([0.0, 30.0, 0.0])
    jumped = {m: fl.gps_position[m] + jump for m in range(fl.gps_index.size) if fl.t_s[fl.gps_index[m]] >= 10.0}
    ins = _fly(cfg, fl, jumped)
    assert ins.gps.resets == 1
    rejected_s = ins.gps.rejected / 5.0  # fixes at 5 Hz
    assert 3.0 - 0.2 - 1e-9 <= rejected_s <= 3.0 + 0.2
    assert np.linalg.norm(ins.position - (fl.position[-1] + jump)) < 1.5  # it follows the new position
    assert ins.t_s - ins.gps.last_fused_s < 0.5  # and fuses it again


def test_the_barometer_holds_the_altitude_while_gps_is_gone() -> None:
    fl = synthetic_flight(np.random.default_rng(13), CFG, duration_s=40.0)
    gone = {m: None for m in range(fl.gps_index.size) if fl.t_s[fl.gps_index[m]] >= 20.0}
    with_baro, without_baro = _fly(CFG, fl, gone), _fly(CFG, fl, gone, baro=False)
    down_err = abs(with_baro.position[2] - fl.position[-1, 2])
    assert down_err < 0.3  # 20 s of dead reckoning, the altitude on the barometer
    assert abs(without_baro.position[2] - fl.position[-1, 2]) > 3.0 * down_err
    assert with_baro.baro.fused == fl.baro_index.size and with_baro.baro.rejected == 0
    assert abs(with_baro.baro_offset - fl.baro_offset[-1]) < 0.3  # learnt from the GPS while it lasted
    # the horizontal position is dead reckoning: its variance grew
    assert with_baro.P[0, 0] > 10.0 * _fly(CFG, fl, {}).P[0, 0]


def test_a_baro_outlier_is_rejected_and_a_shifted_barometer_resets_its_offset() -> None:
    ins = GpsIns(GpsInsConfig(reset_timeout_s=1.0, init_baro_offset_sigma_m=1.0))
    for k in range(400):  # 2 s at rest, baro at 25 Hz, fixes at 5 Hz
        ins.predict(np.zeros(3))
        if k % 8 == 0:
            shifted = 50.0 if k >= 200 else 0.0  # the barometer's offset jumps by 50 m at 1 s (a new QNH)
            ins.update_baro(shifted + (20.0 if k == 40 else 0.0))
        if k % 40 == 0:
            ins.update_gps(np.zeros(3))
    assert ins.baro.rejected >= 1 + round(1.0 * 25) - 1  # the outlier, then the shift until the timeout
    assert ins.baro.resets == 1
    assert ins.baro_offset == pytest.approx(50.0, abs=0.2)
    assert abs(ins.position[2]) < 0.2  # the altitude stayed where GPS and the old offset put it


def test_bad_measurements_raise_typed_errors() -> None:
    ins = GpsIns(CFG)
    for _ in range(10):
        ins.predict(np.zeros(3))
    with pytest.raises(InvalidParameterError):
        ins.update_gps([math.nan, 0.0, 0.0])
    with pytest.raises(InvalidParameterError):
        ins.update_baro(math.inf)
    ins.update_gps(np.zeros(3))
    with pytest.raises(StaleMeasurementError):  # a second fix at the same IMU sample
        ins.update_gps(np.zeros(3))
    with pytest.raises(InvalidParameterError):
        GpsInsConfig(gps_gate_nis=0.0)


def test_isa_altitude_inverts_the_sims_pressure() -> None:
    from mjnav.sim.uav import pressure_at_altitude

    for h in (-100.0, 0.0, 488.0, 489.5, 3000.0):
        assert isa_altitude_m(pressure_at_altitude(h)) == pytest.approx(h, abs=1e-6)
        assert isa_pressure_pa(h) == pytest.approx(pressure_at_altitude(h), rel=1e-12)
    with pytest.raises(InvalidParameterError):
        isa_altitude_m(-1.0)

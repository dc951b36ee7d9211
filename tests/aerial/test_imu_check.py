"""IMU plausibility checks: each reason rejects what it should and nothing else, in stamp order."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.aerial import IMU_REJECT_REASONS, ImuCheck, ImuCheckConfig, InvalidParameterError

G = 9.80665
LEVEL = (1.0, 0.0, 0.0, 0.0)
AT_REST = (0.0, 0.0, G)  # FLU: a level vehicle at rest reads +g up


def _one(check: ImuCheck, t: float, q: tuple[float, ...] = LEVEL, w: tuple[float, ...] = (0.0, 0.0, 0.0),
         f: tuple[float, ...] = AT_REST) -> int:  # fmt: skip
    return int(check.check([t], [q], [w], [f])[0])


def _roll(angle: float) -> tuple[float, float, float, float]:
    return (math.cos(angle / 2), math.sin(angle / 2), 0.0, 0.0)


def test_a_steady_stream_passes_and_the_period_is_learnt() -> None:
    check = ImuCheck()
    t = np.arange(1, 101) * 0.01
    rng = np.random.default_rng(3)
    w = rng.normal(scale=0.002, size=(100, 3))
    f = np.array(AT_REST) + rng.normal(scale=0.05, size=(100, 3))
    periods = check.check(t, [LEVEL] * 100, w, f)
    assert np.all(periods == 1) and check.accepted == 100
    assert sum(check.rejected.values()) == 0 and set(check.rejected) == set(IMU_REJECT_REASONS)
    assert check.learnt_period_s == pytest.approx(0.01) and check.last_stamp_s == pytest.approx(1.0)


def test_each_implausible_sample_is_rejected_for_its_reason() -> None:
    check = ImuCheck()
    assert _one(check, 0.01) == 1 and _one(check, 0.02) == 1  # the period: 10 ms
    cases = [
        ("non_finite", dict(t=0.03, f=(math.nan, 0.0, G))),
        ("non_finite", dict(t=math.inf)),
        ("accel_range", dict(t=0.03, f=(0.0, 0.0, 20.0 * G))),
        ("gyro_range", dict(t=0.03, w=(40.0, 0.0, 0.0))),
        ("quaternion", dict(t=0.03, q=(0.9, 0.0, 0.0, 0.0))),
        ("stamp_not_increasing", dict(t=0.02)),
        ("stamp_not_increasing", dict(t=0.0)),
        ("stamp_off_period", dict(t=0.0253)),
        ("stamp_jump", dict(t=0.5)),
        ("gravity", dict(t=0.03, q=_roll(math.radians(45.0)))),  # at rest, a 45° roll the accelerometer denies
        ("gravity", dict(t=0.03, q=(0.0, 1.0, 0.0, 0.0))),  # upside down
    ]
    for n, (reason, kw) in enumerate(cases, 1):
        assert _one(check, **kw) == 0, reason
        assert check.last_reason == reason
        assert sum(check.rejected.values()) == n
    assert check.accepted == 2 and check.last_stamp_s == pytest.approx(0.02)  # nothing moved the reference
    assert _one(check, 0.03) == 1


def test_gaps_count_periods_and_motion_is_not_taken_for_a_bad_attitude() -> None:
    check = ImuCheck(period_s=0.01)
    assert _one(check, 1.00) == 1
    assert _one(check, 1.03) == 3  # two samples missing: three periods
    # rolled 45° and not at rest (|f| far from g: a banked turn) or turning fast: no gravity check
    assert _one(check, 1.04, q=_roll(math.radians(45.0)), f=(0.0, 0.0, 1.4 * G)) == 1
    assert _one(check, 1.05, q=_roll(math.radians(45.0)), w=(1.0, 0.0, 0.0)) == 1
    # at rest and rolled 20°, the accelerometer agrees: along the attitude's vertical
    g_body = (0.0, G * math.sin(math.radians(20.0)), G * math.cos(math.radians(20.0)))
    assert _one(check, 1.06, q=_roll(math.radians(20.0)), f=g_body) == 1
    assert sum(check.rejected.values()) == 0


def test_limits_are_configurable_and_validated() -> None:
    check = ImuCheck(ImuCheckConfig(rest_tilt_tol_rad=0.1))
    assert _one(check, 0.01, q=_roll(math.radians(10.0))) == 0 and check.last_reason == "gravity"
    with pytest.raises(InvalidParameterError):
        ImuCheckConfig(max_gap_s=0.0)
    with pytest.raises(InvalidParameterError):
        ImuCheck(period_s=-0.01)

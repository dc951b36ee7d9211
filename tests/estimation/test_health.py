"""The localisation health monitor: OK while scans match, DEGRADED on odometry alone, LOST when that lasts."""

from __future__ import annotations

import math

import pytest

from mjnav.estimation.errors import InvalidModel
from mjnav.estimation.health import Health, HealthConfig, HealthMonitor


def test_good_scans_are_ok_and_bad_ones_degrade_then_lose_the_localisation() -> None:
    m = HealthMonitor(HealthConfig(min_returns=30, min_score=0.5, degraded_scans=3, lost_distance_m=2.0))
    x = 0.0
    for _ in range(5):
        x += 0.05
        assert m.update((x, 0.0, 0.0), 300, 0.9, True).level is Health.OK
    # An open hall: 12 returns per scan. One or two bad scans are nothing to report; the third degrades it.
    levels = []
    for _ in range(3):
        x += 0.05
        levels.append(m.update((x, 0.0, 0.0), 12, 0.0, False).level)
    assert levels == [Health.OK, Health.OK, Health.DEGRADED]
    assert "12 lidar returns, fewer than 30" in m.report.reason and m.report.bad_scans == 3
    # Driving on: 2 m on odometry alone since the last good scan is lost.
    while m.report.level is not Health.LOST:
        x += 0.05
        m.update((x, 0.0, 0.0), 12, 0.0, False)
    assert m.report.unmatched_m == pytest.approx(2.0, abs=0.051) and "m and" in m.report.reason
    assert m.report.starved  # lost for want of returns: open space
    assert not m.update((x + 0.05, 0.0, 0.0), 300, 0.0, False).starved  # plenty of returns that do not match
    # One good scan: localised again, every count reset.
    report = m.update((x + 0.1, 0.0, 0.0), 300, 0.8, True)
    assert (report.level, report.reason, report.bad_scans, report.unmatched_m) == (Health.OK, "", 0, 0.0)


def test_turning_on_odometry_alone_loses_it_too_and_a_poor_match_counts_as_bad() -> None:
    m = HealthMonitor(HealthConfig(degraded_scans=1, lost_angle_rad=math.pi / 2))
    m.update((0.0, 0.0, 0.0), 300, 0.9, True)
    report = m.update((0.0, 0.0, 0.5), 300, 0.3, True)
    assert report.level is Health.DEGRADED and "match quality 0.30, below 0.5" in report.reason
    m.update((0.0, 0.0, 1.0), 300, 0.3, True)
    assert m.update((0.0, 0.0, 1.6), 300, 0.3, True).level is Health.LOST
    # Across ±π the angle turned is the short way round.
    n = HealthMonitor()
    n.update((0.0, 0.0, math.pi - 0.01), 300, 0.9, True)
    assert n.update((0.0, 0.0, -math.pi + 0.01), 300, 0.0, False).unmatched_rad == pytest.approx(0.02)


@pytest.mark.parametrize(
    "kwargs",
    [{"min_returns": 2}, {"min_score": 1.5}, {"degraded_scans": 0}, {"lost_distance_m": 0.0}, {"lost_angle_rad": -1}],
)
def test_bad_thresholds_are_typed_errors(kwargs: dict) -> None:
    with pytest.raises(InvalidModel):
        HealthConfig(**kwargs)

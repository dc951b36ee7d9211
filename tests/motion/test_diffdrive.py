"""Diff-drive wheel-rate limiting with extreme inputs."""

from __future__ import annotations

import math

import pytest

from mjnav.motion import DiffDriveKinematics


def test_limit_wheel_rates_survives_huge_finite_commands() -> None:
    kin = DiffDriveKinematics(0.1, 0.3)
    v, w = kin.limit_wheel_rates(1e308, -1e308, 20.0)
    right, left = kin.wheel_rates(v, w)
    assert math.isfinite(v) and math.isfinite(w)
    assert max(abs(right), abs(left)) == pytest.approx(20.0)
    assert v / w == pytest.approx(-1.0)  # the commanded arc is kept


def test_limit_wheel_rates_keeps_commands_within_the_limit() -> None:
    kin = DiffDriveKinematics(0.1, 0.3)
    assert kin.limit_wheel_rates(0.5, 0.2, 20.0) == (0.5, 0.2)

"""PID (anti-windup, derivative on measurement, limits), discrete LQR and their path trackers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.control import (
    LQR,
    PID,
    ControlDesignError,
    LQRTracker,
    PIDTracker,
    lateral_error_model,
    tracking_error,
)
from tests.control.sim import dense_reference, run, s_curve, start_pose_off_path


def test_pid_hand_worked_steps() -> None:
    pid = PID(2.0, 0.5, 0.1)
    assert pid.update(1.0, 0.0, 0.1) == pytest.approx(2.05)  # P 2, I 0.05, D 0 on the first step
    # e = 0.8: P 1.6, I 0.05 + 0.04, D = -0.1 · (0.2 - 0) / 0.1 = -0.2
    assert pid.update(1.0, 0.2, 0.1) == pytest.approx(1.49)
    assert pid.integral == pytest.approx(0.09)


def test_pid_derivative_on_measurement_has_no_setpoint_kick() -> None:
    pid = PID(0.0, 0.0, 1.0)
    pid.update(0.0, 0.5, 0.1)
    assert pid.update(10.0, 0.5, 0.1) == 0.0  # setpoint jump, measurement still: no derivative
    assert pid.update(10.0, 0.6, 0.1) == pytest.approx(-1.0)


def test_pid_output_limits_and_anti_windup() -> None:
    def run_pid(pid: PID) -> list[float]:
        out = [pid.update(1.0, 0.0, 0.1) for _ in range(100)]  # saturated for 10 s
        return out + [pid.update(-1.0, 0.0, 0.1) for _ in range(3)]  # then the error reverses

    limited = PID(1.0, 1.0, output_limits=(-1.5, 1.5))
    out = run_pid(limited)
    assert max(out) == 1.5
    assert limited.integral <= 1.5
    # with anti-windup the integral froze at 0.5 (P 1 + I 0.5 = the limit), so the reversed error
    # brings the output down at once: P -1 + I (0.5 - 0.1) = -0.6
    assert out[100] == pytest.approx(-0.6)
    # a plain clamp without anti-windup would integrate to 1.5 and still output +0.4
    assert out[100] < 0.0


def test_pid_angular_wraps_errors() -> None:
    pid = PID(1.0, angular=True)
    assert pid.update(math.pi - 0.1, -math.pi + 0.1, 0.1) == pytest.approx(-0.2)


def test_pid_reset_and_bad_input() -> None:
    pid = PID(1.0, 1.0)
    pid.update(1.0, 0.0, 0.1)
    pid.reset()
    assert pid.integral == 0.0 and pid.output == 0.0
    with pytest.raises(ValueError, match="dt_s"):
        pid.update(1.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="output_limits"):
        PID(1.0, output_limits=(1.0, -1.0))


def test_lqr_scalar_golden_ratio() -> None:
    # x+ = x + u, Q = R = 1: P² - P - 1 = 0 -> P = φ, K = P / (1 + P) = 1/φ
    lqr = LQR([[1.0]], [[1.0]], [[1.0]], [[1.0]])
    phi = (1 + math.sqrt(5)) / 2
    assert lqr.P[0, 0] == pytest.approx(phi)
    assert lqr.K[0, 0] == pytest.approx(1 / phi)
    assert lqr.control([2.0])[0] == pytest.approx(-2 / phi)


def test_lateral_error_model_and_lqr_gain() -> None:
    a, b = lateral_error_model(0.5, 0.1)
    np.testing.assert_allclose(a, [[1.0, 0.05], [0.0, 1.0]])
    np.testing.assert_allclose(b, [[0.0025], [0.1]])
    lqr = LQR(a, b, np.diag([2.0, 0.5]), [[1.0]])
    assert lqr.closed_loop_spectral_radius < 1.0
    assert lqr.K[0, 0] > 0.0 and lqr.K[0, 1] > 0.0  # left of the path, heading left -> turn right


def test_lqr_design_errors() -> None:
    with pytest.raises(ControlDesignError):
        LQR(np.eye(2), [[0.0], [0.0]], np.eye(2), [[1.0]])  # uncontrollable unstable-ish mode
    with pytest.raises(ControlDesignError, match="shapes"):
        LQR(np.eye(2), [[1.0]], np.eye(2), [[1.0]])
    with pytest.raises(ControlDesignError, match="positive definite"):
        LQR(np.eye(2), np.ones((2, 1)), np.eye(2), [[0.0]])


def test_tracking_error_hand_worked() -> None:
    path = np.c_[np.linspace(0.0, 10.0, 11), np.zeros(11)]
    err = tracking_error(path, (3.5, 0.2, 0.1))
    assert err.segment_index == 3 and err.fraction == pytest.approx(0.5)
    assert err.cross_track_m == pytest.approx(0.2)
    assert err.heading_error_rad == pytest.approx(0.1)
    assert err.remaining_m == pytest.approx(6.5)
    assert tracking_error(path, (3.5, -0.2, 0.0)).cross_track_m == pytest.approx(-0.2)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_lqr_tracker_s_curve(sign: float) -> None:
    r = run(LQRTracker(), s_curve(sign=sign), start_pose_off_path(0.4, sign), dense_reference(sign))
    assert r.reached and r.final_goal_distance <= 0.15
    assert r.cross_track[r.times >= 8.0].max() <= 0.03


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_pid_tracker_s_curve(sign: float) -> None:
    r = run(PIDTracker(), s_curve(sign=sign), start_pose_off_path(0.4, sign), dense_reference(sign))
    assert r.reached and r.final_goal_distance <= 0.15
    assert r.cross_track[r.times >= 8.0].max() <= 0.05


def test_trackers_turn_round_when_facing_backwards() -> None:
    path = np.c_[np.linspace(0.0, 5.0, 51), np.zeros(51)]
    for tracker in (PIDTracker(), LQRTracker()):
        v, w = tracker.compute((1.0, 0.0, math.pi), 0.0, path)
        assert v == 0.0 and abs(w) == pytest.approx(1.0)

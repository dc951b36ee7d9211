"""PID controller with derivative on measurement, output limits and conditional-integration anti-windup."""

from __future__ import annotations

import math
from dataclasses import dataclass

from mjnav.control.tracking import ErrorFeedbackTracker, TrackerParams, TrackingError
from mjnav.geometry import wrap_angle


class PID:
    """Discrete PID: u = feedforward + kp·e + I + D, clamped to the output limits.

    * Error e = setpoint - measurement (wrapped to [-π, π) when ``angular``).
    * Integral I accumulates ki·e·Δt (rectangle rule) in output units, so retuning ki does not bump the
      output.
    * Derivative on measurement: D = -kd·(m_k - m_{k-1})/Δt, so a setpoint step causes no derivative
      kick; an optional first-order low-pass with time constant τ filters it. The first update after
      construction or :meth:`reset` has D = 0.
    * Anti-windup by conditional integration: when the unclamped output is saturated and the new error
      would push it further into saturation, the integral is frozen; the integral is also kept inside
      the output limits.

    Args:
        kp: proportional gain (output units per error unit).
        ki: integral gain (per second).
        kd: derivative gain (seconds).
        output_limits: (low, high) output clamp, low < high (infinite allowed).
        derivative_filter_s: τ of the derivative low-pass, s, >= 0 (0: no filter).
        angular: treat setpoint and measurement as angles (radians) and wrap differences.
    """

    def __init__(
        self,
        kp: float,
        ki: float = 0.0,
        kd: float = 0.0,
        *,
        output_limits: tuple[float, float] = (-math.inf, math.inf),
        derivative_filter_s: float = 0.0,
        angular: bool = False,
    ) -> None:
        for name, v in (("kp", kp), ("ki", ki), ("kd", kd)):
            if not math.isfinite(v):
                raise ValueError(f"{name} must be finite, got {v}")
        lo, hi = output_limits
        if math.isnan(lo) or math.isnan(hi) or not lo < hi:
            raise ValueError(f"output_limits must satisfy low < high, got {output_limits}")
        if not (math.isfinite(derivative_filter_s) and derivative_filter_s >= 0.0):
            raise ValueError(f"derivative_filter_s must be finite and >= 0, got {derivative_filter_s}")
        self.kp, self.ki, self.kd = float(kp), float(ki), float(kd)
        self.output_limits = (float(lo), float(hi))
        self.derivative_filter_s = float(derivative_filter_s)
        self.angular = angular
        self._integral = 0.0
        self._prev_measurement: float | None = None
        self._derivative = 0.0
        self._output = 0.0

    def reset(self) -> None:
        """Clear the integral, the derivative memory and the last output."""
        self._integral = 0.0
        self._prev_measurement = None
        self._derivative = 0.0
        self._output = 0.0

    @property
    def integral(self) -> float:
        """Current integral term I (output units)."""
        return self._integral

    @property
    def output(self) -> float:
        """Last output returned by :meth:`update`."""
        return self._output

    def _clamp(self, u: float) -> float:
        lo, hi = self.output_limits
        return lo if u < lo else hi if u > hi else u

    def update(self, setpoint: float, measurement: float, dt_s: float, feedforward: float = 0.0) -> float:
        """Advance the controller by one step and return the clamped output.

        Args:
            setpoint: desired value.
            measurement: measured value (same units).
            dt_s: time since the previous update, s, > 0.
            feedforward: term added before clamping (e.g. the yaw rate a path curvature needs).

        Returns:
            The output, within ``output_limits``.

        Raises:
            ValueError: non-finite inputs or dt_s <= 0.
        """
        if not (math.isfinite(setpoint) and math.isfinite(measurement) and math.isfinite(feedforward)):
            raise ValueError("setpoint, measurement and feedforward must be finite")
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise ValueError(f"dt_s must be positive and finite, got {dt_s}")
        error = setpoint - measurement
        if self.angular:
            error = wrap_angle(error)
        if self._prev_measurement is None:
            raw_d = 0.0
        else:
            dm = measurement - self._prev_measurement
            if self.angular:
                dm = wrap_angle(dm)
            raw_d = -dm / dt_s
        tau = self.derivative_filter_s
        if tau > 0.0 and self._prev_measurement is not None:
            self._derivative += dt_s / (tau + dt_s) * (raw_d - self._derivative)
        else:
            self._derivative = raw_d
        self._prev_measurement = measurement
        p_term = self.kp * error
        d_term = self.kd * self._derivative
        candidate = self._integral + self.ki * error * dt_s
        unclamped = feedforward + p_term + candidate + d_term
        clamped = self._clamp(unclamped)
        winding_up = unclamped != clamped and (unclamped - clamped) * (self.ki * error) > 0.0
        if not winding_up:
            self._integral = self._clamp(candidate)
        self._output = self._clamp(feedforward + p_term + self._integral + d_term)
        return self._output


@dataclass(frozen=True, slots=True)
class PIDTrackerParams(TrackerParams):
    """:class:`TrackerParams` plus the cross-track PID gains.

    Attributes:
        kp: proportional gain, rad/s per metre of cross-track error.
        ki: integral gain, rad/s per metre-second.
        kd: derivative gain, rad/s per (m/s) of cross-track rate.
        derivative_filter_s: low-pass time constant of the derivative, s.
    """

    kp: float = 2.0
    ki: float = 0.1
    kd: float = 3.0
    derivative_filter_s: float = 0.0


class PIDTracker(ErrorFeedbackTracker):
    """Path tracking with a PID on the cross-track error plus curvature feedforward.

    ω = κ_path·v + PID(0 - e_y). The derivative acts on the measured cross-track error, whose rate is
    v·sin(e_θ), so it damps the approach through the heading; near the path the loop is
    ë_y = -v (kp e_y + kd ė_y + ki ∫e_y), a damped oscillator with ω_n² = v·kp.
    """

    def __init__(self, params: PIDTrackerParams | None = None) -> None:
        p = params if params is not None else PIDTrackerParams()
        super().__init__(p)
        self.params: PIDTrackerParams = p
        lim = p.max_angular_speed_radps
        self.pid = PID(p.kp, p.ki, p.kd, output_limits=(-lim, lim), derivative_filter_s=p.derivative_filter_s)

    def _reset_controller(self) -> None:
        self.pid.reset()

    def _steer(self, error: TrackingError, v_mps: float, dt_s: float) -> float:
        return self.pid.update(0.0, error.cross_track_m, dt_s, feedforward=error.path_curvature_invm * v_mps)

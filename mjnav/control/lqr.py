"""Discrete-time LQR and the linearised path-tracking error model of a differential-drive robot."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from mjnav.control._track import check_params
from mjnav.control.errors import ControlDesignError
from mjnav.control.tracking import ErrorFeedbackTracker, TrackerParams, TrackingError

FloatArray = NDArray[np.float64]


class LQR:
    """Infinite-horizon discrete LQR: u_k = -K x_k minimising sum x_kᵀ Q x_k + u_kᵀ R u_k.

    The gain is K = (R + Bᵀ P B)⁻¹ Bᵀ P A with P the stabilising solution of the discrete algebraic
    Riccati equation (``scipy.linalg.solve_discrete_are``).

    Args:
        A: (n, n) state matrix.
        B: (n, m) input matrix.
        Q: (n, n) symmetric positive semi-definite state weight.
        R: (m, m) symmetric positive definite input weight.

    Raises:
        ControlDesignError: wrong shapes, non-symmetric or indefinite weights, a Riccati equation without
            a stabilising solution, or a closed loop that is not stable.
    """

    def __init__(self, A: ArrayLike, B: ArrayLike, Q: ArrayLike, R: ArrayLike) -> None:
        a = np.atleast_2d(np.asarray(A, dtype=np.float64))
        b = np.asarray(B, dtype=np.float64)
        b = b.reshape(-1, 1) if b.ndim == 1 else b
        q = np.atleast_2d(np.asarray(Q, dtype=np.float64))
        r = np.atleast_2d(np.asarray(R, dtype=np.float64))
        n, m = a.shape[0], b.shape[1]
        if a.shape != (n, n) or b.shape != (n, m) or q.shape != (n, n) or r.shape != (m, m):
            raise ControlDesignError(
                f"inconsistent shapes A {a.shape}, B {b.shape}, Q {q.shape}, R {r.shape} for n={n}, m={m}"
            )
        for name, mat in (("A", a), ("B", b), ("Q", q), ("R", r)):
            if not np.isfinite(mat).all():
                raise ControlDesignError(f"{name} has non-finite entries")
        if not (np.allclose(q, q.T) and np.allclose(r, r.T)):
            raise ControlDesignError("Q and R must be symmetric")
        if np.linalg.eigvalsh(q).min() < -1e-12 or np.linalg.eigvalsh(r).min() <= 0.0:
            raise ControlDesignError("Q must be positive semi-definite and R positive definite")
        try:
            p = scipy.linalg.solve_discrete_are(a, b, q, r)
        except (np.linalg.LinAlgError, ValueError) as exc:
            raise ControlDesignError(f"no stabilising Riccati solution: {exc}") from exc
        k = np.linalg.solve(r + b.T @ p @ b, b.T @ p @ a)
        radius = float(np.max(np.abs(np.linalg.eigvals(a - b @ k))))
        if not radius < 1.0:
            raise ControlDesignError(f"closed loop A - BK is not stable (spectral radius {radius:.6g})")
        self.A, self.B, self.Q, self.R = a, b, q, r
        self.P: FloatArray = p
        self.K: FloatArray = k
        self.closed_loop_spectral_radius = radius

    def control(self, state: ArrayLike) -> FloatArray:
        """u = -K x for an (n,) state; returns an (m,) input."""
        x = np.asarray(state, dtype=np.float64).reshape(-1)
        if x.shape != (self.A.shape[0],):
            raise ValueError(f"state must have shape ({self.A.shape[0]},), got {x.shape}")
        return np.asarray(-self.K @ x)


def lateral_error_model(speed_mps: float, dt_s: float) -> tuple[FloatArray, FloatArray]:
    """Zero-order-hold discretisation of the linearised path-tracking error dynamics of a unicycle.

    With the lateral error e_y (m, left of the path positive), the heading error e_θ = θ - θ_path (rad)
    and the input u = ω - κ_path·v (yaw rate beyond what the path curvature needs), linearising about the
    path at speed v gives ė_y = v e_θ, ė_θ = u, i.e. A_c = [[0, v], [0, 0]], B_c = [[0], [1]]. A_c is
    nilpotent, so the exact discretisation over Δt is

        A = [[1, vΔt], [0, 1]],   B = [[vΔt²/2], [Δt]].

    Args:
        speed_mps: forward speed v, m/s.
        dt_s: sample time Δt, s, > 0.

    Returns:
        (A (2, 2), B (2, 1)).
    """
    if not (math.isfinite(speed_mps) and math.isfinite(dt_s) and dt_s > 0.0):
        raise ValueError(f"need finite speed and dt > 0, got ({speed_mps}, {dt_s})")
    a = np.array([[1.0, speed_mps * dt_s], [0.0, 1.0]])
    b = np.array([[0.5 * speed_mps * dt_s * dt_s], [dt_s]])
    return a, b


@dataclass(frozen=True, slots=True)
class LQRTrackerParams(TrackerParams):
    """:class:`TrackerParams` plus the LQR weights of the lateral error model.

    Attributes:
        q_lateral: weight on e_y², 1/m².
        q_heading: weight on e_θ², 1/rad².
        r_yaw_rate: weight on u², s²/rad² (u = ω - κ v).
        min_model_speed_mps: the model is linearised at max(v, this), m/s (at v = 0 the lateral error is
            uncontrollable and the Riccati equation has no stabilising solution).
    """

    q_lateral: float = 2.0
    q_heading: float = 0.5
    r_yaw_rate: float = 1.0
    min_model_speed_mps: float = 0.05


class LQRTracker(ErrorFeedbackTracker):
    """Path tracking with a discrete LQR on the linearised lateral/heading error plus curvature feedforward.

    ω = κ_path·v - K(v)·[e_y, e_θ], with K from :class:`LQR` on :func:`lateral_error_model` at the
    commanded speed v and the control period. Gains are cached per speed (rounded to 1 mm/s).
    """

    def __init__(self, params: LQRTrackerParams | None = None) -> None:
        p = params if params is not None else LQRTrackerParams()
        check_params(p, positive=("q_lateral", "q_heading", "r_yaw_rate", "min_model_speed_mps"))
        super().__init__(p)
        self.params: LQRTrackerParams = p
        self._gains: dict[tuple[float, float], FloatArray] = {}

    def gain(self, speed_mps: float, dt_s: float) -> FloatArray:
        """(1, 2) LQR gain K for the error model at this speed and period (cached)."""
        p = self.params
        key = (round(max(abs(speed_mps), p.min_model_speed_mps), 3), round(dt_s, 6))
        k = self._gains.get(key)
        if k is None:
            a, b = lateral_error_model(key[0], key[1])
            k = LQR(a, b, np.diag([p.q_lateral, p.q_heading]), [[p.r_yaw_rate]]).K
            if len(self._gains) > 512:
                self._gains.clear()
            self._gains[key] = k
        return k

    def _steer(self, error: TrackingError, v_mps: float, dt_s: float) -> float:
        k = self.gain(v_mps, dt_s)
        u = -(k[0, 0] * error.cross_track_m + k[0, 1] * error.heading_error_rad)
        return error.path_curvature_invm * v_mps + u

"""Linear and extended Kalman filters.

Linear model (Kalman 1960; notation of the issue):

    predict:  x = F x + G u + b,          P = F P Fᵀ + Q
    update:   ν = y − (H x + d),  S = H P Hᵀ + R,  K = P Hᵀ S⁻¹,
              x = x + K ν,       P = (I − K H) P          (or Joseph: (I − KH) P (I − KH)ᵀ + K R Kᵀ)

b (the predict ``offset``) and d (the update ``offset``) are optional known additive inputs per step; G u is the
usual control input. After each update the filter keeps the innovation ν, its covariance S, the gain K, the
normalised innovation squared NIS = νᵀ S⁻¹ ν and the Gaussian log-likelihood of the measurement,
log N(ν; 0, S) = −½ (NIS + log det S + m log 2π).

Both steps of :class:`KalmanFilter` run in numba kernels (Cholesky of S, no explicit inverse) and return fresh
arrays, so ``kf.x`` saved from one step is never overwritten by the next. :class:`ExtendedKalmanFilter` takes user
models and Jacobians (Python callables) and shares the update kernel.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from mjnav.estimation.errors import InvalidMeasurement, InvalidModel, NotPositiveDefinite

FloatArray = NDArray[np.float64]
_LOG_2PI = math.log(2.0 * math.pi)
_EMPTY = np.zeros(0)


@njit(cache=True)
def _predict_kernel(
    x: FloatArray, P: FloatArray, F: FloatArray, Q: FloatArray, G: FloatArray, u: FloatArray, b: FloatArray
) -> tuple[FloatArray, FloatArray, bool]:
    # x' = F x + G u + b; P' = F P Fᵀ + Q. G/u and b may be empty (size 0): then they are skipped.
    # The flag is False (and nothing computed) when u or b holds NaN/inf.
    n = x.shape[0]
    nu = u.shape[0]
    for k in range(nu):
        if not math.isfinite(u[k]):
            return x, P, False
    for k in range(b.shape[0]):
        if not math.isfinite(b[k]):
            return x, P, False
    xn = np.empty(n)
    for i in range(n):
        s = 0.0
        for k in range(n):
            s += F[i, k] * x[k]
        for k in range(nu):
            s += G[i, k] * u[k]
        if b.shape[0] > 0:
            s += b[i]
        xn[i] = s
    FP = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(n):
                s += F[i, k] * P[k, j]
            FP[i, j] = s
    Pn = np.empty((n, n))
    for i in range(n):
        for j in range(i, n):
            s = 0.0
            for k in range(n):
                s += FP[i, k] * F[j, k]
            Pn[i, j] = s + 0.5 * (Q[i, j] + Q[j, i])
            Pn[j, i] = Pn[i, j]
    return xn, Pn, True


@njit(cache=True)
def _update_core(
    x: FloatArray, P: FloatArray, H: FloatArray, R: FloatArray, nu: FloatArray, joseph: bool
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, float, float, bool]:
    """Gain and posterior for innovation ν: returns x, P, S, K, NIS, log det S, ok (False: S not PD)."""
    n = x.shape[0]
    m = nu.shape[0]
    # PHt = P Hᵀ (n × m); S = H PHt + R
    PHt = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            s = 0.0
            for k in range(n):
                s += P[i, k] * H[j, k]
            PHt[i, j] = s
    S = np.empty((m, m))
    for i in range(m):
        for j in range(i, m):
            s = 0.0
            for k in range(n):
                s += H[i, k] * PHt[k, j]
            S[i, j] = s + 0.5 * (R[i, j] + R[j, i])
            S[j, i] = S[i, j]
    # Cholesky S = L Lᵀ
    L = np.zeros((m, m))
    for j in range(m):
        d = S[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0:
            return x, P, S, PHt, math.nan, math.nan, False
        L[j, j] = math.sqrt(d)
        for i in range(j + 1, m):
            s = S[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    logdet = 0.0
    for j in range(m):
        logdet += 2.0 * math.log(L[j, j])
    # NIS = |L⁻¹ ν|²
    w = np.empty(m)
    nis = 0.0
    for i in range(m):
        s = nu[i]
        for k in range(i):
            s -= L[i, k] * w[k]
        w[i] = s / L[i, i]
        nis += w[i] * w[i]
    # K = PHt S⁻¹: each row k solves S kᵀ = PHt[row]ᵀ (S symmetric) by forward and back substitution.
    K = np.empty((n, m))
    t = np.empty(m)
    for r in range(n):
        for i in range(m):
            s = PHt[r, i]
            for k in range(i):
                s -= L[i, k] * t[k]
            t[i] = s / L[i, i]
        for i in range(m - 1, -1, -1):
            s = t[i]
            for k in range(i + 1, m):
                s -= L[k, i] * K[r, k]
            K[r, i] = s / L[i, i]
    xn = np.empty(n)
    for i in range(n):
        s = x[i]
        for j in range(m):
            s += K[i, j] * nu[j]
        xn[i] = s
    # A = I − K H
    A = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(m):
                s += K[i, k] * H[k, j]
            A[i, j] = (1.0 if i == j else 0.0) - s
    AP = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(n):
                s += A[i, k] * P[k, j]
            AP[i, j] = s
    if not joseph:
        return xn, AP, S, K, nis, logdet, True
    Pn = np.empty((n, n))
    KR = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            s = 0.0
            for k in range(m):
                s += K[i, k] * R[k, j]
            KR[i, j] = s
    for i in range(n):
        for j in range(i, n):
            s = 0.0
            for k in range(n):
                s += AP[i, k] * A[j, k]
            for k in range(m):
                s += KR[i, k] * K[j, k]
            Pn[i, j] = s
            Pn[j, i] = s
    return xn, Pn, S, K, nis, logdet, True


@njit(cache=True)
def _kf_update_kernel(
    x: FloatArray, P: FloatArray, H: FloatArray, R: FloatArray, y: FloatArray, d: FloatArray, joseph: bool
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, float, float, int]:
    """ν = y − H x − d, then :func:`_update_core`. Status: 0 ok, 1 S not PD, 2 y or d not finite."""
    n = x.shape[0]
    m = y.shape[0]
    nu = np.empty(m)
    for i in range(m):
        s = y[i]
        for k in range(n):
            s -= H[i, k] * x[k]
        if d.shape[0] > 0:
            s -= d[i]
        if not math.isfinite(s):
            return x, P, P, P, nu, math.nan, math.nan, 2
        nu[i] = s
    xn, Pn, S, K, nis, logdet, ok = _update_core(x, P, H, R, nu, joseph)
    return xn, Pn, S, K, nu, nis, logdet, 0 if ok else 1


def _matrix(a: ArrayLike, shape: tuple[int, int], name: str) -> FloatArray:
    m = np.asarray(a, dtype=np.float64)
    if m.ndim == 0 and shape[0] == shape[1]:
        m = np.eye(shape[0]) * float(m)  # a scalar covariance q means q·I
    m = np.ascontiguousarray(m)
    if m.shape != shape:
        raise InvalidModel(f"{name} must have shape {shape}, got {m.shape}")
    if not np.isfinite(m).all():
        raise InvalidModel(f"{name} contains non-finite values")
    return m


def _covariance(a: ArrayLike, n: int, name: str) -> FloatArray:
    m = _matrix(a, (n, n), name)
    if not np.allclose(m, m.T, rtol=1e-9, atol=1e-12):
        raise InvalidModel(f"{name} must be symmetric")
    if n and np.linalg.eigvalsh(0.5 * (m + m.T)).min() < -1e-9 * max(1.0, float(np.abs(m).max())):
        raise InvalidModel(f"{name} must be positive semi-definite")
    return m


def _vector(a: ArrayLike, n: int, name: str, error: type[ValueError] = InvalidMeasurement) -> FloatArray:
    v = np.asarray(a, dtype=np.float64)
    if v.size != n or (v.ndim > 1 and max(v.shape) != n):
        raise error(f"{name} must have {n} values, got shape {v.shape}")
    v = np.ascontiguousarray(v.reshape(n))
    if not np.isfinite(v).all():
        raise error(f"{name} contains non-finite values")
    return v


def _hot_vector(a: ArrayLike, n: int, name: str) -> FloatArray:
    """:func:`_vector` for the per-step inputs: a float64 (n,) array passes as is (the kernels check finiteness)."""
    if type(a) is np.ndarray and a.dtype == np.float64 and a.shape == (n,) and a.flags.c_contiguous:
        return a
    return _vector(a, n, name)


class _GaussianState:
    """State, covariance and the results of the last update, shared by both filters."""

    def __init__(self, x0: FloatArray, P0: FloatArray, m: int, joseph: bool) -> None:
        self._x = x0
        self._P = P0
        self.joseph = bool(joseph)
        n = x0.shape[0]
        self.S: FloatArray = np.full((m, m), np.nan)
        """(m, m) innovation covariance of the last update."""
        self.K: FloatArray = np.full((n, m), np.nan)
        """(n, m) Kalman gain of the last update."""
        self.innovation: FloatArray = np.full(m, np.nan)
        """(m,) innovation ν = y − ŷ of the last update."""
        self.nis: float = math.nan
        """Normalised innovation squared νᵀ S⁻¹ ν of the last update (χ² with m dof for a consistent filter)."""
        self.log_likelihood: float = math.nan
        """log N(ν; 0, S) of the last update."""

    @property
    def likelihood(self) -> float:
        """N(ν; 0, S) of the last update (exp of :attr:`log_likelihood`)."""
        return math.exp(self.log_likelihood)

    @property
    def mahalanobis(self) -> float:
        """Mahalanobis distance √NIS of the last innovation."""
        return math.sqrt(self.nis)

    @property
    def dim_x(self) -> int:
        """State dimension n."""
        return int(self._x.shape[0])

    @property
    def x(self) -> FloatArray:
        """(n,) state mean. Each step replaces the array (a saved reference keeps its values)."""
        return self._x

    @x.setter
    def x(self, value: ArrayLike) -> None:
        self._x = _vector(value, self.dim_x, "x", InvalidModel)

    @property
    def P(self) -> FloatArray:  # noqa: N802 (the textbook name)
        """(n, n) state covariance. Each step replaces the array."""
        return self._P

    @P.setter
    def P(self, value: ArrayLike) -> None:  # noqa: N802
        self._P = _covariance(value, self.dim_x, "P")

    def _store(self, out: tuple[FloatArray, FloatArray, FloatArray, FloatArray, float, float, bool]) -> None:
        xn, Pn, S, K, nis, logdet, ok = out
        if not ok:
            raise NotPositiveDefinite("innovation covariance S")
        self._x, self._P, self.S, self.K, self.nis = xn, Pn, S, K, nis
        self.log_likelihood = -0.5 * (nis + logdet + S.shape[0] * _LOG_2PI)


class KalmanFilter(_GaussianState):
    """Linear Kalman filter ``KalmanFilter(F, H, Q, R, G=None, x0=None, P0=None)``.

    Args:
        F: (n, n) state transition.
        H: (m, n) measurement matrix.
        Q: (n, n) process noise covariance (a scalar means q·I).
        R: (m, m) measurement noise covariance (a scalar means r·I).
        G: (n, p) control input matrix, or None (no control).
        x0: (n,) initial mean (default zeros).
        P0: (n, n) initial covariance (default identity).
        joseph: update the covariance in Joseph form (I − KH) P (I − KH)ᵀ + K R Kᵀ (symmetric and positive for
            any gain) instead of (I − KH) P.

    Attributes:
        x, P: current mean (n,) and covariance (n, n).
        S, K, innovation, nis, log_likelihood: results of the last :meth:`update`.

    Raises:
        InvalidModel: a matrix has the wrong shape, non-finite values, or a covariance is not symmetric PSD.
    """

    def __init__(
        self,
        F: ArrayLike,
        H: ArrayLike,
        Q: ArrayLike,
        R: ArrayLike,
        G: ArrayLike | None = None,
        x0: ArrayLike | None = None,
        P0: ArrayLike | None = None,
        *,
        joseph: bool = False,
    ) -> None:
        Fm = np.atleast_2d(np.asarray(F, dtype=np.float64))  # a scalar F is a 1-state model
        Hm = np.atleast_2d(np.asarray(H, dtype=np.float64))  # a 1-D H is one measurement row
        if Fm.ndim != 2 or Fm.shape[0] != Fm.shape[1] or Fm.shape[0] == 0:
            raise InvalidModel(f"F must be a square (n, n) matrix, got shape {Fm.shape}")
        n = Fm.shape[0]
        if Hm.ndim != 2 or Hm.shape[1] != n or Hm.shape[0] == 0:
            raise InvalidModel(f"H must have shape (m, {n}), got {Hm.shape}")
        m = Hm.shape[0]
        self.F = _matrix(Fm, (n, n), "F")
        self.H = _matrix(Hm, (m, n), "H")
        self.Q = _covariance(Q, n, "Q")
        self.R = _covariance(R, m, "R")
        if G is None:
            self.G: FloatArray | None = None
        else:
            Gm = np.asarray(G, dtype=np.float64)
            if Gm.ndim == 1:
                Gm = Gm.reshape(n, -1)
            self.G = _matrix(Gm, (n, Gm.shape[1] if Gm.ndim == 2 else 0), "G")
        self._no_G = np.zeros((n, 0))
        x = np.zeros(n) if x0 is None else _vector(x0, n, "x0", InvalidModel)
        P = np.eye(n) if P0 is None else _covariance(P0, n, "P0")
        super().__init__(x, P, m, joseph)

    @property
    def dim_z(self) -> int:
        """Measurement dimension m."""
        return int(self.H.shape[0])

    def predict(self, u: ArrayLike | None = None, *, offset: ArrayLike | None = None) -> None:
        """Time update x = F x + G u + b, P = F P Fᵀ + Q.

        Args:
            u: (p,) control input (needs G), or None.
            offset: (n,) known additive input b for this step, or None.

        Raises:
            InvalidMeasurement: u without G, or u / offset of the wrong size or non-finite.
        """
        n = self._x.shape[0]
        if u is None:
            G, uu = self._no_G, _EMPTY
        else:
            if self.G is None:
                raise InvalidMeasurement("predict(u) needs a control matrix G")
            G, uu = self.G, _hot_vector(u, self.G.shape[1], "u")
        b = _EMPTY if offset is None else _hot_vector(offset, n, "offset")
        x, P, finite = _predict_kernel(self._x, self._P, self.F, self.Q, G, uu, b)
        if not finite:
            raise InvalidMeasurement("u or offset contains non-finite values")
        self._x, self._P = x, P

    def update(self, y: ArrayLike, *, offset: ArrayLike | None = None) -> None:
        """Measurement update with y = H x + d + v, v ~ N(0, R).

        Args:
            y: (m,) measurement.
            offset: (m,) known additive measurement offset d for this step, or None.

        Raises:
            InvalidMeasurement: y or offset of the wrong size or non-finite.
            NotPositiveDefinite: S = H P Hᵀ + R is not positive definite.
        """
        m = self.H.shape[0]
        yy = _hot_vector(y, m, "y")
        d = _EMPTY if offset is None else _hot_vector(offset, m, "offset")
        xn, Pn, S, K, nu, nis, logdet, status = _kf_update_kernel(self._x, self._P, self.H, self.R, yy, d, self.joseph)
        if status == 2:
            raise InvalidMeasurement("y or offset contains non-finite values")
        self._store((xn, Pn, S, K, nis, logdet, status == 0))
        self.innovation = nu

    def filter(
        self,
        ys: ArrayLike,
        us: ArrayLike | None = None,
        *,
        predict_offsets: ArrayLike | None = None,
        update_offsets: ArrayLike | None = None,
    ) -> tuple[FloatArray, FloatArray]:
        """Run predict then update for each of T measurements, from the current state.

        Args:
            ys: (T, m) measurements.
            us: (T, p) controls, or None.
            predict_offsets: (T, n) additive inputs b_t (or one (n,) for every step), or None.
            update_offsets: (T, m) measurement offsets d_t (or one (m,) for every step), or None.

        Returns:
            (T, n) filtered means and (T, n, n) filtered covariances (after each update).
        """
        Y = np.asarray(ys, dtype=np.float64)
        if Y.ndim != 2 or Y.shape[1] != self.dim_z:
            raise InvalidMeasurement(f"ys must be (T, {self.dim_z}), got {Y.shape}")
        T = Y.shape[0]

        def rows(a: ArrayLike | None, width: int, name: str) -> FloatArray | None:
            if a is None:
                return None
            A = np.asarray(a, dtype=np.float64)
            if A.ndim == 1:
                A = np.broadcast_to(A, (T, A.shape[0]))
            if A.shape != (T, width):
                raise InvalidMeasurement(f"{name} must be ({T}, {width}), got {A.shape}")
            return A

        U = rows(us, self.G.shape[1] if self.G is not None else 0, "us")
        B = rows(predict_offsets, self.dim_x, "predict_offsets")
        D = rows(update_offsets, self.dim_z, "update_offsets")
        means = np.empty((T, self.dim_x))
        covs = np.empty((T, self.dim_x, self.dim_x))
        for t in range(T):
            self.predict(None if U is None else U[t], offset=None if B is None else B[t])
            self.update(Y[t], offset=None if D is None else D[t])
            means[t] = self._x
            covs[t] = self._P
        return means, covs


class ExtendedKalmanFilter(_GaussianState):
    """Extended Kalman filter with user models and Jacobians.

    Models (all arrays float64):
        ``f(x, u) -> (n,)`` motion model and ``F_jacobian(x, u) -> (n, n)`` its Jacobian ∂f/∂x (u is whatever
        :meth:`predict` was given, possibly None); ``h(x) -> (m,)`` measurement model and ``H_jacobian(x) -> (m, n)``.
        An optional ``residual(a, b) -> (m,)`` replaces a − b for the innovation (e.g. to wrap bearings).

    Args:
        f, F_jacobian, h, H_jacobian: the models above.
        Q: (n, n) process noise covariance (additive, after f).
        R: (m, m) measurement noise covariance.
        x0: (n,) initial mean.
        P0: (n, n) initial covariance.
        residual: innovation function, default a − b.
        joseph: Joseph-form covariance update.

    Attributes:
        x, P: current mean and covariance; S, K, innovation, nis, log_likelihood: results of the last update.
    """

    def __init__(
        self,
        f: Callable[[FloatArray, object], ArrayLike],
        F_jacobian: Callable[[FloatArray, object], ArrayLike],
        h: Callable[[FloatArray], ArrayLike],
        H_jacobian: Callable[[FloatArray], ArrayLike],
        Q: ArrayLike,
        R: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        *,
        residual: Callable[[FloatArray, FloatArray], ArrayLike] | None = None,
        joseph: bool = False,
    ) -> None:
        x = np.asarray(x0, dtype=np.float64).reshape(-1)
        n = x.shape[0]
        if n == 0:
            raise InvalidModel("x0 must not be empty")
        x = _vector(x, n, "x0", InvalidModel)
        self.R = np.ascontiguousarray(np.atleast_2d(np.asarray(R, dtype=np.float64)))
        m = self.R.shape[0]
        self.R = _covariance(self.R, m, "R")
        self.Q = _covariance(Q, n, "Q")
        self.f, self.F_jacobian, self.h, self.H_jacobian = f, F_jacobian, h, H_jacobian
        self.residual = residual
        super().__init__(x, _covariance(P0, n, "P0"), m, joseph)

    def predict(self, u: object = None) -> None:
        """x = f(x, u), P = F P Fᵀ + Q with F = ∂f/∂x at the prior mean."""
        n = self._x.shape[0]
        F = _matrix(self.F_jacobian(self._x, u), (n, n), "F_jacobian(x, u)")
        xn = _vector(self.f(self._x, u), n, "f(x, u)", InvalidModel)
        _, Pn, _ = _predict_kernel(self._x, self._P, F, self.Q, _EMPTY.reshape(n, 0), _EMPTY, _EMPTY)
        self._x, self._P = xn, Pn

    def update(
        self,
        z: ArrayLike,
        *,
        h: Callable[[FloatArray], ArrayLike] | None = None,
        H_jacobian: Callable[[FloatArray], ArrayLike] | None = None,
        R: ArrayLike | None = None,
    ) -> None:
        """Update with measurement z; ``h``/``H_jacobian``/``R`` override the filter's for this call only.

        Raises:
            InvalidMeasurement: z of the wrong size or non-finite.
            NotPositiveDefinite: S is not positive definite.
        """
        hf = self.h if h is None else h
        Hf = self.H_jacobian if H_jacobian is None else H_jacobian
        zz = np.asarray(z, dtype=np.float64).reshape(-1)
        m = zz.shape[0]
        Rm = self.R if R is None else _covariance(R, m, "R")
        if Rm.shape[0] != m:
            raise InvalidMeasurement(f"z must have {Rm.shape[0]} values, got {m}")
        zz = _vector(zz, m, "z")
        Hm = _matrix(Hf(self._x), (m, self.dim_x), "H_jacobian(x)")
        zp = _vector(hf(self._x), m, "h(x)", InvalidModel)
        nu = zz - zp if self.residual is None else _vector(self.residual(zz, zp), m, "residual", InvalidModel)
        self._store(_update_core(self._x, self._P, Hm, Rm, np.ascontiguousarray(nu), self.joseph))
        self.innovation = nu

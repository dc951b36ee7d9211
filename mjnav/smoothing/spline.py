"""Piecewise-cubic path splines with C0, C1 or C2 continuity, fitted as a quadratic programme in CasADi.

Parameterisation. The knots are the input points, at parameter values t_k equal to the cumulative chord
length (so t is close to arc length, in metres). Segment k (t_k <= t <= t_{k+1}, length h_k) is the
cubic p_k(u) = a_k + b_k u + c_k u² + d_k u³ in the normalised local coordinate u = (t - t_k) / h_k,
with (2,)-vector coefficients in metres; derivatives with respect to t are p_k'(u) / h_k, p_k''(u) / h_k²
and p_k'''(u) / h_k³.

Problem. With ĥ_k = h_k / h̄ (h̄ the mean segment length) the QP minimises the roughness

    R = sum_k 36 |d_k|² / ĥ_k⁵  +  w_bend (4 |c_k|² + 12 c_k·d_k + 12 |d_k|²) / ĥ_k³,

which is h̄⁵ ∫|s'''|² dt + w_bend h̄³ ∫|s''|² dt (squared jerk plus a little bending energy, made
dimensionless), subject to

* C0: p_k(1) = p_{k+1}(0) at every interior knot, and C1 / C2 additionally the matching first / second
  derivatives with respect to t;
* through the points (``smoothing = 0``): p_k(0) = x_k and p_{M-1}(1) = x_M; or near them
  (``smoothing > 0``): the data misfit sum_k |s(t_k) - x_k|² is added to ``smoothing * R`` instead.

Why jerk: the bending energy alone is minimised among all interpolants by the natural cubic spline, which
is C2, so a C1 constraint would change nothing. Penalising the jerk makes each continuity level distinct:
with C0 every segment becomes a straight line (a polyline); with C1 the second derivative may jump at a
knot, so a straight line followed by a circular arc is reproduced with its curvature jump instead of
ringing; with C2 the result is a C2 interpolating cubic spline. The x and y coordinates are independent
problems with the same matrices; CasADi's ``qpsol`` (``qrqp``, an exact active-set solver) is built once
per problem structure (number of segments, continuity, mode) and reused for both coordinates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from mjnav.smoothing.errors import PathError, SolverError
from mjnav.smoothing.path import check_path

FloatArray = NDArray[np.float64]

# 8-point Gauss-Legendre rule on [0, 1] for arc-length integrals
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_GL_U = 0.5 * (_GL_X + 1.0)
_GL_W = 0.5 * _GL_W


@lru_cache(maxsize=32)
def _qp_solver(segments: int, continuity: int, interpolate: bool) -> Any:
    """CasADi QP for one coordinate; parameters p = [ĥ (M), values (M+1), w_bend, smoothing]."""
    m = segments
    coef = ca.SX.sym("coef", m, 4)
    a, b, c, d = coef[:, 0], coef[:, 1], coef[:, 2], coef[:, 3]
    hn = ca.SX.sym("h", m)
    vals = ca.SX.sym("v", m + 1)
    w_bend = ca.SX.sym("w_bend")
    smoothing = ca.SX.sym("smoothing")
    rough = ca.sum1(36.0 * d**2 / hn**5 + w_bend * (4.0 * c**2 + 12.0 * c * d + 12.0 * d**2) / hn**3)
    end = a + b + c + d  # p_k(1)
    cons = []
    if m > 1:
        cons.append(end[:-1] - a[1:])
        if continuity >= 1:
            cons.append((b[:-1] + 2.0 * c[:-1] + 3.0 * d[:-1]) / hn[:-1] - b[1:] / hn[1:])
        if continuity >= 2:
            cons.append((2.0 * c[:-1] + 6.0 * d[:-1]) / hn[:-1] ** 2 - 2.0 * c[1:] / hn[1:] ** 2)
    knot_vals = ca.vertcat(a, end[m - 1])
    if interpolate:
        cons.append(knot_vals - vals)
        cost = rough
    else:
        cost = ca.sumsqr(knot_vals - vals) + smoothing * rough
    qp = {"x": ca.vec(coef), "f": cost, "g": ca.vertcat(*cons), "p": ca.vertcat(hn, vals, w_bend, smoothing)}
    opts = {"print_time": False, "error_on_fail": False, "print_iter": False, "print_header": False}
    opts["print_info"] = False
    return ca.qpsol("spline_qp", "qrqp", qp, opts)


@dataclass(frozen=True, slots=True, eq=False)
class PiecewiseCubic:
    """A planar piecewise-cubic curve s(t) over the parameter interval [t_0, t_M] (metres of chord length).

    Attributes:
        knots: (M + 1,) strictly increasing parameter values of the knots, metres; knots[0] = 0.
        coefficients: (M, 4, 2) coefficients (a, b, c, d) of each segment in its normalised coordinate
            u in [0, 1], metres.
        continuity: the continuity order (0, 1 or 2) the fit enforced at the interior knots.
    """

    knots: FloatArray
    coefficients: FloatArray
    continuity: int

    @property
    def segments(self) -> int:
        """Number of cubic segments M."""
        return int(self.coefficients.shape[0])

    @property
    def parameter_length(self) -> float:
        """t_M - t_0, metres of chord length."""
        return float(self.knots[-1] - self.knots[0])

    def _locate(self, t: ArrayLike) -> tuple[NDArray[np.intp], FloatArray, FloatArray]:
        tt = np.asarray(t, dtype=np.float64)
        if not np.isfinite(tt).all():
            raise ValueError("parameter values must be finite")
        lo, hi = float(self.knots[0]), float(self.knots[-1])
        tol = 1e-9 * max(1.0, hi - lo)
        if tt.size and (tt.min() < lo - tol or tt.max() > hi + tol):
            raise ValueError(f"parameter values must lie in [{lo}, {hi}], got [{tt.min()}, {tt.max()}]")
        tt = np.clip(tt, lo, hi)
        k = np.clip(np.searchsorted(self.knots, tt, side="right") - 1, 0, self.segments - 1)
        h = self.knots[k + 1] - self.knots[k]
        return k, (tt - self.knots[k]) / h, h

    def evaluate(self, t: ArrayLike, order: int = 0) -> FloatArray:
        """Position or a derivative with respect to the parameter t.

        At an interior knot the segment to the right is used (its left limit is available from
        :meth:`knot_jumps`).

        Args:
            t: scalar or (K,) parameter values in [t_0, t_M], metres.
            order: 0 position (m), 1 first derivative (dimensionless), 2 second derivative (1/m),
                3 third derivative (1/m²).

        Returns:
            (K, 2) array (or (2,) for scalar t).
        """
        if order not in (0, 1, 2, 3):
            raise ValueError(f"order must be 0, 1, 2 or 3, got {order}")
        k, u, h = self._locate(t)
        a, b, c, d = (self.coefficients[k, i] for i in range(4))
        uu = u[..., None]
        hh = h[..., None]
        if order == 0:
            return a + uu * (b + uu * (c + uu * d))
        if order == 1:
            return (b + uu * (2.0 * c + 3.0 * uu * d)) / hh
        if order == 2:
            return (2.0 * c + 6.0 * uu * d) / hh**2
        return 6.0 * d / hh**3 + 0.0 * uu

    def knot_jumps(self, order: int) -> FloatArray:
        """Jump right-limit minus left-limit of the order-th t-derivative at each interior knot.

        Args:
            order: 0, 1, 2 or 3.

        Returns:
            (M - 1, 2) jumps (units of :meth:`evaluate` for that order).
        """
        if order not in (0, 1, 2, 3):
            raise ValueError(f"order must be 0, 1, 2 or 3, got {order}")
        cf = self.coefficients
        h = np.diff(self.knots)[:, None]
        a, b, c, d = cf[:, 0], cf[:, 1], cf[:, 2], cf[:, 3]
        if order == 0:
            left, right = a + b + c + d, a
        elif order == 1:
            left, right = (b + 2.0 * c + 3.0 * d) / h, b / h
        elif order == 2:
            left, right = (2.0 * c + 6.0 * d) / h**2, 2.0 * c / h**2
        else:
            left = right = 6.0 * d / h**3
        return np.asarray(right[1:] - left[:-1])

    def curvature(self, t: ArrayLike) -> FloatArray:
        """Signed curvature (x'y'' - y'x'') / |s'|³ at parameter values t, 1/metres (left turns positive)."""
        d1 = self.evaluate(t, 1)
        d2 = self.evaluate(t, 2)
        speed = np.hypot(d1[..., 0], d1[..., 1])
        return np.asarray((d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0]) / speed**3)

    def _segment_arc_lengths(self) -> FloatArray:
        cf = self.coefficients
        u = _GL_U[None, :, None]
        deriv = cf[:, None, 1] + u * (2.0 * cf[:, None, 2] + 3.0 * u * cf[:, None, 3])  # dp/du, (M, 8, 2)
        return np.asarray(np.hypot(deriv[..., 0], deriv[..., 1]) @ _GL_W)

    @property
    def arc_length(self) -> float:
        """Total arc length of the curve, metres (8-point Gauss-Legendre per segment)."""
        return float(self._segment_arc_lengths().sum())

    def parameter_at_arc_length(self, s: ArrayLike) -> FloatArray:
        """Parameter values t at which the arc length measured from the start equals s.

        Args:
            s: scalar or (K,) arc lengths in [0, arc_length], metres.

        Returns:
            Parameter values t with the shape of ``s``, metres.
        """
        ss = np.asarray(s, dtype=np.float64)
        seg = self._segment_arc_lengths()
        cum = np.concatenate(([0.0], np.cumsum(seg)))
        total = float(cum[-1])
        if not np.isfinite(ss).all() or (ss.size and (ss.min() < -1e-9 * total or ss.max() > total * (1 + 1e-9))):
            raise ValueError(f"arc lengths must lie in [0, {total}]")
        flat = np.clip(ss.reshape(-1), 0.0, total)
        k = np.clip(np.searchsorted(cum, flat, side="right") - 1, 0, self.segments - 1)
        target = flat - cum[k]
        cf = self.coefficients[k]  # (K, 4, 2)
        u = np.where(seg[k] > 0.0, target / np.where(seg[k] > 0.0, seg[k], 1.0), 0.0)
        for _ in range(8):  # Newton on A_k(u) = ∫_0^u |p_k'(v)| dv, with the integral by Gauss-Legendre
            v = u[:, None] * _GL_U[None, :]
            dv = cf[:, None, 1] + v[..., None] * (2.0 * cf[:, None, 2] + 3.0 * v[..., None] * cf[:, None, 3])
            arc = u * (np.hypot(dv[..., 0], dv[..., 1]) @ _GL_W)
            du = cf[:, 1] + u[:, None] * (2.0 * cf[:, 2] + 3.0 * u[:, None] * cf[:, 3])
            speed = np.hypot(du[:, 0], du[:, 1])
            u = np.clip(u - (arc - target) / np.maximum(speed, 1e-12), 0.0, 1.0)
        t = self.knots[k] + u * np.diff(self.knots)[k]
        return t.reshape(ss.shape)

    def at_arc_length(self, s: ArrayLike, order: int = 0) -> FloatArray:
        """Position or a derivative with respect to arc length.

        Args:
            s: scalar or (K,) arc lengths in [0, arc_length], metres.
            order: 0 position (m); 1 unit tangent ds/ds; 2 curvature vector d²s/ds² (1/m).

        Returns:
            (K, 2) array (or (2,) for scalar s).
        """
        if order not in (0, 1, 2):
            raise ValueError(f"order must be 0, 1 or 2 for arc-length derivatives, got {order}")
        t = self.parameter_at_arc_length(s)
        if order == 0:
            return self.evaluate(t, 0)
        d1 = self.evaluate(t, 1)
        speed = np.hypot(d1[..., 0], d1[..., 1])[..., None]
        if order == 1:
            return np.asarray(d1 / speed)
        d2 = self.evaluate(t, 2)
        along = np.sum(d1 * d2, axis=-1, keepdims=True) / speed**2
        return np.asarray((d2 - along * d1) / speed**2)

    def sample(self, spacing_m: float) -> FloatArray:
        """Points at equal arc-length spacing from start to end (the last interval may be shorter).

        Args:
            spacing_m: arc-length step, metres, > 0.

        Returns:
            (K, 2) positions, metres, starting and ending at the curve's end points.
        """
        if not (math.isfinite(spacing_m) and spacing_m > 0.0):
            raise ValueError(f"spacing_m must be positive and finite, got {spacing_m}")
        total = self.arc_length
        s = np.arange(0.0, total, spacing_m)
        if total - s[-1] < 1e-9:
            s = s[:-1]
        return self.at_arc_length(np.append(s, total))


def fit_spline(
    points: ArrayLike,
    continuity: int = 2,
    *,
    smoothing: float = 0.0,
    w_bend: float = 0.01,
) -> PiecewiseCubic:
    """Fit a planar piecewise cubic with C0, C1 or C2 continuity through (or near) the points with CasADi.

    See the module docstring for the parameterisation and the quadratic programme.

    Args:
        points: (N, 2) positions, metres, N >= 2, no two consecutive points equal.
        continuity: 0, 1 or 2 — continuity order enforced at every interior knot.
        smoothing: 0 interpolates the points exactly; > 0 trades the data misfit (m²) against
            ``smoothing`` times the dimensionless roughness, so the curve passes near the points.
        w_bend: weight of the bending term relative to the jerk term, > 0 (it makes the C0 fit unique and
            settles the free end conditions; small values keep C1 curvature jumps sharp).

    Returns:
        The fitted :class:`PiecewiseCubic`, parameterised by cumulative chord length.

    Raises:
        PathError: fewer than 2 points, wrong shape, non-finite or repeated consecutive points.
        ValueError: ``continuity`` not in {0, 1, 2} or invalid weights.
        SolverError: the CasADi QP solver did not report success.
    """
    pts = check_path(points, name="points")
    if continuity not in (0, 1, 2):
        raise ValueError(f"continuity must be 0, 1 or 2, got {continuity}")
    if not (math.isfinite(smoothing) and smoothing >= 0.0):
        raise ValueError(f"smoothing must be finite and >= 0, got {smoothing}")
    if not (math.isfinite(w_bend) and w_bend > 0.0):
        raise ValueError(f"w_bend must be finite and > 0, got {w_bend}")
    chords = np.hypot(*np.diff(pts, axis=0).T)
    if (chords <= 1e-12 * max(1.0, float(chords.max()))).any():
        i = int(np.flatnonzero(chords <= 1e-12 * max(1.0, float(chords.max())))[0])
        raise PathError(f"points {i} and {i + 1} coincide; remove repeated points first")
    knots = np.concatenate(([0.0], np.cumsum(chords)))
    m = pts.shape[0] - 1
    solver = _qp_solver(m, continuity, smoothing == 0.0)
    hn = chords / chords.mean()
    coefficients = np.empty((m, 4, 2))
    for axis in range(2):
        p = np.concatenate((hn, pts[:, axis], [w_bend, smoothing]))
        res = solver(p=p, lbg=0.0, ubg=0.0)
        stats = solver.stats()
        if not stats.get("success", False):
            raise SolverError("CasADi qrqp did not solve the spline QP", str(stats.get("return_status")))
        coefficients[:, :, axis] = np.asarray(res["x"]).reshape(4, m).T
    return PiecewiseCubic(knots, coefficients, continuity)

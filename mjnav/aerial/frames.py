"""Geodetic and local frames on the WGS84 ellipsoid, body rotations and ZYX Euler rates.

Conventions (the whole of `mjnav.aerial`):
    * geodetic latitude/longitude in **degrees**, ellipsoidal height in metres (WGS84);
    * ECEF: x through (0°N, 0°E), z through the north pole, metres;
    * local frames at an origin (lat0, lon0, h0): NED (north, east, down) and ENU (east, north, up), metres;
    * body frame FRD (x forward, y right, z down); attitude as ZYX (yaw-pitch-roll) Euler angles in **radians**:
      ``R_nb = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` maps body vectors into NED;
    * quaternions are (w, x, y, z), Hamilton, body → NED.

Every frame conversion is vectorised over broadcastable arrays (any shape) and returns a tuple of three arrays of
the broadcast shape; when every argument is a Python or NumPy scalar the result is a tuple of Python floats from
a compiled scalar kernel (no array round trip), so scalar calls cost about a microsecond.

`ecef_to_geodetic` is Vermeille's closed form (J. Geodesy 76, 2002; 85, 2011) with the cubic solved by the
trigonometric form where its discriminant is negative (points inside the evolute, near the centre) and the
equatorial-plane case inside the evolute solved directly, so it is exact (no iteration) and finite everywhere:
poles, z = 0, the antimeridian, the centre of the Earth, and altitudes to tens of thousands of kilometres. Array
calls run a branch-free vectorised form of the same formula (a polynomial atan2 accurate to 6e-16 rad and a Halley
cube root) and hand the few points it does not cover (deep inside the Earth) to the exact scalar kernel.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from mjnav.aerial.errors import GimbalLockError, InvalidParameterError

__all__ = [
    "WGS84_A",
    "WGS84_E2",
    "WGS84_F",
    "body_to_ned",
    "ecef_to_enu",
    "ecef_to_geodetic",
    "ecef_to_ned",
    "enu_to_ecef",
    "enu_to_geodetic",
    "euler_from_quat",
    "euler_rate_matrix",
    "euler_rates",
    "geodetic_to_ecef",
    "geodetic_to_enu",
    "geodetic_to_ned",
    "ned_to_body",
    "ned_to_ecef",
    "ned_to_geodetic",
    "quat_from_euler",
    "quat_multiply",
    "quat_to_rotation",
    "rotation_body_to_ned",
]

WGS84_A = 6378137.0
"""WGS84 semi-major axis, metres."""
WGS84_F = 1.0 / 298.257223563
"""WGS84 flattening."""
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
"""WGS84 first eccentricity squared."""

_DEG = math.pi / 180.0
_SCALAR_TYPES = (float, int, np.floating, np.integer)


# ---------------------------------------------------------------------------------------------------------------
# scalar kernels (radians inside)


@njit(cache=True, fastmath=False)
def _geo2ecef(lat: float, lon: float, h: float) -> tuple[float, float, float]:
    slat = math.sin(lat)
    clat = math.cos(lat)
    n = WGS84_A / math.sqrt(1.0 - WGS84_E2 * slat * slat)
    rr = (n + h) * clat
    return rr * math.cos(lon), rr * math.sin(lon), (n * (1.0 - WGS84_E2) + h) * slat


@njit(cache=True, fastmath=False)
def _ecef2geo(x: float, y: float, z: float) -> tuple[float, float, float]:
    a = WGS84_A
    e2 = WGS84_E2
    e4 = e2 * e2
    e2m = 1.0 - e2
    rxy = math.hypot(x, y)
    lon = math.atan2(y, x) if rxy > 0.0 else 0.0
    p = (rxy / a) ** 2
    q = e2m * (z / a) ** 2
    r = (p + q - e4) / 6.0
    if q == 0.0 and r <= 0.0:
        # On the equatorial plane inside the evolute (|rxy| <= a e^2), the centre included: two symmetric nearest
        # points; take the northern one (southern for z = -0.0).
        zz = math.sqrt((e4 - p) / e2m)
        xx = math.sqrt(p)
        hh = math.hypot(zz, xx)
        lat = math.atan2(zz, xx)
        if math.copysign(1.0, z) < 0.0:
            lat = -lat
        return lat, lon, -a * e2m * hh / e2
    s = e4 * p * q / 4.0
    r2 = r * r
    r3 = r * r2
    disc = s * (2.0 * r3 + s)
    u = r
    if disc >= 0.0:
        t3 = s + r3
        t3 += math.copysign(math.sqrt(disc), t3)  # same signs: no cancellation
        t = np.cbrt(t3)
        u += t + (r2 / t if t != 0.0 else 0.0)
    else:
        # Three real roots (only inside the evolute, r < 0): the largest, continuous with the branch above.
        phi = math.atan2(math.sqrt(-disc), s + r3)
        u -= 2.0 * r * math.cos(phi / 3.0)
    v = math.sqrt(u * u + e4 * q)
    uv = e4 * q / (v - u) if u < 0.0 else u + v  # u + v without cancellation
    w = max(0.0, e2 * (uv - q) / (2.0 * v))
    k = uv / (math.sqrt(uv + w * w) + w)
    d = k * rxy / (k + e2)
    lat = math.atan2(z * (k + e2), k * rxy)
    h = (k + e2 - 1.0) / k * math.hypot(d, z)
    return lat, lon, h


@njit(cache=True)
def _ecef2enu(x: float, y: float, z: float, lat0: float, lon0: float, h0: float) -> tuple[float, float, float]:
    x0, y0, z0 = _geo2ecef(lat0, lon0, h0)
    dx = x - x0
    dy = y - y0
    dz = z - z0
    sl = math.sin(lat0)
    cl = math.cos(lat0)
    so = math.sin(lon0)
    co = math.cos(lon0)
    t = co * dx + so * dy
    e = -so * dx + co * dy
    n = -sl * t + cl * dz
    u = cl * t + sl * dz
    return e, n, u


@njit(cache=True)
def _enu2ecef(e: float, n: float, u: float, lat0: float, lon0: float, h0: float) -> tuple[float, float, float]:
    x0, y0, z0 = _geo2ecef(lat0, lon0, h0)
    sl = math.sin(lat0)
    cl = math.cos(lat0)
    so = math.sin(lon0)
    co = math.cos(lon0)
    t = cl * u - sl * n
    return x0 + co * t - so * e, y0 + so * t + co * e, z0 + sl * u + cl * n


# Branch-free fast path for arrays (LLVM vectorises it): a polynomial atan2 and Halley's cube root replace the libm
# calls. Points the fast path does not cover (inside the evolute or far below the surface: r <= 0 or s > 1) are
# flagged and redone by the exact scalar kernel above.

# atan(t)/t = P(t²) for |t| <= tan(π/8): Chebyshev least-squares fit (degree 9 in t²), max error 6e-16 rad.
_ATAN_C = (
    0.9999999999999994,
    -0.3333333333322165,
    0.1999999997841435,
    -0.14285712661858607,
    0.11111048822077872,
    -0.09089528779683545,
    0.07673517252047024,
    -0.06505839577488139,
    0.050241935707753746,
    -0.025307491891893078,
)
_TAN_PI_8 = math.tan(math.pi / 8.0)


@njit(cache=True, inline="always", error_model="numpy")
def _atan2_fast(y: float, x: float) -> float:
    ax = abs(x)
    ay = abs(y)
    mx = max(ax, ay)
    mn = min(ax, ay)
    t = mn / mx if mx > 0.0 else 0.0
    big = t > _TAN_PI_8
    t = (t - 1.0) / (t + 1.0) if big else t
    s = t * t
    c = _ATAN_C
    poly = c[9]
    poly = poly * s + c[8]
    poly = poly * s + c[7]
    poly = poly * s + c[6]
    poly = poly * s + c[5]
    poly = poly * s + c[4]
    poly = poly * s + c[3]
    poly = poly * s + c[2]
    poly = poly * s + c[1]
    poly = poly * s + c[0]
    a = t * poly + (0.25 * math.pi if big else 0.0)
    a = 0.5 * math.pi - a if ay > ax else a
    a = math.pi - a if x < 0.0 else a
    return -a if y < 0.0 else a


@njit(cache=True, error_model="numpy")
def _ecef2geo_fast_loop(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, lat: np.ndarray, lon: np.ndarray, h: np.ndarray, flag: np.ndarray
) -> int:
    a2 = WGS84_A * WGS84_A
    e2 = WGS84_E2
    e4 = e2 * e2
    e2m = 1.0 - e2
    slope = (3.7320508075688772 ** (1.0 / 3.0) - 1.0) / 2.7320508075688772
    for i in range(x.size):
        xi = x[i]
        yi = y[i]
        zi = z[i]
        rr = xi * xi + yi * yi
        rxy = math.sqrt(rr)
        p = rr / a2
        q = e2m * zi * zi / a2
        r = (p + q - e4) / 6.0
        s = e4 * p * q / (4.0 * r * r * r)
        flag[i] = not (r > 0.0 and s <= 1.0)
        aa = 1.0 + s + math.sqrt(s * (2.0 + s))
        g = 1.0 + slope * (aa - 1.0)
        for _ in range(3):  # Halley: g <- g (g³ + 2A) / (2g³ + A)
            g3 = g * g * g
            g = g * (g3 + 2.0 * aa) / (2.0 * g3 + aa)
        u = r * (1.0 + g + 1.0 / g)
        v = math.sqrt(u * u + e4 * q)
        uv = u + v
        w = e2 * (uv - q) / (2.0 * v)
        k = uv / (math.sqrt(uv + w * w) + w)
        d = k * rxy / (k + e2)
        lat[i] = _atan2_fast(zi * (k + e2), k * rxy) / _DEG
        lon[i] = _atan2_fast(yi, xi) / _DEG
        h[i] = (k + e2 - 1.0) / k * math.sqrt(d * d + zi * zi)
    n_slow = 0
    for i in range(x.size):
        if flag[i]:
            la, lo, hh = _ecef2geo(x[i], y[i], z[i])
            lat[i] = la / _DEG
            lon[i] = lo / _DEG
            h[i] = hh
            n_slow += 1
    return n_slow


# ---------------------------------------------------------------------------------------------------------------
# array loops


@njit(cache=True)
def _geo2ecef_loop(lat: np.ndarray, lon: np.ndarray, h: np.ndarray, out: np.ndarray) -> None:
    for i in range(lat.size):
        out[0, i], out[1, i], out[2, i] = _geo2ecef(lat[i] * _DEG, lon[i] * _DEG, h[i])


@njit(cache=True)
def _ecef2enu_loop(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, lat0: np.ndarray, lon0: np.ndarray, h0: np.ndarray, out: np.ndarray
) -> None:
    for i in range(x.size):
        out[0, i], out[1, i], out[2, i] = _ecef2enu(x[i], y[i], z[i], lat0[i] * _DEG, lon0[i] * _DEG, h0[i])


@njit(cache=True)
def _enu2ecef_loop(
    e: np.ndarray, n: np.ndarray, u: np.ndarray, lat0: np.ndarray, lon0: np.ndarray, h0: np.ndarray, out: np.ndarray
) -> None:
    for i in range(e.size):
        out[0, i], out[1, i], out[2, i] = _enu2ecef(e[i], n[i], u[i], lat0[i] * _DEG, lon0[i] * _DEG, h0[i])


def _all_scalar(args: tuple[Any, ...]) -> bool:
    return all(isinstance(a, _SCALAR_TYPES) for a in args)


def _flat(args: tuple[Any, ...]) -> tuple[tuple[int, ...], list[np.ndarray]]:
    arrays = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in args))
    shape = arrays[0].shape
    return shape, [np.ascontiguousarray(a).reshape(-1) for a in arrays]


def _unflat(out: np.ndarray, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return out[0].reshape(shape), out[1].reshape(shape), out[2].reshape(shape)


Triple = tuple[Any, Any, Any]


# ---------------------------------------------------------------------------------------------------------------
# public conversions


def geodetic_to_ecef(lat_deg: Any, lon_deg: Any, h_m: Any) -> Triple:
    """Geodetic (WGS84) to ECEF.

    Args:
        lat_deg: latitude, degrees (scalar or array).
        lon_deg: longitude, degrees.
        h_m: ellipsoidal height, metres.

    Returns:
        (x, y, z) ECEF metres, floats for scalar input, else arrays of the broadcast shape.
    """
    args = (lat_deg, lon_deg, h_m)
    if _all_scalar(args):
        return _geo2ecef(float(lat_deg) * _DEG, float(lon_deg) * _DEG, float(h_m))
    shape, flat = _flat(args)
    out = np.empty((3, flat[0].size))
    _geo2ecef_loop(flat[0], flat[1], flat[2], out)
    return _unflat(out, shape)


def ecef_to_geodetic(x_m: Any, y_m: Any, z_m: Any) -> Triple:
    """ECEF to geodetic (WGS84), exact closed form (Vermeille), finite everywhere.

    Args:
        x_m, y_m, z_m: ECEF coordinates, metres (scalars or broadcastable arrays).

    Returns:
        (lat_deg, lon_deg, h_m): latitude in [-90, 90] and longitude in [-180, 180] degrees (0 on the polar
        axis), ellipsoidal height in metres (negative inside the ellipsoid). For a point on the equatorial plane
        inside the evolute (|r| < a·e², including the centre) the nearest surface point is not unique; the
        northern one is returned (southern for z = -0.0).
    """
    args = (x_m, y_m, z_m)
    if _all_scalar(args):
        lat, lon, h = _ecef2geo(float(x_m), float(y_m), float(z_m))
        return lat / _DEG, lon / _DEG, h
    shape, flat = _flat(args)
    out = np.empty((3, flat[0].size))
    flag = np.empty(flat[0].size, dtype=np.bool_)
    _ecef2geo_fast_loop(flat[0], flat[1], flat[2], out[0], out[1], out[2], flag)
    return _unflat(out, shape)


def ecef_to_enu(x: Any, y: Any, z: Any, lat0_deg: Any, lon0_deg: Any, h0_m: Any) -> Triple:
    """ECEF point(s) to the local ENU frame at a geodetic origin.

    Args:
        x, y, z: ECEF metres.
        lat0_deg, lon0_deg, h0_m: origin, degrees and metres (usually scalars; broadcast with the points).

    Returns:
        (east, north, up) metres.
    """
    args = (x, y, z, lat0_deg, lon0_deg, h0_m)
    if _all_scalar(args):
        return _ecef2enu(float(x), float(y), float(z), float(lat0_deg) * _DEG, float(lon0_deg) * _DEG, float(h0_m))
    shape, flat = _flat(args)
    out = np.empty((3, flat[0].size))
    _ecef2enu_loop(flat[0], flat[1], flat[2], flat[3], flat[4], flat[5], out)
    return _unflat(out, shape)


def enu_to_ecef(e: Any, n: Any, u: Any, lat0_deg: Any, lon0_deg: Any, h0_m: Any) -> Triple:
    """Local ENU (metres, origin in degrees/metres) to ECEF metres; the inverse of `ecef_to_enu`."""
    args = (e, n, u, lat0_deg, lon0_deg, h0_m)
    if _all_scalar(args):
        return _enu2ecef(float(e), float(n), float(u), float(lat0_deg) * _DEG, float(lon0_deg) * _DEG, float(h0_m))
    shape, flat = _flat(args)
    out = np.empty((3, flat[0].size))
    _enu2ecef_loop(flat[0], flat[1], flat[2], flat[3], flat[4], flat[5], out)
    return _unflat(out, shape)


def ecef_to_ned(x: Any, y: Any, z: Any, lat0_deg: Any, lon0_deg: Any, h0_m: Any) -> Triple:
    """ECEF point(s) to the local NED frame at a geodetic origin: returns (north, east, down) metres."""
    e, n, u = ecef_to_enu(x, y, z, lat0_deg, lon0_deg, h0_m)
    return n, e, -u


def ned_to_ecef(n: Any, e: Any, d: Any, lat0_deg: Any, lon0_deg: Any, h0_m: Any) -> Triple:
    """Local NED (metres) at a geodetic origin to ECEF metres; the inverse of `ecef_to_ned`."""
    return enu_to_ecef(e, n, -d if _all_scalar((d,)) else -np.asarray(d, dtype=np.float64), lat0_deg, lon0_deg, h0_m)


def geodetic_to_enu(lat_deg: Any, lon_deg: Any, h_m: Any, lat0_deg: Any, lon0_deg: Any, h0_m: Any) -> Triple:
    """Geodetic point(s) (degrees, metres) to local ENU metres at a geodetic origin."""
    x, y, z = geodetic_to_ecef(lat_deg, lon_deg, h_m)
    return ecef_to_enu(x, y, z, lat0_deg, lon0_deg, h0_m)


def geodetic_to_ned(lat_deg: Any, lon_deg: Any, h_m: Any, lat0_deg: Any, lon0_deg: Any, h0_m: Any) -> Triple:
    """Geodetic point(s) (degrees, metres) to local NED metres at a geodetic origin."""
    x, y, z = geodetic_to_ecef(lat_deg, lon_deg, h_m)
    return ecef_to_ned(x, y, z, lat0_deg, lon0_deg, h0_m)


def enu_to_geodetic(e: Any, n: Any, u: Any, lat0_deg: Any, lon0_deg: Any, h0_m: Any) -> Triple:
    """Local ENU metres at a geodetic origin to geodetic (lat_deg, lon_deg, h_m)."""
    x, y, z = enu_to_ecef(e, n, u, lat0_deg, lon0_deg, h0_m)
    return ecef_to_geodetic(x, y, z)


def ned_to_geodetic(n: Any, e: Any, d: Any, lat0_deg: Any, lon0_deg: Any, h0_m: Any) -> Triple:
    """Local NED metres at a geodetic origin to geodetic (lat_deg, lon_deg, h_m)."""
    x, y, z = ned_to_ecef(n, e, d, lat0_deg, lon0_deg, h0_m)
    return ecef_to_geodetic(x, y, z)


# ---------------------------------------------------------------------------------------------------------------
# body rotations and Euler angles


@njit(cache=True)
def _rot_zyx(roll: float, pitch: float, yaw: float, out: np.ndarray) -> None:
    sr, cr = math.sin(roll), math.cos(roll)
    sp, cp = math.sin(pitch), math.cos(pitch)
    sy, cy = math.sin(yaw), math.cos(yaw)
    out[0, 0] = cy * cp
    out[0, 1] = cy * sp * sr - sy * cr
    out[0, 2] = cy * sp * cr + sy * sr
    out[1, 0] = sy * cp
    out[1, 1] = sy * sp * sr + cy * cr
    out[1, 2] = sy * sp * cr - cy * sr
    out[2, 0] = -sp
    out[2, 1] = cp * sr
    out[2, 2] = cp * cr


@njit(cache=True)
def _rotate_loop(v: np.ndarray, roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray, transpose: bool) -> np.ndarray:
    out = np.empty_like(v)
    m = np.empty((3, 3))
    for i in range(v.shape[0]):
        _rot_zyx(roll[i], pitch[i], yaw[i], m)
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += (m[k, j] if transpose else m[j, k]) * v[i, k]
            out[i, j] = acc
    return out


def rotation_body_to_ned(roll: Any, pitch: Any, yaw: Any) -> np.ndarray:
    """The ZYX rotation matrix ``R_nb = Rz(yaw) Ry(pitch) Rx(roll)`` (body FRD → NED).

    Args:
        roll, pitch, yaw: radians, scalars or broadcastable arrays of shape S.

    Returns:
        (3, 3) array for scalars, else S + (3, 3).
    """
    r, p, y = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (roll, pitch, yaw)))
    sr, cr, sp, cp, sy, cy = np.sin(r), np.cos(r), np.sin(p), np.cos(p), np.sin(y), np.cos(y)
    out = np.empty((*r.shape, 3, 3))
    out[..., 0, 0] = cy * cp
    out[..., 0, 1] = cy * sp * sr - sy * cr
    out[..., 0, 2] = cy * sp * cr + sy * sr
    out[..., 1, 0] = sy * cp
    out[..., 1, 1] = sy * sp * sr + cy * cr
    out[..., 1, 2] = sy * sp * cr - cy * sr
    out[..., 2, 0] = -sp
    out[..., 2, 1] = cp * sr
    out[..., 2, 2] = cp * cr
    return out


def _rotate(v: Any, roll: Any, pitch: Any, yaw: Any, transpose: bool) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    if v.shape[-1:] != (3,):
        raise InvalidParameterError(f"vectors must have a last axis of 3, got shape {v.shape}")
    angles = [np.asarray(a, dtype=np.float64) for a in (roll, pitch, yaw)]
    shape = np.broadcast_shapes(v.shape[:-1], *(a.shape for a in angles))
    vb = np.ascontiguousarray(np.broadcast_to(v, (*shape, 3))).reshape(-1, 3)
    ab = [np.ascontiguousarray(np.broadcast_to(a, shape)).reshape(-1) for a in angles]
    return _rotate_loop(vb, ab[0], ab[1], ab[2], transpose).reshape((*shape, 3))


def ned_to_body(v_ned: Any, roll: Any, pitch: Any, yaw: Any) -> np.ndarray:
    """Rotate NED vector(s) into the body FRD frame: ``v_b = R_nb(roll, pitch, yaw)ᵀ v_n`` (ZYX Euler, radians).

    Args:
        v_ned: (..., 3) vectors in NED (any unit).
        roll, pitch, yaw: radians, broadcastable with ``v_ned[..., 0]``.

    Returns:
        (..., 3) vectors in the body frame.
    """
    return _rotate(v_ned, roll, pitch, yaw, True)


def body_to_ned(v_body: Any, roll: Any, pitch: Any, yaw: Any) -> np.ndarray:
    """Rotate body FRD vector(s) into NED: ``v_n = R_nb(roll, pitch, yaw) v_b``; the inverse of `ned_to_body`."""
    return _rotate(v_body, roll, pitch, yaw, False)


def euler_rate_matrix(roll: float, pitch: float, tol: float = 1e-6) -> np.ndarray:
    """The ZYX kinematic matrix W with ``[roll_dot, pitch_dot, yaw_dot] = W(roll, pitch) @ [p, q, r]``.

    ``W = [[1, sinφ tanθ, cosφ tanθ], [0, cosφ, -sinφ], [0, sinφ/cosθ, cosφ/cosθ]]``.

    Args:
        roll, pitch: radians.
        tol: smallest accepted |cos(pitch)|.

    Raises:
        GimbalLockError: |cos(pitch)| < tol.
    """
    cp = math.cos(pitch)
    if abs(cp) < tol:
        raise GimbalLockError(f"pitch {pitch!r} rad is within gimbal lock (|cos(pitch)| = {abs(cp):.3g} < {tol})")
    sr, cr = math.sin(roll), math.cos(roll)
    tp = math.sin(pitch) / cp
    return np.array([[1.0, sr * tp, cr * tp], [0.0, cr, -sr], [0.0, sr / cp, cr / cp]])


def euler_rates(roll: Any, pitch: Any, p: Any, q: Any, r: Any, tol: float = 1e-6) -> np.ndarray:
    """ZYX Euler angle rates from body rates: ``W(roll, pitch) @ [p, q, r]``.

    Args:
        roll, pitch: radians; p, q, r: body rates (FRD), rad/s. Scalars or broadcastable arrays of shape S.
        tol: smallest accepted |cos(pitch)|.

    Returns:
        (3,) array [roll_dot, pitch_dot, yaw_dot] rad/s for scalars, else S + (3,).

    Raises:
        GimbalLockError: some |cos(pitch)| < tol (the yaw and roll rates are unbounded there).
    """
    if _all_scalar((roll, pitch, p, q, r)):
        cp = math.cos(pitch)
        if abs(cp) < tol:
            raise GimbalLockError(f"pitch {pitch!r} rad is within gimbal lock (|cos(pitch)| = {abs(cp):.3g} < {tol})")
        sr, cr = math.sin(roll), math.cos(roll)
        a = q * sr + r * cr
        return np.array([p + a * math.sin(pitch) / cp, q * cr - r * sr, a / cp])
    ph, th, pp, qq, rr = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (roll, pitch, p, q, r)))
    cp = np.cos(th)
    if np.any(np.abs(cp) < tol):
        raise GimbalLockError(f"a pitch is within gimbal lock (|cos(pitch)| < {tol})")
    sr, cr = np.sin(ph), np.cos(ph)
    a = qq * sr + rr * cr
    return np.stack([pp + a * np.tan(th), qq * cr - rr * sr, a / cp], axis=-1)


def quat_from_euler(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Unit quaternion (w, x, y, z), body → NED, of the ZYX Euler angles (radians)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return np.array(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ]
    )


def euler_from_quat(quat: Any) -> np.ndarray:
    """ZYX Euler angles [roll, pitch, yaw] (radians) of a (w, x, y, z) body → NED quaternion; (4,) or (N, 4)."""
    qv = np.asarray(quat, dtype=np.float64)
    w, x, y, z = qv[..., 0], qv[..., 1], qv[..., 2], qv[..., 3]
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=-1)


@njit(cache=True)
def _qmul(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    aw, ax, ay, az = a[0], a[1], a[2], a[3]
    bw, bx, by, bz = b[0], b[1], b[2], b[3]
    out[0] = aw * bw - ax * bx - ay * by - az * bz
    out[1] = aw * bx + ax * bw + ay * bz - az * by
    out[2] = aw * by - ax * bz + ay * bw + az * bx
    out[3] = aw * bz + ax * by - ay * bx + az * bw


def quat_multiply(a: Any, b: Any) -> np.ndarray:
    """Hamilton product a ⊗ b of two (4,) quaternions (w, x, y, z)."""
    out = np.empty(4)
    _qmul(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64), out)
    return out


def quat_to_rotation(quat: Any) -> np.ndarray:
    """(3, 3) rotation matrix (body → NED) of a (w, x, y, z) quaternion (normalised first)."""
    qv = np.asarray(quat, dtype=np.float64)
    w, x, y, z = qv / np.linalg.norm(qv)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )

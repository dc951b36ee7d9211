"""Frames: WGS84 conversions against GeographicLib (CartConvert), local frames, rotations and Euler rates."""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mjnav.aerial import (
    GimbalLockError,
    body_to_ned,
    ecef_to_enu,
    ecef_to_geodetic,
    ecef_to_ned,
    enu_to_ecef,
    enu_to_geodetic,
    euler_from_quat,
    euler_rate_matrix,
    euler_rates,
    geodetic_to_ecef,
    geodetic_to_enu,
    geodetic_to_ned,
    ned_to_body,
    ned_to_ecef,
    ned_to_geodetic,
    quat_from_euler,
    quat_multiply,
    quat_to_rotation,
    rotation_body_to_ned,
)
from tests.aerial.geo_reference import cartconvert, load_table, reference_table

LAT_TOL_DEG = 1e-9
LEN_TOL_M = 1e-3


def _check_against(table: np.ndarray) -> None:
    lat, lon, h, x, y, z = table.T
    ex, ey, ez = geodetic_to_ecef(lat, lon, h)
    assert np.max(np.abs(np.column_stack([ex, ey, ez]) - table[:, 3:])) < LEN_TOL_M
    glat, glon, gh = ecef_to_geodetic(x, y, z)
    assert np.all(np.isfinite(glat)) and np.all(np.isfinite(glon)) and np.all(np.isfinite(gh))
    assert np.max(np.abs(glat - lat)) < LAT_TOL_DEG
    assert np.max(np.abs(gh - h)) < LEN_TOL_M
    off_axis = np.hypot(x, y) > 1.0  # the longitude of a point on the polar axis is arbitrary
    dlon = np.abs((glon - lon + 180.0) % 360.0 - 180.0)
    assert np.max(dlon[off_axis]) < LAT_TOL_DEG


def test_committed_geographiclib_table() -> None:
    table = load_table()
    assert table.shape == (200, 6)
    assert np.any(np.abs(table[:, 0]) == 90.0) and np.any(np.abs(table[:, 1]) == 180.0)
    assert table[:, 2].min() < -5_000.0 and table[:, 2].max() > 1.0e7
    assert np.any(np.linalg.norm(table[:, 3:], axis=1) < 1.0)  # the centre of the Earth
    _check_against(table)


@pytest.mark.skipif(shutil.which("CartConvert") is None, reason="CartConvert not installed (geographiclib-tools)")
def test_fresh_cartconvert_points() -> None:
    _check_against(reference_table(np.random.default_rng(2026), 1500, 1500))


@pytest.mark.skipif(shutil.which("CartConvert") is None, reason="CartConvert not installed (geographiclib-tools)")
def test_local_enu_against_cartconvert() -> None:
    rng = np.random.default_rng(3)
    lat0, lon0, h0 = 47.3, 179.9, 420.0
    pts = np.column_stack([rng.uniform(46.0, 48.5, 50), rng.uniform(178.5, 181.5, 50), rng.uniform(-100, 9e3, 50)])
    pts[:, 1] = (pts[:, 1] + 180.0) % 360.0 - 180.0  # straddles the antimeridian
    import subprocess

    text = "\n".join(f"{a:.17g} {b:.17g} {c:.17g}" for a, b, c in pts)
    out = subprocess.run(
        ["CartConvert", "-p", "9", "-l", str(lat0), str(lon0), str(h0)], input=text, capture_output=True, text=True
    ).stdout
    ref = np.array([[float(v) for v in ln.split()] for ln in out.strip().splitlines()])
    e, n, u = geodetic_to_enu(pts[:, 0], pts[:, 1], pts[:, 2], lat0, lon0, h0)
    assert np.max(np.abs(np.column_stack([e, n, u]) - ref)) < LEN_TOL_M
    nn, ee, dd = geodetic_to_ned(pts[:, 0], pts[:, 1], pts[:, 2], lat0, lon0, h0)
    np.testing.assert_allclose(np.column_stack([nn, ee, -dd]), ref[:, [1, 0, 2]], atol=LEN_TOL_M)
    assert cartconvert(pts[:1], reverse=False).shape == (1, 3)


def test_fast_path_agrees_with_exact_kernel() -> None:
    """The vectorised path (polynomial atan2, Halley cube root) matches the exact scalar kernel everywhere."""
    rng = np.random.default_rng(5)
    d = rng.normal(size=(20000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    pts = d * 10.0 ** rng.uniform(3.0, 7.7, 20000)[:, None]
    lat, lon, h = ecef_to_geodetic(pts[:, 0], pts[:, 1], pts[:, 2])
    exact = np.array([ecef_to_geodetic(*map(float, p)) for p in pts[::50]])
    np.testing.assert_allclose(lat[::50], exact[:, 0], atol=1e-11)
    np.testing.assert_allclose(lon[::50], exact[:, 1], atol=1e-11)
    np.testing.assert_allclose(h[::50], exact[:, 2], atol=1e-7)


def test_no_nan_at_awkward_points() -> None:
    a = 6378137.0
    pts = np.array(
        [
            [0.0, 0.0, 0.0],
            [0.0, 0.0, -0.0],
            [1e-300, 0.0, 1e-300],
            [42_000.0, 0.0, 0.0],  # on the evolute
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 6356752.314245179],
            [0.0, 0.0, -7.0e6],
            [-a, 0.0, 0.0],
            [-a, -0.0, 0.0],
            [a + 4e7, 0.0, 1.0],
            [1e3, 1e3, 1e3],
            [1e10, 1e10, 1e10],
        ]
    )
    lat, lon, h = ecef_to_geodetic(pts[:, 0], pts[:, 1], pts[:, 2])
    assert np.all(np.isfinite(lat)) and np.all(np.isfinite(lon)) and np.all(np.isfinite(h))
    assert lat[0] == 90.0 and h[0] == pytest.approx(-6356752.314245179, abs=1e-6)  # the centre is b below the pole
    assert lat[1] == -90.0
    assert h[5] == pytest.approx(0.0, abs=1e-6) and lat[5] == 90.0
    assert lat[6] == -90.0 and h[6] == pytest.approx(7.0e6 - 6356752.314245179, abs=1e-6)
    assert abs(lon[7]) == 180.0 and h[7] == pytest.approx(0.0, abs=1e-6)
    # the forward round trip holds for the inside points too
    x, y, z = geodetic_to_ecef(lat, lon, h)
    np.testing.assert_allclose(np.column_stack([x, y, z])[:10], pts[:10], atol=1e-6)


def test_scalar_and_array_calls_agree_and_keep_shape() -> None:
    lat, lon, h = ecef_to_geodetic(4e6, -3e6, 3.5e6)
    assert isinstance(lat, float) and isinstance(h, float)
    grid = np.array([[4e6, 1e6], [2e6, -7e6]])
    out = ecef_to_geodetic(grid, -3e6, 3.5e6)
    assert out[0].shape == (2, 2)
    # arrays take the vectorised fast path, scalars the exact scalar kernel: the same to rounding
    assert out[0][0, 0] == pytest.approx(lat, abs=1e-12) and out[1][0, 0] == pytest.approx(lon, abs=1e-12)
    assert out[2][0, 0] == pytest.approx(h, abs=1e-8)
    x, _, _ = geodetic_to_ecef(np.float64(10.0), 20, 30.0)
    assert isinstance(x, float)


def test_local_frames_round_trip_and_axes() -> None:
    lat0, lon0, h0 = -33.9, 151.2, 40.0
    n, e, d = geodetic_to_ned(lat0 + 1e-3, lon0, h0, lat0, lon0, h0)
    assert n > 100.0 and abs(e) < 1e-6 and d > 0.0  # north of the origin; the Earth curves away (down > 0)
    e2, n2, u2 = geodetic_to_enu(lat0, lon0 + 1e-3, h0 + 5.0, lat0, lon0, h0)
    assert e2 > 90.0 and abs(n2) < 0.01 and u2 == pytest.approx(5.0, abs=0.01)
    rng = np.random.default_rng(0)
    ned = rng.uniform(-5e4, 5e4, (100, 3))
    lat, lon, h = ned_to_geodetic(ned[:, 0], ned[:, 1], ned[:, 2], lat0, lon0, h0)
    back = np.column_stack(geodetic_to_ned(lat, lon, h, lat0, lon0, h0))
    np.testing.assert_allclose(back, ned, atol=1e-6)
    x, y, z = ned_to_ecef(ned[:, 0], ned[:, 1], ned[:, 2], lat0, lon0, h0)
    np.testing.assert_allclose(np.column_stack(ecef_to_ned(x, y, z, lat0, lon0, h0)), ned, atol=1e-6)
    xs, ys, zs = enu_to_ecef(1.0, 2.0, 3.0, lat0, lon0, h0)
    assert ecef_to_enu(xs, ys, zs, lat0, lon0, h0) == pytest.approx((1.0, 2.0, 3.0), abs=1e-7)
    assert enu_to_geodetic(0.0, 0.0, 0.0, lat0, lon0, h0) == pytest.approx((lat0, lon0, h0), abs=1e-7)


def test_rotation_matches_quaternion_and_inverse() -> None:
    rng = np.random.default_rng(1)
    angles = rng.uniform([-math.pi, -1.5, -math.pi], [math.pi, 1.5, math.pi], (20, 3))
    mats = rotation_body_to_ned(angles[:, 0], angles[:, 1], angles[:, 2])
    for (r, p, y), m in zip(angles, mats, strict=True):
        np.testing.assert_allclose(m, quat_to_rotation(quat_from_euler(r, p, y)), atol=1e-12)
        np.testing.assert_allclose(euler_from_quat(quat_from_euler(r, p, y)), [r, p, y], atol=1e-9)
    v = rng.normal(size=(20, 3))
    vb = ned_to_body(v, angles[:, 0], angles[:, 1], angles[:, 2])
    np.testing.assert_allclose(vb, np.einsum("nji,nj->ni", mats, v), atol=1e-12)
    np.testing.assert_allclose(body_to_ned(vb, angles[:, 0], angles[:, 1], angles[:, 2]), v, atol=1e-12)
    # yaw 90°: north is the body's left (-y) side; pitch up 90°: down-vector seen along the body's +x
    np.testing.assert_allclose(ned_to_body([1.0, 0, 0], 0.0, 0.0, math.pi / 2), [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(ned_to_body([0, 0, -1.0], 0.0, math.pi / 2, 0.0), [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(ned_to_body([0, 1.0, 0], math.pi / 2, 0.0, 0.0), [0, 0, -1], atol=1e-12)


def test_euler_rates_match_quaternion_integration() -> None:
    """Integrating the W-matrix rates and integrating q̇ = ½ q ⊗ (0, ω) give the same attitude for 10 s."""

    def omega(t: float) -> np.ndarray:
        return np.array([0.6 * math.sin(1.3 * t), 0.4 * math.cos(0.7 * t + 0.2), 0.8 + 0.3 * math.sin(0.5 * t)])

    e0 = np.array([0.2, -0.3, 2.9])

    def f_euler(t: float, e: np.ndarray) -> np.ndarray:
        w = omega(t)
        return euler_rates(e[0], e[1], w[0], w[1], w[2])

    def f_quat(t: float, q: np.ndarray) -> np.ndarray:
        return 0.5 * quat_multiply(q, np.concatenate([[0.0], omega(t)]))

    kw = {"method": "DOP853", "rtol": 1e-12, "atol": 1e-13, "t_eval": np.linspace(0, 10, 101)}
    se = solve_ivp(f_euler, (0, 10), e0, **kw)
    sq = solve_ivp(f_quat, (0, 10), quat_from_euler(*e0), **kw)
    eq = euler_from_quat(sq.y.T / np.linalg.norm(sq.y.T, axis=1, keepdims=True))
    diff = (se.y.T - eq + math.pi) % (2 * math.pi) - math.pi
    assert np.max(np.abs(diff)) < 1e-9
    assert np.ptp(np.unwrap(se.y[2])) > 5.0  # the yaw really turned


def test_euler_rates_formula_and_gimbal_lock() -> None:
    w = euler_rate_matrix(0.3, 0.4)
    np.testing.assert_allclose(euler_rates(0.3, 0.4, 0.1, -0.2, 0.5), w @ [0.1, -0.2, 0.5], atol=1e-15)
    np.testing.assert_allclose(euler_rates(0.0, 0.0, 0.1, 0.2, 0.3), [0.1, 0.2, 0.3])
    arr = euler_rates(np.array([0.3, 0.0]), np.array([0.4, 0.0]), 0.1, -0.2, 0.5)
    np.testing.assert_allclose(arr[0], w @ [0.1, -0.2, 0.5], atol=1e-15)
    with pytest.raises(GimbalLockError):
        euler_rates(0.1, math.pi / 2, 0.1, 0.2, 0.3)
    with pytest.raises(ValueError):
        euler_rates(np.zeros(2), np.array([0.0, -math.pi / 2 + 1e-9]), 0.0, 0.0, 0.0)
    with pytest.raises(GimbalLockError):
        euler_rate_matrix(0.0, -math.pi / 2)

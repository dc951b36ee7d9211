"""Synthetic laser scans for the scan-matching tests: an analytic ray caster over wall segments."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

# A 10 m × 6 m room (corner at the origin) with an inner box and an alcove wall: (x0, y0, x1, y1) segments.
ROOM: NDArray[np.float64] = np.array(
    [
        (0.0, 0.0, 10.0, 0.0),
        (10.0, 0.0, 10.0, 6.0),
        (10.0, 6.0, 0.0, 6.0),
        (0.0, 6.0, 0.0, 0.0),
        (6.0, 2.0, 7.0, 2.0),
        (7.0, 2.0, 7.0, 3.5),
        (7.0, 3.5, 6.0, 3.5),
        (6.0, 3.5, 6.0, 2.0),
        (2.0, 6.0, 2.0, 4.5),
        (8.5, 0.0, 9.2, 1.2),
    ]
)

# A corridor: two long parallel walls 2 m apart, 60 m long (ends out of range).
CORRIDOR: NDArray[np.float64] = np.array([(-30.0, -1.0, 30.0, -1.0), (-30.0, 1.0, 30.0, 1.0)])


def raycast(
    segments: NDArray[np.float64],
    pose: tuple[float, float, float],
    n_beams: int = 360,
    fov_rad: float = 2.0 * math.pi,
    max_range_m: float = 20.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(angles (B,), ranges (B,)) of beams from ``pose`` (inf where nothing is hit within max range)."""
    if fov_rad >= 2.0 * math.pi:
        angles = np.arange(n_beams) * (2.0 * math.pi / n_beams) - math.pi
    else:
        angles = np.linspace(-0.5 * fov_rad, 0.5 * fov_rad, n_beams)
    x, y, th = pose
    d = np.column_stack((np.cos(angles + th), np.sin(angles + th)))  # (B, 2)
    p0 = segments[:, :2]
    e = segments[:, 2:] - p0  # (S, 2)
    w = p0 - np.array([x, y])  # (S, 2)
    den = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]  # (B, S)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[None, :, 0] * e[None, :, 1] - w[None, :, 1] * e[None, :, 0]) / den
        u = (w[None, :, 0] * d[:, None, 1] - w[None, :, 1] * d[:, None, 0]) / den
    ok = (np.abs(den) > 1e-12) & (t > 1e-9) & (u >= 0.0) & (u <= 1.0)
    r = np.where(ok, t, np.inf).min(axis=1)
    r[r > max_range_m] = np.inf
    return angles, r


def scan_points(
    segments: NDArray[np.float64],
    pose: tuple[float, float, float],
    rng: np.random.Generator | None = None,
    noise_m: float = 0.0,
    n_beams: int = 360,
    fov_rad: float = 2.0 * math.pi,
) -> NDArray[np.float64]:
    """(N, 2) points in the sensor frame of a scan from ``pose`` (range noise σ = ``noise_m``)."""
    a, r = raycast(segments, pose, n_beams, fov_rad)
    if rng is not None and noise_m > 0:
        r = r + rng.normal(0.0, noise_m, r.shape)
    ok = np.isfinite(r)
    return np.column_stack((r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])))


def relative(a: tuple[float, float, float], b: tuple[float, float, float]) -> NDArray[np.float64]:
    """a⁻¹·b as (x, y, θ)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    dth = (b[2] - a[2] + math.pi) % (2 * math.pi) - math.pi
    return np.array([c * dx + s * dy, -s * dx + c * dy, dth])

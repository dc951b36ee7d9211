"""Reference points from GeographicLib's CartConvert (Debian `geographiclib-tools`), used by the frame tests.

`make_points` draws seeded geodetic and ECEF points that cover the poles, the antimeridian, z = 0, the inside of the
Earth (to its centre) and altitudes from -10 km to 40,000 km; `cartconvert` runs them through CartConvert. The
committed table `data/geographiclib_points.csv` was written by `python -m tests.aerial.geo_reference` (seed 14).
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np

TABLE = Path(__file__).resolve().parent / "data" / "geographiclib_points.csv"
HEADER = "lat_deg,lon_deg,h_m,x_m,y_m,z_m"


def make_points(rng: np.random.Generator, n_geodetic: int, n_ecef: int) -> tuple[np.ndarray, np.ndarray]:
    """(n_geodetic, 3) lat/lon/h inputs and (n_ecef, 3) ECEF inputs covering the awkward places."""
    lat = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n_geodetic)))
    lon = rng.uniform(-180.0, 180.0, n_geodetic)
    k = max(n_geodetic // 10, 1)
    lat[:k] = rng.choice([-90.0, 90.0], k)
    lon[k : 2 * k] = rng.choice([-180.0, 180.0], k)
    lat[2 * k : 3 * k] = 0.0
    h = np.where(
        rng.uniform(size=n_geodetic) < 0.5,
        rng.uniform(-10_000.0, 10_000.0, n_geodetic),
        10.0 ** rng.uniform(4.0, np.log10(4.0e7), n_geodetic),
    )
    geo = np.column_stack([lat, lon, h])
    d = rng.normal(size=(n_ecef, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    radius = np.where(
        rng.uniform(size=n_ecef) < 0.5, rng.uniform(0.0, 6.4e6, n_ecef), 10.0 ** rng.uniform(6.8, 7.66, n_ecef)
    )
    xyz = d * radius[:, None]
    m = max(n_ecef // 8, 1)
    xyz[:m, 2] = 0.0  # equatorial plane, inside and outside the evolute
    xyz[m : 2 * m, :2] = 0.0  # polar axis
    xyz[2 * m, :] = 0.0  # the centre
    xyz[2 * m + 1 : 3 * m, 1] = rng.choice([-1e-9, 0.0, 1e-9], m - 1)  # antimeridian / prime meridian plane
    return geo, xyz


def cartconvert(rows: np.ndarray, reverse: bool) -> np.ndarray:
    """Run (N, 3) rows through CartConvert (forward: geodetic → ECEF; reverse: ECEF → geodetic)."""
    exe = shutil.which("CartConvert")
    if exe is None:
        raise FileNotFoundError("CartConvert not found (Debian package geographiclib-tools)")
    text = "\n".join(" ".join(f"{v:.17g}" for v in row) for row in rows) + "\n"
    args = [exe, "-p", "9"] + (["-r"] if reverse else [])
    out = subprocess.run(args, input=text, capture_output=True, text=True, check=True).stdout
    return np.array([[float(v) for v in line.split()] for line in out.strip().splitlines()])


def reference_table(rng: np.random.Generator, n_geodetic: int, n_ecef: int) -> np.ndarray:
    """(N, 6) rows lat, lon, h, x, y, z that CartConvert says are the same point."""
    geo, xyz = make_points(rng, n_geodetic, n_ecef)
    fwd = np.column_stack([geo, cartconvert(geo, reverse=False)])
    rev = np.column_stack([cartconvert(xyz, reverse=True), xyz])
    return np.vstack([fwd, rev])


def load_table() -> np.ndarray:
    """The committed (N, 6) reference table."""
    return np.loadtxt(TABLE, delimiter=",", skiprows=1)


if __name__ == "__main__":
    table = reference_table(np.random.default_rng(14), 120, 80)
    np.savetxt(TABLE, table, delimiter=",", header=HEADER, comments="", fmt="%.17g")
    print(f"wrote {len(table)} rows to {TABLE}")

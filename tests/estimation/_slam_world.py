"""A synthetic loop world for the SLAM tests: a ring corridor with features, a rounded-rectangle drive, scans."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from mjnav.mapping import OccupancyGrid
from tests.estimation._scans import raycast


def _box(x0: float, y0: float, x1: float, y1: float) -> list[tuple[float, float, float, float]]:
    return [(x0, y0, x1, y0), (x1, y0, x1, y1), (x1, y1, x0, y1), (x0, y1, x0, y0)]


# Outer walls 20 m × 14 m, an inner block 12 m × 6 m: a corridor 4 m wide around it, with boxes and alcoves on
# both walls so that no stretch is a featureless corridor.
RING: NDArray[np.float64] = np.array(
    _box(0.0, 0.0, 20.0, 14.0)
    + _box(4.0, 4.0, 16.0, 10.0)
    + _box(6.0, 0.0, 6.8, 0.9)
    + _box(12.0, 0.0, 13.5, 0.6)
    + _box(19.2, 5.0, 20.0, 6.5)
    + _box(15.0, 13.2, 16.0, 14.0)
    + _box(8.0, 13.0, 8.5, 14.0)
    + _box(0.0, 9.0, 1.0, 9.6)
    + _box(0.0, 3.0, 0.5, 4.5)
    + _box(9.0, 3.4, 10.5, 4.0)
    + _box(16.0, 7.0, 16.6, 8.2)
    + _box(7.0, 10.0, 7.8, 10.7)
    + _box(3.4, 6.0, 4.0, 7.5)
    + [(2.0, 1.0, 2.6, 1.6), (17.5, 12.5, 18.3, 12.0)]
)


def ring_drive(laps: float = 1.15, speed_mps: float = 1.0, dt_s: float = 0.1) -> NDArray[np.float64]:
    """(S, 3) true poses driving counter-clockwise around the corridor's centre line (a rounded rectangle
    from (2, 2) to (18, 12), corner radius 1 m), ``laps`` times, starting mid-way along the bottom side."""
    x0, y0, x1, y1, rc = 2.0, 2.0, 18.0, 12.0, 1.0
    w, h = x1 - x0 - 2 * rc, y1 - y0 - 2 * rc
    arc = 0.5 * math.pi * rc
    perimeter = 2 * w + 2 * h + 4 * arc
    s_all = np.arange(0.0, laps * perimeter, speed_mps * dt_s) + 0.5 * w
    out = np.empty((s_all.size, 3))
    # Pieces in order: bottom (→), corner, right (↑), corner, top (←), corner, left (↓), corner.
    pieces = [
        ("line", (x0 + rc, y0), 0.0, w),
        ("arc", (x1 - rc, y0 + rc), -0.5 * math.pi, arc),
        ("line", (x1, y0 + rc), 0.5 * math.pi, h),
        ("arc", (x1 - rc, y1 - rc), 0.0, arc),
        ("line", (x1 - rc, y1), math.pi, w),
        ("arc", (x0 + rc, y1 - rc), 0.5 * math.pi, arc),
        ("line", (x0, y1 - rc), -0.5 * math.pi, h),
        ("arc", (x0 + rc, y0 + rc), math.pi, arc),
    ]
    for k, s in enumerate(s_all):
        s = s % perimeter
        for kind, (px, py), ang, length in pieces:
            if s <= length:
                if kind == "line":
                    out[k] = (px + s * math.cos(ang), py + s * math.sin(ang), ang)
                else:
                    a = ang + s / rc
                    out[k] = (px + rc * math.cos(a), py + rc * math.sin(a), a + 0.5 * math.pi)
                break
            s -= length
    out[:, 2] = np.remainder(out[:, 2] + math.pi, 2 * math.pi) - math.pi
    return out


def scans(
    poses: NDArray[np.float64],
    rng: np.random.Generator,
    noise_m: float = 0.01,
    max_range_m: float = 12.0,
    world: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(angles (B,), ranges (S, B)) of 360-beam scans from ``poses`` in ``world`` (wall segments; default
    :data:`RING`; inf = no return)."""
    walls = RING if world is None else world
    rows = []
    angles = np.zeros(0)
    for p in poses:
        angles, r = raycast(walls, (float(p[0]), float(p[1]), float(p[2])), 360, 2 * math.pi, max_range_m)
        rows.append(r + rng.normal(0.0, noise_m, r.shape))
    return angles, np.array(rows)


def true_map(resolution_m: float = 0.05) -> OccupancyGrid:
    """The ring's occupancy grid built from exact scans at poses along the drive."""
    grid = OccupancyGrid(int(21 / resolution_m), int(15 / resolution_m), resolution_m, (-0.5, -0.5))
    poses = ring_drive(1.0, 0.5, 1.0)
    for p in poses:
        a, r = raycast(RING, (float(p[0]), float(p[1]), float(p[2])), 720, 2 * math.pi, 12.0)
        grid.integrate_scan(p, a, r, 12.0)
    return grid


# Two parallel corridors 2 m wide (A: 0 <= y <= 2, B: 2.2 <= y <= 4.2) behind a 0.2 m wall that ends at x = 11, so
# they join at the east end; each has its own boxes. Seen from 2.2 m aside, B's walls line up with A's.
TWO_CORRIDORS: NDArray[np.float64] = np.array(
    _box(0.0, 0.0, 14.0, 4.2)
    + _box(0.0, 2.0, 11.0, 2.2)
    + _box(3.0, 0.0, 3.5, 0.4)
    + _box(7.5, 0.0, 8.3, 0.3)
    + _box(5.0, 1.6, 5.4, 2.0)
    + _box(2.0, 3.8, 2.6, 4.2)
    + _box(9.0, 3.9, 9.4, 4.2)
    + _box(4.0, 2.2, 4.7, 2.5)
)


def two_corridor_drive(speed_mps: float = 1.0, dt_s: float = 0.1) -> NDArray[np.float64]:
    """(S, 3) true poses: east along corridor A's centre (y = 1) from x = 1 to 12, a U-turn of radius 1.1 m
    around the wall's end, then west along corridor B's centre (y = 3.2) back to x = 1."""
    straight, radius = 11.0, 1.1
    arc = math.pi * radius
    rows = []
    for s in np.arange(0.0, 2 * straight + arc, speed_mps * dt_s):
        if s < straight:
            rows.append((1.0 + s, 1.0, 0.0))
        elif s < straight + arc:
            a = -0.5 * math.pi + (s - straight) / radius
            rows.append((12.0 + radius * math.cos(a), 2.1 + radius * math.sin(a), a + 0.5 * math.pi))
        else:
            rows.append((12.0 - (s - straight - arc), 3.2, math.pi))
    out = np.array(rows)
    out[:, 2] = np.remainder(out[:, 2] + math.pi, 2 * math.pi) - math.pi
    return out

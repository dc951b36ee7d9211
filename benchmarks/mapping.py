"""Mapping benchmarks: scan integration (numba) beside a vectorised NumPy version of the same update.

Run from the repository root::

    .venv/bin/python benchmarks/mapping.py            # full run (~1 min)
    .venv/bin/python benchmarks/mapping.py --quick    # fewer scans and repetitions (~15 s)

Scenario (the issue's goal): 360 beams (1° apart) into a 400×400 grid at 0.05 m (20 m × 20 m), max range 12 m.
The scans are ray-cast analytically, with 1 cm Gaussian noise (seeded), in a walled 19 m × 19 m room holding
boxes and round pillars, from random free poses; beams beyond max range read +inf, ~1 % read NaN. Both
implementations integrate the same scans into fresh grids in the same process, and their final grids are
compared cell by cell. If ../shared/refdata is present, the Intel Research Lab CARMEN log (Radish; 180 beams,
corrected poses, 10 cm grid, readings >= 50 m treated as no-return) is replayed through both as a real-data row.

Peers:

* integrate_scan: ``numpy_integrate_scan`` below, the same per-scan update (clipped canonical Bresenham, at
  most one update per cell per scan, hit beats pass-through) vectorised over all beams and cells with NumPy.
* bresenham: ``skimage.draw.line`` (scikit-image, Cython), when installed.

Rates are the best of the repeats. "cpu" is per CPU-second of this process: everything timed is
single-threaded, so it is not diluted by other jobs on a shared machine. "wall" is per elapsed second.
"""

from __future__ import annotations

import argparse
import gzip
import math
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from mjnav.mapping import OccupancyGrid, bresenham, inflation_costmap

RES = 0.05
SIZE = 400
N_BEAMS = 360


# ---------------------------------------------------------------------------------------------------------
# Peer: vectorised NumPy scan update (same semantics as OccupancyGrid.integrate_scan)
# ---------------------------------------------------------------------------------------------------------


def numpy_trace(
    grid: OccupancyGrid,
    pose: tuple[float, float, float],
    angles: NDArray[np.float64],
    ranges: NDArray[np.float64],
    max_range_m: float,
    min_range_m: float = 0.0,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Flat indices of every traced cell visit (with repeats) and of the hit cells, for one scan."""
    H, W = grid.shape
    inv = 1.0 / grid.resolution_m
    ox, oy = grid.origin_m
    sx = (pose[0] - ox) * inv
    sy = (pose[1] - oy) * inv
    r = ranges * inv
    max_r = max_range_m * inv
    with np.errstate(invalid="ignore"):
        r = np.where(np.isnan(r), np.inf, r)  # NaN = no return, like +inf
        valid = np.isfinite(angles) & (r >= min_range_m * inv) & (r > 0.0)
        is_hit = r < max_r
    a = angles[valid]
    r = np.where(is_hit[valid], r[valid], max_r)
    is_hit = is_hit[valid]
    ct, st = math.cos(pose[2]), math.sin(pose[2])
    ca, sa = np.cos(a), np.sin(a)
    ex = sx + r * (ct * ca - st * sa)
    ey = sy + r * (st * ca + ct * sa)
    # Liang–Barsky against the grid rectangle.
    dx = ex - sx
    dy = ey - sy
    t0 = np.zeros_like(dx)
    t1 = np.ones_like(dx)
    ok = np.ones(dx.shape, dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for p, q in ((-dx, sx), (dx, W - sx), (-dy, sy), (dy, H - sy)):
            t = q / p
            zero = p == 0.0
            neg = p < 0.0
            pos = p > 0.0
            ok &= ~(zero & (q < 0.0)) & ~(neg & (t > t1)) & ~(pos & (t < t0))
            t0 = np.where(neg, np.maximum(t0, t), t0)
            t1 = np.where(pos, np.minimum(t1, t), t1)
    bx = np.where(t0 > 0.0, sx + t0 * dx, sx)[ok]
    by = np.where(t0 > 0.0, sy + t0 * dy, sy)[ok]
    clipped = t1 < 1.0
    ex = np.where(clipped, sx + t1 * dx, ex)[ok]
    ey = np.where(clipped, sy + t1 * dy, ey)[ok]
    is_hit = (is_hit & ~clipped)[ok]
    r1u = np.floor(ey).astype(np.int64)
    c1u = np.floor(ex).astype(np.int64)
    hit_in = is_hit & (r1u >= 0) & (r1u < H) & (c1u >= 0) & (c1u < W)
    r0 = np.clip(np.floor(by).astype(np.int64), 0, H - 1)
    c0 = np.clip(np.floor(bx).astype(np.int64), 0, W - 1)
    r1 = np.clip(r1u, 0, H - 1)
    c1 = np.clip(c1u, 0, W - 1)
    # Canonical Bresenham: walk the major axis from the endpoint with the smaller major coordinate.
    col_major = np.abs(c1 - c0) >= np.abs(r1 - r0)
    swap = np.where(col_major, c1 < c0, r1 < r0)
    pr = np.where(swap, r1, r0)
    pc = np.where(swap, c1, c0)
    qr = np.where(swap, r0, r1)
    qc = np.where(swap, c0, c1)
    d_major = np.where(col_major, qc - pc, qr - pr)
    d_minor = np.where(col_major, np.abs(qr - pr), np.abs(qc - pc))
    step = np.where(col_major, np.sign(qr - pr), np.sign(qc - pc))
    counts = d_major + 1
    beam = np.repeat(np.arange(counts.size), counts)
    starts = np.cumsum(counts) - counts
    i = np.arange(beam.size) - starts[beam]
    dM = np.maximum(d_major[beam], 1)
    off = (2 * i * d_minor[beam] + dM - 1) // (2 * dM)
    cm = col_major[beam]
    rows = np.where(cm, pr[beam] + step[beam] * off, pr[beam] + i)
    cols = np.where(cm, pc[beam] + i, pc[beam] + step[beam] * off)
    return rows * W + cols, r1[hit_in] * W + c1[hit_in]


def numpy_integrate_scan(
    grid: OccupancyGrid,
    pose: tuple[float, float, float],
    angles: NDArray[np.float64],
    ranges: NDArray[np.float64],
    max_range_m: float,
    min_range_m: float = 0.0,
) -> None:
    """Vectorised NumPy version of :meth:`OccupancyGrid.integrate_scan` (updates ``grid.log_odds``)."""
    visits, hit_cells = numpy_trace(grid, pose, angles, ranges, max_range_m, min_range_m)
    m = grid.model
    touched = np.zeros(grid.log_odds.size, dtype=bool)
    touched[visits] = True
    hits = np.zeros(grid.log_odds.size, dtype=bool)
    hits[hit_cells] = True
    flat = grid.log_odds.reshape(-1)
    free_idx = np.flatnonzero(touched & ~hits)
    hit_idx = np.flatnonzero(hits)
    flat[free_idx] = np.clip(flat[free_idx] + (m.miss_log_odds - m.prior_log_odds), m.min_log_odds, m.max_log_odds)
    flat[hit_idx] = np.clip(flat[hit_idx] + (m.hit_log_odds - m.prior_log_odds), m.min_log_odds, m.max_log_odds)


# ---------------------------------------------------------------------------------------------------------
# Synthetic world and scans
# ---------------------------------------------------------------------------------------------------------

ROOM = (0.5, 19.5, 0.5, 19.5)  # x_min, x_max, y_min, y_max of the walled room, metres
BOXES = np.array(
    [
        [3.0, 5.0, 3.0, 7.0],
        [8.0, 12.0, 9.0, 10.0],
        [14.0, 17.0, 4.0, 6.0],
        [4.0, 6.5, 13.0, 16.0],
        [15.0, 16.0, 12.0, 18.0],
    ]
)  # x_min, x_max, y_min, y_max
CIRCLES = np.array([[10.0, 4.0, 0.6], [11.0, 15.0, 0.8], [6.0, 10.0, 0.4], [17.0, 9.0, 0.5]])  # cx, cy, radius


def _raycast(px: float, py: float, heading: NDArray[np.float64]) -> NDArray[np.float64]:
    """Exact range (m) from (px, py) along each heading to the first surface of the synthetic world."""
    dx = np.cos(heading)
    dy = np.sin(heading)
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(dx > 0, (ROOM[1] - px) / dx, (ROOM[0] - px) / dx)
        ty = np.where(dy > 0, (ROOM[3] - py) / dy, (ROOM[2] - py) / dy)
        best = np.minimum(np.where(dx == 0, np.inf, tx), np.where(dy == 0, np.inf, ty))
        for x0, x1, y0, y1 in BOXES:
            ta = (x0 - px) / dx
            tb = (x1 - px) / dx
            tc = (y0 - py) / dy
            td = (y1 - py) / dy
            tmin = np.maximum(np.minimum(ta, tb), np.minimum(tc, td))
            tmax = np.minimum(np.maximum(ta, tb), np.maximum(tc, td))
            hit = (tmax >= tmin) & (tmin > 0)
            best = np.where(hit & (tmin < best), tmin, best)
        for cx, cy, rad in CIRCLES:
            fx = px - cx
            fy = py - cy
            b = fx * dx + fy * dy
            c = fx * fx + fy * fy - rad * rad
            disc = b * b - c
            t = -b - np.sqrt(np.maximum(disc, 0.0))
            hit = (disc >= 0) & (t > 0)
            best = np.where(hit & (t < best), t, best)
    return best


def _free_pose(rng: np.random.Generator) -> tuple[float, float, float]:
    while True:
        x, y = rng.uniform(1.0, 19.0, size=2)
        in_box = np.any(
            (x > BOXES[:, 0] - 0.3) & (x < BOXES[:, 1] + 0.3) & (y > BOXES[:, 2] - 0.3) & (y < BOXES[:, 3] + 0.3)
        )
        in_circle = np.any(np.hypot(x - CIRCLES[:, 0], y - CIRCLES[:, 1]) < CIRCLES[:, 2] + 0.3)
        if not (in_box or in_circle):
            return float(x), float(y), float(rng.uniform(-math.pi, math.pi))


def make_scans(
    n_scans: int, max_range_m: float, rng: np.random.Generator
) -> tuple[list[tuple[float, float, float]], NDArray[np.float64], NDArray[np.float64]]:
    """Poses, (N_BEAMS,) angles and (n_scans, N_BEAMS) ranges of the synthetic scenario."""
    angles = np.deg2rad(np.arange(N_BEAMS, dtype=np.float64)) - math.pi
    poses = [_free_pose(rng) for _ in range(n_scans)]
    ranges = np.empty((n_scans, N_BEAMS))
    for k, (x, y, th) in enumerate(poses):
        r = _raycast(x, y, th + angles) + rng.normal(0.0, 0.01, N_BEAMS)
        r[r >= max_range_m] = np.inf
        r[rng.random(N_BEAMS) < 0.01] = np.nan
        ranges[k] = r
    return poses, angles, ranges


def load_intel(
    limit: int,
) -> tuple[list[tuple[float, float, float]], NDArray[np.float64], NDArray[np.float64]] | None:
    """Corrected poses and 180-beam scans of the Intel Research Lab log, or None without refdata."""
    env = os.environ.get("MJNAV_REFDATA")
    root = Path(env) if env else Path(__file__).resolve().parent.parent.parent / "shared" / "refdata"
    path = root / "laser2d_carmen" / "intel-corrected.log.gz"
    if not path.is_file():
        return None
    poses: list[tuple[float, float, float]] = []
    scans: list[list[float]] = []
    with gzip.open(path, "rt") as fh:
        for line in fh:
            if not line.startswith("FLASER"):
                continue
            tok = line.split()
            n = int(tok[1])
            scans.append([float(v) for v in tok[2 : 2 + n]])
            poses.append((float(tok[2 + n]), float(tok[3 + n]), float(tok[4 + n])))
            if len(poses) >= limit:
                break
    angles = np.deg2rad(np.arange(-90.0, 90.0, 1.0))
    return poses, angles, np.asarray(scans)


# ---------------------------------------------------------------------------------------------------------
# Timing
# ---------------------------------------------------------------------------------------------------------


def _time_scans(
    fn: Callable[..., None],
    make_grid: Callable[[], OccupancyGrid],
    poses: list[tuple[float, float, float]],
    angles: NDArray[np.float64],
    ranges: NDArray[np.float64],
    max_range_m: float,
    repeats: int,
) -> tuple[float, float, OccupancyGrid]:
    """Best of ``repeats`` runs integrating all scans into a fresh grid: (cpu scans/s, wall scans/s, grid)."""
    cpu: list[float] = []
    wall: list[float] = []
    grid = make_grid()
    for _ in range(repeats):
        grid = make_grid()
        t_wall = time.perf_counter()
        t_cpu = time.process_time()
        for pose, rng_row in zip(poses, ranges, strict=True):
            fn(grid, pose, angles, rng_row, max_range_m)
        cpu.append(len(poses) / (time.process_time() - t_cpu))
        wall.append(len(poses) / (time.perf_counter() - t_wall))
    return max(cpu), max(wall), grid


def _mjnav_scan(grid: OccupancyGrid, pose: tuple[float, float, float], a: NDArray, r: NDArray, mr: float) -> None:
    grid.integrate_scan(pose, a, r, mr)


def _fmt(v: float | None) -> str:
    return f"{v:12,.0f}" if v else f"{'—':>12}"


def _row(name: str, cpu: tuple[float, float | None], wall: tuple[float, float | None], unit: str, peer: str) -> str:
    ratio = f"{cpu[0] / cpu[1]:7.1f}×" if cpu[1] else f"{'—':>8}"
    return f"{name:<50} {_fmt(cpu[0])} {_fmt(cpu[1])} {ratio} {_fmt(wall[0])} {_fmt(wall[1])}  {unit:<8} {peer}"


def bench_scans(
    label: str,
    poses: list[tuple[float, float, float]],
    angles: NDArray[np.float64],
    ranges: NDArray[np.float64],
    max_range_m: float,
    shape: tuple[int, int],
    res: float,
    origin: tuple[float, float],
    repeats: int,
) -> list[str]:
    """Time mjnav and the NumPy peer on one scan sequence; a table row plus a detail line."""

    def make() -> OccupancyGrid:
        return OccupancyGrid(shape[1], shape[0], res, origin)

    probe = make()
    visits = [numpy_trace(probe, p, angles, r, max_range_m) for p, r in zip(poses, ranges, strict=True)]
    n_visits = float(np.mean([v.size for v, _ in visits]))
    n_unique = float(np.mean([np.unique(v).size for v, _ in visits]))
    c1, w1, g1 = _time_scans(_mjnav_scan, make, poses, angles, ranges, max_range_m, repeats)
    c2, w2, g2 = _time_scans(numpy_integrate_scan, make, poses, angles, ranges, max_range_m, max(1, repeats // 3))
    diff = int(np.count_nonzero(g1.log_odds != g2.log_odds))
    touched = int(np.count_nonzero(g1.log_odds != g1.model.prior_log_odds))
    return [
        _row(f"integrate_scan {label}", (c1, c2), (w1, w2), "scans/s", "numpy_integrate_scan (vectorised)"),
        f"    {len(poses)} scans; per scan {n_visits:,.0f} cell visits, {n_unique:,.0f} distinct cells; final grid "
        f"{touched:,} cells updated, {diff} differ between mjnav and the peer",
    ]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer scans and repetitions")
    parser.add_argument("--max-range", type=float, default=12.0, help="sensor max range, metres (default 12)")
    args = parser.parse_args()
    n_scans = 200 if args.quick else 1000
    repeats = 3 if args.quick else 7
    rng = np.random.default_rng(20240611)
    poses, angles, ranges = make_scans(n_scans, args.max_range, rng)

    # Warm-up (numba compile / cache load) outside the timed region.
    warm = OccupancyGrid(SIZE, SIZE, RES)
    warm.integrate_scan(poses[0], angles, ranges[0], args.max_range)
    bresenham(0, 0, 3, 5)

    finite = ranges[np.isfinite(ranges)]
    print(f"mjnav mapping benchmark (python {sys.version.split()[0]}, numpy {np.__version__})")
    print(
        f"synthetic room: {SIZE}×{SIZE} grid at {RES} m, {N_BEAMS} beams, max range {args.max_range} m; "
        f"{np.mean(np.isinf(ranges)):.1%} no-return, {np.mean(np.isnan(ranges)):.1%} NaN, "
        f"mean finite range {finite.mean():.2f} m"
    )
    print("rates: best of the repeats; cpu = per CPU-second of this process, wall = per elapsed second")
    print()
    hdr = (
        f"{'benchmark':<50} {'mjnav cpu':>12} {'peer cpu':>12} {'ratio':>8} {'mjnav wall':>12} {'peer wall':>12}  unit"
    )
    print(hdr + "     peer")
    print("-" * 150)
    for line in bench_scans(
        "360 beams, 400² @0.05 m (room)",
        poses,
        angles,
        ranges,
        args.max_range,
        (SIZE, SIZE),
        RES,
        (0.0, 0.0),
        repeats,
    ):
        print(line)

    intel = load_intel(300 if args.quick else 910)
    if intel is not None:
        ip, ia, ir = intel
        for line in bench_scans(
            "180 beams, 500² @0.10 m (Intel log)",
            ip,
            ia,
            ir,
            50.0,
            (500, 500),
            0.10,
            (-25.0, -25.0),
            repeats,
        ):
            print(line)
    else:
        print("integrate_scan Intel log: skipped (../shared/refdata not found)")

    # Line drawing: 2000 random lines of up to 400 cells, per-call cost (Python call overhead included).
    lr = np.random.default_rng(7)
    pts = lr.integers(0, SIZE, size=(2000, 4)).tolist()

    def lines_rate(fn: Callable[[int, int, int, int], object]) -> tuple[float, float]:
        best_c = best_w = 0.0
        for _ in range(repeats):
            t_w = time.perf_counter()
            t_c = time.process_time()
            for r0, c0, r1, c1 in pts:
                fn(r0, c0, r1, c1)
            best_c = max(best_c, len(pts) / (time.process_time() - t_c))
            best_w = max(best_w, len(pts) / (time.perf_counter() - t_w))
        return best_c, best_w

    oc, ow = lines_rate(bresenham)
    try:
        from skimage.draw import line as sk_line

        sk_line(0, 0, 3, 5)
        pc, pw = lines_rate(sk_line)
        print(_row("bresenham, 2000 random lines ≤ 400 c.", (oc, pc), (ow, pw), "lines/s", "skimage.draw.line"))
    except ImportError:
        print(_row("bresenham, 2000 random lines ≤ 400 c.", (oc, None), (ow, None), "lines/s", "(no skimage)"))

    # Inflation of a mapped world (scipy EDT underneath; no peer).
    mapped = OccupancyGrid(SIZE, SIZE, RES)
    for pose, rr in zip(poses[:50], ranges[:50], strict=True):
        for _ in range(3):
            mapped.integrate_scan(pose, angles, rr, args.max_range)
    occ = mapped.states()
    reps = 5 if args.quick else 20
    t_w = time.perf_counter()
    t_c = time.process_time()
    for _ in range(reps):
        inflation_costmap(occ, RES, robot_radius_m=0.2, inflation_radius_m=0.6, cost_scaling_factor=3.0)
    ic = reps / (time.process_time() - t_c)
    iw = reps / (time.perf_counter() - t_w)
    print(_row("inflation_costmap 400²", (ic, None), (iw, None), "maps/s", "(scipy EDT inside, no peer)"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

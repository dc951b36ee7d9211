"""Benchmark: path-tracker command rate on a 500-point path.

Goal (issue): PurePursuit.compute >= 20,000 commands/s on a 500-point path.

The robot is replayed along the path (poses sampled along it with a lateral offset and heading noise,
seeded), so the forward closest-point search works as it does in a real run. Every call returns a
(v, ω) tuple. Compared in the same run:

  PurePursuit (mjnav)   numba forward search from the last closest segment + lookahead intersection
  naive NumPy PP        the textbook implementation: per call, distances to all N points (argmin),
                        then the first point beyond L by a vectorised scan of the rest of the path
  PIDTracker / LQRTracker (mjnav), same interface

Run: .venv/bin/python benchmarks/control.py [--quick]
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable

import numpy as np

from mjnav.control import LQRTracker, PIDTracker, PurePursuit


def naive_pure_pursuit(pose: tuple[float, float, float], speed: float, path: np.ndarray) -> tuple[float, float]:
    """Textbook per-call pure pursuit over the whole path (same lookahead and curvature law, no regulation)."""
    x, y, th = pose
    lookahead = min(max(abs(speed) * 1.0, 0.3), 1.5)
    d = np.hypot(path[:, 0] - x, path[:, 1] - y)
    i = int(np.argmin(d))
    beyond = np.flatnonzero(d[i:] >= lookahead)
    j = i + int(beyond[0]) if beyond.size else path.shape[0] - 1
    dx, dy = path[j, 0] - x, path[j, 1] - y
    yr = -math.sin(th) * dx + math.cos(th) * dy
    kappa = 2.0 * yr / (dx * dx + dy * dy)
    return 0.5, kappa * 0.5


def rate(step: Callable[[tuple[float, float, float]], object], poses: list[tuple[float, float, float]]) -> float:
    """Commands per second over the pose sequence (best of 3 passes)."""
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        for pose in poses:
            step(pose)
        best = min(best, time.perf_counter() - t0)
    return len(poses) / best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer calls")
    ap.add_argument("--points", type=int, default=500)
    args = ap.parse_args()
    calls = 5_000 if args.quick else 50_000
    n = args.points
    t = np.linspace(0.0, 20.0, n)
    path = np.c_[t, 2.0 * np.sin(t / 3.0)]
    rng = np.random.default_rng(3)
    s = np.linspace(0.0, 19.5, calls)  # robot progress along x; it never reaches the goal tolerance
    yy = 2.0 * np.sin(s / 3.0) + 0.05 * np.sin(s)
    th = np.arctan2(2.0 / 3.0 * np.cos(s / 3.0), 1.0) + rng.normal(0.0, 0.05, calls)
    poses = [(float(a), float(b), float(c)) for a, b, c in zip(s, yy, th, strict=True)]

    def fresh_pp() -> Callable[[tuple[float, float, float]], object]:
        pp = PurePursuit()
        return lambda pose: pp.compute(pose, 0.5, path)

    def fresh(tracker: PIDTracker | LQRTracker) -> Callable[[tuple[float, float, float]], object]:
        return lambda pose: tracker.compute(pose, 0.5, path)

    fresh_pp()(poses[0])  # compile / load the numba cache outside the timing
    rows = [
        ("PurePursuit (mjnav)", rate(fresh_pp(), poses)),
        ("naive NumPy PP", rate(lambda pose: naive_pure_pursuit(pose, 0.5, path), poses[: max(calls // 5, 1000)])),
        ("PIDTracker (mjnav)", rate(fresh(PIDTracker()), poses)),
        ("LQRTracker (mjnav)", rate(fresh(LQRTracker()), poses)),
    ]
    pp_rate = rows[0][1]
    naive_rate = rows[1][1]
    print(f"tracker command rate: {n}-point S-curve, {calls} calls per pass along the path, best of 3 passes")
    header = f"{'controller':22s} {'commands/s':>12s} {'us/call':>9s} {'vs naive':>9s} {'goal >= 20k/s':>14s}"
    print(header)
    print("-" * len(header))
    for name, r in rows:
        goal = ("yes" if r >= 20_000 else "NO") if name.startswith("PurePursuit") else ""
        print(f"{name:22s} {r:12,.0f} {1e6 / r:9.2f} {r / naive_rate:8.1f}x {goal:>14s}")
    print(f"PurePursuit / naive: {pp_rate / naive_rate:.1f}x")


if __name__ == "__main__":
    main()

"""Offline graph SLAM on the four Radish/Freiburg CARMEN logs: Kümmerle et al.'s relative error and time per scan.

Run from the repository root::

    .venv/bin/python benchmarks/slam.py                       # four logs, seeds 0..2 (~4 min)
    .venv/bin/python benchmarks/slam.py --seeds 1             # seed 0 only
    .venv/bin/python benchmarks/slam.py --logs intel,csail    # some of the logs

Each log (``../shared/refdata/laser2d_carmen``: intel, aces, freiburg-079, csail "corrected") is run exactly as
``mjnav slam --carmen LOG --seed S`` does: the odometry is the corrected trajectory corrupted with the documented
seeded noise (default σ = 0.05 m/√m, 0.05 rad/√rad, 0.02 rad/√m; :mod:`mjnav.estimation.slam_metrics`), the SLAM
starts at the first corrected pose, and every scan's final (optimised) pose is compared with the corrected pose by
Kümmerle et al. (2009)'s relative error over two relation sets: consecutive scans, and scans 1 m apart along the
corrected path. Figures and verdicts are means over the noise seeds (default three): one run is chaotic in its input
(whether one loop closure is accepted changes what follows), and seed to seed the mean error moves by about 0.001 m.

Peer: the graph-mapping figures of Kümmerle et al. (2009), mean translational error (Intel 0.031 m, ACES 0.044 m,
Freiburg 079 0.056 m, MIT CSAIL 0.004 m). They are quoted from secondary sources (the issue, and a second
independent write-up that gives the same table with standard deviations: 0.031 ± 0.026, 0.044 ± 0.044,
0.056 ± 0.042, 0.004 ± 0.009 m); the paper itself could not be read here. The comparison is indicative, not like
for like: the paper scores against hand-verified relations of its own (not shipped with the logs), this benchmark
against the corrected poses. The corrected poses are themselves a SLAM solution that disagrees with the scans:
the "reference floor" line matches every pair of consecutive scans by PL-ICP started *at the corrected relative
pose* and prints how far the match ends from it (mean over the pairs PL-ICP accepts). No method that follows the
scans can score much below that floor; on CSAIL it is several times the published 0.004 m. The paper scores
against relations given as relative poses, chosen and verified by hand; the "scan-matched relations" line is an
automatic analogue: the result against those PL-ICP matches themselves (pairs PL-ICP accepts). It is printed for
context, with its ratio; the verdicts stay on the corrected poses, the issue's metric. The published rotational
errors are not printed: no source for them could be checked here. The noisy odometry's own error is the baseline.

Time: the process CPU time of each ``GraphSlam.update`` call (front end, loop search and pose-graph optimisation;
the occupancy grid is rendered on request, after the run, and timed separately), mean and 99th percentile over
scans; wall time is printed beside it (on a shared machine it also counts other processes' turns). The time goal
(mean ≤ 10 ms per scan, ≥ 10× real time at 10 Hz) is judged on CPU time, per log and over the four.
The logs are sub-sampled (Intel ~0.7 m, ACES and CSAIL ~1 m between scans), so nearly every scan is a keyframe
there and the per-scan time is a per-keyframe time; Freiburg 079 (~0.1 m) is closer to a 10 Hz stream.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from mjnav.commands.slam import CARMEN_MAX_RANGE_M, run_slam
from mjnav.estimation import read_carmen
from mjnav.estimation.carmen import CarmenLog
from mjnav.estimation.scan_matching import PointReference, ScanMatchError
from mjnav.estimation.slam import GraphSlam, SlamConfig, compose, relative
from mjnav.estimation.slam_metrics import (
    DEFAULT_ODOMETRY_NOISE,
    consecutive_relations,
    corrupt_odometry,
    distance_relations,
    relation_error,
    relative_pose_error,
)

REFDATA = Path(__file__).resolve().parent.parent.parent / "shared" / "refdata"
LOGS = {"intel": 0.031, "aces": 0.044, "freiburg-079": 0.056, "csail": 0.004}
TIME_GOAL_MS = 10.0


def verdict(ok: bool, text: str) -> None:
    print(f"  goal {text}: {'met' if ok else 'NOT met'}")


class ScanMatched(NamedTuple):
    """Consecutive scans matched by PL-ICP started at the corrected relative pose (pairs kept when the match is
    non-degenerate with at least half the points matched).

    Attributes:
        relations: (R, 2) the kept pairs (k, k + 1).
        measured: (R, 3) their matched relative poses.
        floor_m: mean translational distance of the matches from the corrected relative poses, metres (the
            reference floor).
        cycle_m: mean translational error of the three-scan cycles m(k, k+2)⁻¹ ∘ m(k, k+1) ∘ m(k+1, k+2) over the
            triples whose three matches are kept, metres (the matcher's self-consistency).
        cycles: number of those triples.
    """

    relations: np.ndarray
    measured: np.ndarray
    floor_m: float
    cycle_m: float
    cycles: int


def _plicp(pts: list[np.ndarray], i: int, j: int, initial: np.ndarray) -> np.ndarray | None:
    """Pose of scan j in scan i's frame by PL-ICP from ``initial``; None when rejected (degenerate, or fewer than
    half the points matched)."""
    if pts[i].shape[0] < 20 or pts[j].shape[0] < 20:
        return None
    try:
        m = PointReference(pts[i]).match(pts[j], initial, "plicp", max_correspondence_m=0.3, max_iterations=50)
    except ScanMatchError:
        return None
    return None if m.degenerate or m.score < 0.5 else m.pose


def scan_matched_relations(log: CarmenLog) -> ScanMatched:
    """Match consecutive scans (and every scan with the one two later, for the cycles); see :class:`ScanMatched`."""
    pts = [log.points(k, max_range_m=30.0) for k in range(len(log))]
    pairs: dict[int, np.ndarray] = {}
    errors = []
    for k in range(len(log) - 1):
        z = relative(log.poses[k], log.poses[k + 1])
        m = _plicp(pts, k, k + 1, z)
        if m is not None:
            e = relative(z, m)
            errors.append(float(np.hypot(e[0], e[1])))
            pairs[k] = m
    cycles = []
    for k in range(len(log) - 2):
        if k in pairs and k + 1 in pairs:
            m02 = _plicp(pts, k, k + 2, relative(log.poses[k], log.poses[k + 2]))
            if m02 is not None:
                c = relative(m02, compose(pairs[k], pairs[k + 1]))
                cycles.append(float(np.hypot(c[0], c[1])))
    keys = sorted(pairs)
    return ScanMatched(
        np.array([(k, k + 1) for k in keys], dtype=np.int64),
        np.array([pairs[k] for k in keys]),
        float(np.mean(errors)),
        float(np.mean(cycles)) if cycles else float("nan"),
        len(cycles),
    )


def run_log(name: str, seed: int, matched: ScanMatched) -> dict[str, float]:
    log = read_carmen(REFDATA / "laser2d_carmen" / f"{name}-corrected.log.gz")
    n = len(log)
    ref = log.poses
    odom = corrupt_odometry(ref, np.random.default_rng(seed), DEFAULT_ODOMETRY_NOISE)
    slam = GraphSlam(SlamConfig(), initial_pose=ref[0])
    cpu = np.zeros(n)
    times = run_slam(
        slam,
        log.timestamps,
        odom,
        log.ranges,
        np.broadcast_to(log.angles, log.ranges.shape),
        np.zeros(n),
        np.full(n, CARMEN_MAX_RANGE_M),
        cpu_times=cpu,
    )
    t0 = time.perf_counter()
    slam.occupancy_grid()
    render_s = time.perf_counter() - t0
    _, est = slam.trajectory()
    out: dict[str, float] = {
        "scans": n,
        "keyframes": slam.num_keyframes,
        "loops": slam.loop_closures,
        "wall_ms": float(times.mean() * 1e3),
        "wall_p99_ms": float(np.percentile(times, 99) * 1e3),
        "cpu_ms": float(cpu.mean() * 1e3),
        "cpu_p99_ms": float(np.percentile(cpu, 99) * 1e3),
        "render_s": render_s,
    }
    m = relation_error(est, matched.relations, matched.measured)
    out |= {"m_t": m.trans_mean_m, "m_ts": m.trans_std_m, "m_r": m.rot_mean_deg, "m_n": m.relations}
    for tag, rel in (("c", consecutive_relations(n)), ("d", distance_relations(ref, 1.0))):
        e = relative_pose_error(est, ref, rel)
        o = relative_pose_error(odom, ref, rel)
        out |= {
            f"{tag}_t": e.trans_mean_m,
            f"{tag}_ts": e.trans_std_m,
            f"{tag}_r": e.rot_mean_deg,
            f"{tag}_rs": e.rot_std_deg,
            f"{tag}_ot": o.trans_mean_m,
            f"{tag}_or": o.rot_mean_deg,
        }
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    # One seed is not enough for a verdict: the result is chaotic in the input (a loop closure accepted or not
    # changes what follows; re-associating a floating-point sum, 1e-13 relative, moved Intel's error by 5 %).
    parser.add_argument("--seeds", type=int, default=3, help="noise seeds per log (0..N-1; default 3)")
    parser.add_argument(
        "--logs", default=",".join(LOGS), help=f"comma-separated logs to run (default all: {','.join(LOGS)})"
    )
    args = parser.parse_args()
    names = [x for x in args.logs.split(",") if x]
    unknown = [x for x in names if x not in LOGS]
    if unknown or not names or args.seeds < 1:
        parser.error(f"--logs must name some of {', '.join(LOGS)} and --seeds must be >= 1")
    if not (REFDATA / "laser2d_carmen").is_dir():
        print("SLAM benchmark: skipped (../shared/refdata/laser2d_carmen not found)")
        return 0
    # Warm-up: compile the numba kernels outside the timed runs.
    warm = read_carmen(REFDATA / "laser2d_carmen" / "intel-corrected.log.gz")
    w = GraphSlam()
    for k in range(30):
        w.update(0.0, warm.poses[k], warm.ranges[k], warm.angles, range_min_m=0.0, range_max_m=CARMEN_MAX_RANGE_M)
    w.occupancy_grid()
    sigmas = ",".join(f"{v:g}" for v in DEFAULT_ODOMETRY_NOISE)
    print(f"Graph SLAM on the CARMEN corrected logs (odometry noise {sigmas}, seeds 0..{args.seeds - 1})")
    all_cpu: list[float] = []
    for name in names:
        published = LOGS[name]
        matched = scan_matched_relations(read_carmen(REFDATA / "laser2d_carmen" / f"{name}-corrected.log.gz"))
        runs = [run_log(name, s, matched) for s in range(args.seeds)]
        r = {k: float(np.mean([x[k] for x in runs])) for k in runs[0]}
        all_cpu.append(r["cpu_ms"])
        # Three independent matches with equal isotropic errors of σ per axis make a cycle error of √3 σ per
        # axis, so one match is off by about cycle / √3. By the triangle inequality (per relation, then in the
        # mean) any trajectory that agrees with the true scan relations, the true one included, is at least
        # floor − cycle / √3 from the corrected relative poses on these pairs.
        floor, match_err = matched.floor_m, matched.cycle_m / np.sqrt(3.0)
        print(
            f"\n{name}: {int(r['scans'])} scans, {r['keyframes']:.0f} keyframes, {r['loops']:.0f} loop closures "
            f"(mean over {args.seeds} seed(s))"
        )
        print(
            f"  consecutive: {r['c_t']:.4f} ± {r['c_ts']:.4f} m, {r['c_r']:.3f} ± {r['c_rs']:.3f}°   "
            f"(noisy odometry {r['c_ot']:.4f} m, {r['c_or']:.3f}°)"
        )
        print(
            f"  1 m apart:   {r['d_t']:.4f} ± {r['d_ts']:.4f} m, {r['d_r']:.3f} ± {r['d_rs']:.3f}°   "
            f"(noisy odometry {r['d_ot']:.4f} m, {r['d_or']:.3f}°)"
        )
        print(f"  reference floor (PL-ICP of consecutive scans from the corrected relative pose): {floor:.4f} m")
        print(
            f"  PL-ICP self-consistency ({matched.cycles} three-scan cycles): {matched.cycle_m:.4f} m, so one match "
            f"is off by ~{match_err:.4f} m; the true trajectory itself scores >= {floor - match_err:.4f} m "
            f"against the corrected poses on these pairs ({(floor - match_err) / published:.2f}× graph mapping)"
        )
        print(
            f"  vs scan-matched relations ({r['m_n']:.0f} consecutive pairs, the floor's matches): "
            f"{r['m_t']:.4f} ± {r['m_ts']:.4f} m, {r['m_r']:.3f}°   (ratio to graph mapping {r['m_t'] / published:.2f})"
        )
        print(
            f"  time per scan: cpu mean {r['cpu_ms']:.2f} ms, p99 {r['cpu_p99_ms']:.1f} ms "
            f"(wall mean {r['wall_ms']:.2f} ms, p99 {r['wall_p99_ms']:.1f} ms); "
            f"map render after the run {r['render_s']:.2f} s"
        )
        print(f"  ratio mjnav / graph mapping (Kümmerle 2009), consecutive translational: {r['c_t'] / published:.2f}")
        verdict(
            r["c_t"] < published,
            f"mean translational error < {published} m (graph mapping) on consecutive scans ({r['c_t']:.4f} m)",
        )
        verdict(
            r["cpu_ms"] <= TIME_GOAL_MS,
            f"mean time per scan <= {TIME_GOAL_MS:g} ms ({r['cpu_ms']:.2f} ms cpu, p99 {r['cpu_p99_ms']:.1f} ms)",
        )
    print()
    verdict(
        float(np.mean(all_cpu)) <= TIME_GOAL_MS,
        f"mean time per scan over the logs run <= {TIME_GOAL_MS:g} ms ({np.mean(all_cpu):.2f} ms cpu)",
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

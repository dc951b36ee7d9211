"""``mjnav slam``: offline graph SLAM on a CARMEN log or an mjnav bag, as fast as the machine runs it.

Input, one of:

* ``--carmen LOG`` — a CARMEN log (``.log`` or ``.log.gz``; FLASER lines). The Radish/Freiburg "corrected" logs
  carry the corrected pose as their odometry, so the odometry the SLAM sees is corrupted with seeded noise
  (``--odom-noise``, ``--seed``; model in :mod:`mjnav.estimation.slam_metrics`), and the result is scored against
  the corrected poses with Kümmerle et al.'s relative error (consecutive scans, and scan pairs 1 m apart along the
  path). ``--odom-noise 0,0,0`` uses the log's own odometry column.
* ``--bag RUN.mcap`` — a bag recorded by ``mjnav record`` / ``mjnav demo --record``: ``<ns>/scan`` with the
  ``<ns>/odom`` pose interpolated at each scan's stamp.

Output in ``--out DIR``: ``map.yaml`` + ``map.pgm`` (map_server format, trinary), ``trajectory.txt`` (one line per
scan: ``t x y theta``, seconds, metres, radians, map frame, the poses of the final optimised graph),
``graph.g2o`` (the keyframe pose graph at its optimised poses, with front-end and loop-closure edges) and
``summary.json`` (the figures printed, and the SLAM's settings under ``slam_config``).

Exit codes: 0 done; 2 bad arguments or unreadable input.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mjnav import jsonsafe

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from mjnav.estimation.slam import GraphSlam, SlamConfig

CARMEN_MAX_RANGE_M = 80.0  # CARMEN logs write 81.83 (Intel) or 81.91 m for "no return"


def parse_sigmas(text: str) -> tuple[float, float, float]:
    """``ST,SR,SB`` → three finite numbers >= 0."""
    parts = text.split(",")
    try:
        if len(parts) != 3:
            raise ValueError
        vals = tuple(float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected ST,SR,SB (three numbers), got {text!r}") from None
    if not all(math.isfinite(v) and v >= 0 for v in vals):
        raise argparse.ArgumentTypeError(f"ST,SR,SB must be finite and >= 0, got {text!r}")
    return vals[0], vals[1], vals[2]


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``slam`` sub-command."""
    from mjnav.commands._args import non_negative_float, positive_int

    p = subparsers.add_parser(
        "slam",
        help="offline graph SLAM on a CARMEN log or a bag: map, trajectory and pose graph",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "Run mjnav's online graph SLAM (scan-to-map correlative matching + PL-ICP front end; pose graph with\n"
            "branch-and-bound loop closures, optimised with CHOLMOD) over a recorded run as fast as possible.\n\n"
            "Writes to --out DIR: map.yaml + map.pgm (map_server), trajectory.txt ('t x y theta' per scan, map\n"
            "frame, final optimised poses), graph.g2o (keyframe pose graph) and summary.json.\n\n"
            "CARMEN logs: the 'corrected' logs' odometry equals the corrected pose, so the odometry the SLAM\n"
            "gets is the corrected trajectory corrupted with seeded noise. Per step u = x[k-1]^-1 x[k] (distance\n"
            "d, turn |u_theta|):  u_x, u_y += N(0, ST^2 d);  u_theta += N(0, SR^2 |u_theta| + SB^2 d)\n"
            "(ST m/sqrt(m), SR rad/sqrt(rad), SB rad/sqrt(m); a random walk per metre, so the drift does not\n"
            "depend on the log's sampling). Default 0.05,0.05,0.02: ~0.5 m and ~11 deg of drift per 100 m.\n"
            "The result is scored with Kuemmerle et al. (2009)'s relative error against the corrected poses\n"
            "(relations: consecutive scans, and scans 1 m apart along the path)."
        ),
        epilog=(
            "Examples:\n"
            "  mjnav slam --carmen intel-corrected.log.gz --out out/intel\n"
            "  mjnav slam --carmen aces-corrected.log.gz --odom-noise 0.1,0.1,0.04 --seed 3 --out out/aces\n"
            "  mjnav demo --record run.mcap && mjnav slam --bag run.mcap --out out/run"
        ),
    )
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--carmen", type=Path, metavar="LOG", help="CARMEN log (.log/.log.gz) with FLASER lines")
    src.add_argument("--bag", type=Path, metavar="RUN.mcap", help="MCAP bag with <ns>/scan and <ns>/odom")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder (created if missing)")
    p.add_argument(
        "--odom-noise",
        type=parse_sigmas,
        default=None,
        metavar="ST,SR,SB",
        help="CARMEN only: odometry noise (see above; default 0.05,0.05,0.02; 0,0,0 = the log's odometry)",
    )
    p.add_argument("--seed", type=int, default=0, help="CARMEN only: seed of the odometry noise (default 0)")
    p.add_argument("--namespace", default=None, help="bag only: robot namespace (default: the only one)")
    p.add_argument("--limit", type=positive_int, default=None, metavar="N", help="use only the first N scans")
    p.add_argument(
        "--max-range",
        type=non_negative_float,
        default=30.0,
        metavar="M",
        help="beams beyond this are not matched or marked (default 30 m)",
    )
    p.add_argument(
        "--resolution", type=non_negative_float, default=0.05, metavar="M", help="map cell size (default 0.05 m)"
    )
    p.add_argument("--no-loops", action="store_true", help="disable loop closure (front end only)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object on the last line")
    p.set_defaults(func=run)


def _fail(message: str) -> int:
    print(f"mjnav slam: error: {message}", file=sys.stderr)
    return 2


def run_slam(
    slam: GraphSlam,
    stamps: NDArray[np.float64],
    odometry: NDArray[np.float64],
    ranges: Any,
    angles: Any,
    range_min: NDArray[np.float64],
    range_max: NDArray[np.float64],
    *,
    progress: bool = False,
    cpu_times: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Feed every scan to ``slam``; returns (S,) wall seconds per :meth:`GraphSlam.update` call.

    ``ranges`` and ``angles`` are indexable per scan (a 2-D array or a sequence of 1-D arrays). ``cpu_times``, an
    (S,) array, receives the process CPU seconds of each call (on a shared machine the wall time also counts the
    other processes' turns).
    """
    import numpy as np

    n = stamps.shape[0]
    times = np.zeros(n)
    cpu = np.zeros(n) if cpu_times is None else cpu_times
    start = time.perf_counter()
    next_report = start + 2.0
    for k in range(n):
        c0 = time.process_time()
        t0 = time.perf_counter()
        slam.update(
            float(stamps[k]),
            odometry[k],
            ranges[k],
            angles[k],
            range_min_m=float(range_min[k]),
            range_max_m=float(range_max[k]),
        )
        t1 = time.perf_counter()
        cpu[k] = time.process_time() - c0
        times[k] = t1 - t0
        if progress and (t1 >= next_report or k == n - 1):
            next_report = t1 + 2.0
            print(
                f"\rmjnav slam: {k + 1}/{n} scans, {slam.num_keyframes} keyframes, "
                f"{slam.loop_closures} loop closures, {t1 - start:.1f} s",
                end="\n" if k == n - 1 else "",
                file=sys.stderr,
                flush=True,
            )
    return times


def write_outputs(slam: GraphSlam, out: Path) -> dict[str, str]:
    """Write map.yaml/.pgm, trajectory.txt and graph.g2o into ``out``; returns their paths by name."""
    import numpy as np

    from mjnav.estimation.g2o import write_g2o
    from mjnav.mapping import write_ros_map

    out.mkdir(parents=True, exist_ok=True)
    grid = slam.occupancy_grid()
    yaml_path = write_ros_map(out / "map.yaml", grid.to_ros(), grid.resolution_m, grid.origin_m)
    stamps, poses = slam.trajectory()
    traj = out / "trajectory.txt"
    np.savetxt(traj, np.column_stack((stamps, poses)), fmt="%.9g", header="t x y theta", comments="# ")
    graph = out / "graph.g2o"
    write_g2o(graph, slam.pose_graph())
    return {"map": str(yaml_path), "trajectory": str(traj), "graph": str(graph)}


def _config(args: argparse.Namespace) -> SlamConfig:
    from mjnav.estimation.slam import SlamConfig

    kw: dict[str, Any] = {"max_range_m": args.max_range, "map_resolution_m": args.resolution}
    if args.no_loops:
        kw["loop_candidates"] = 0
    return SlamConfig(**kw)


def run(args: argparse.Namespace) -> int:
    """Read the input, run the SLAM, write the outputs, print the summary; returns the exit code."""
    import numpy as np

    from mjnav.estimation.slam import GraphSlam, SlamError

    if args.max_range <= 0 or args.resolution <= 0:
        return _fail("--max-range and --resolution must be > 0")
    if args.bag is not None and (args.odom_noise is not None or args.seed != 0):
        return _fail("--odom-noise and --seed apply to --carmen only (a bag's odometry is real)")
    if args.carmen is not None and args.namespace is not None:
        return _fail("--namespace applies to --bag only")
    summary: dict[str, Any] = {}
    reference = None
    try:
        if args.carmen is not None:
            from mjnav.estimation.carmen import CarmenFormatError, read_carmen
            from mjnav.estimation.slam_metrics import DEFAULT_ODOMETRY_NOISE, corrupt_odometry

            try:
                log = read_carmen(args.carmen)
            except (OSError, CarmenFormatError) as exc:
                return _fail(f"cannot read CARMEN log {args.carmen}: {exc}")
            n = len(log) if args.limit is None else min(args.limit, len(log))
            reference = log.poses[:n]
            sigmas = DEFAULT_ODOMETRY_NOISE if args.odom_noise is None else args.odom_noise
            if any(sigmas):
                odom = corrupt_odometry(reference, np.random.default_rng(args.seed), sigmas)
            else:
                odom = log.odometry[:n]
            stamps = log.timestamps[:n]
            ranges: Any = log.ranges[:n]
            angles: Any = np.broadcast_to(log.angles, ranges.shape)
            rmin, rmax = np.zeros(n), np.full(n, CARMEN_MAX_RANGE_M)
            summary.update(
                input=str(args.carmen), odom_noise=list(sigmas), seed=args.seed, initial_pose=reference[0].tolist()
            )
            slam = GraphSlam(_config(args), initial_pose=reference[0])
        else:
            from mjnav.bag import BagError
            from mjnav.bag.scans import read_scans

            try:
                bag = read_scans(args.bag, args.namespace)
            except BagError as exc:
                return _fail(str(exc))
            n = len(bag) if args.limit is None else min(args.limit, len(bag))
            stamps, odom = bag.stamps[:n], bag.odometry[:n]
            ranges, angles = bag.ranges[:n], bag.angles[:n]
            rmin, rmax = bag.range_min[:n], bag.range_max[:n]
            summary.update(input=str(args.bag), namespace=bag.namespace, scans_without_odometry=bag.dropped)
            slam = GraphSlam(_config(args))
        cpu = np.zeros(n)
        times = run_slam(slam, stamps, odom, ranges, angles, rmin, rmax, progress=not args.quiet, cpu_times=cpu)
        t0 = time.perf_counter()
        files = write_outputs(slam, args.out)
        write_s = time.perf_counter() - t0
    except SlamError as exc:
        return _fail(str(exc))
    except OSError as exc:
        return _fail(f"cannot write to {args.out}: {exc}")
    summary.update(
        scans=int(n),
        keyframes=slam.num_keyframes,
        loop_closures=slam.loop_closures,
        optimizations=slam.optimizations,
        time_per_scan_mean_ms=float(times.mean() * 1e3),
        time_per_scan_p99_ms=float(np.percentile(times, 99) * 1e3),
        cpu_per_scan_mean_ms=float(cpu.mean() * 1e3),
        cpu_per_scan_p99_ms=float(np.percentile(cpu, 99) * 1e3),
        total_s=float(times.sum()),
        map_and_files_s=write_s,
        files=files,
        slam_config=dataclasses.asdict(slam.config),
    )
    print(f"input:      {summary['input']} ({n} scans)")
    print(
        f"graph:      {slam.num_keyframes} keyframes, {slam.loop_closures} loop closures, "
        f"{slam.optimizations} optimisations"
    )
    mean_ms, p99_ms = summary["time_per_scan_mean_ms"], summary["time_per_scan_p99_ms"]
    cpu_ms, cpu_p99 = summary["cpu_per_scan_mean_ms"], summary["cpu_per_scan_p99_ms"]
    print(
        f"time:       {mean_ms:.2f} ms per scan (p99 {p99_ms:.1f} ms), cpu {cpu_ms:.2f} ms (p99 {cpu_p99:.1f} ms), "
        f"{summary['total_s']:.1f} s in all; map and files {write_s:.2f} s"
    )
    if reference is not None and n >= 2:
        from mjnav.estimation.slam_metrics import consecutive_relations, distance_relations, relative_pose_error

        _, est = slam.trajectory()
        for name, rel in (("consecutive", consecutive_relations(n)), ("1m", distance_relations(reference, 1.0))):
            if rel.shape[0] == 0:
                continue
            e = relative_pose_error(est, reference, rel)
            o = relative_pose_error(odom, reference, rel)
            summary[f"rpe_{name}"] = {
                "relations": e.relations,
                "trans_mean_m": e.trans_mean_m,
                "trans_std_m": e.trans_std_m,
                "rot_mean_deg": e.rot_mean_deg,
                "rot_std_deg": e.rot_std_deg,
                "odometry_trans_mean_m": o.trans_mean_m,
                "odometry_rot_mean_deg": o.rot_mean_deg,
            }
            print(
                f"error {name + ':':12s} {e.trans_mean_m:.4f} ± {e.trans_std_m:.4f} m, "
                f"{e.rot_mean_deg:.3f} ± {e.rot_std_deg:.3f}° over {e.relations} relations "
                f"(noisy odometry: {o.trans_mean_m:.4f} m, {o.rot_mean_deg:.3f}°)"
            )
    print(f"wrote:      {', '.join(files.values())}")
    (args.out / "summary.json").write_text(jsonsafe.dumps(summary) + "\n")
    if args.json:
        print(jsonsafe.dumps(summary))
    return 0

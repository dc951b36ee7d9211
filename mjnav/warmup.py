"""Compile mjnav's numba kernels into their on-disk caches once, so no service compiles at start-up.

``make setup`` runs it after installing (``mjnav warmup``, or ``python -m mjnav.warmup``). Every kernel is
``@njit(cache=True)``: its machine code is written beside its module (``__pycache__/*.nbi``/``*.nbc``) the first
time it is called with a set of argument types, and later processes load it from there instead of compiling (tens
of seconds for SLAM's kernels). The exercises below call the library the way the services do (float64 arrays,
int64 cells, the same entry points) on tiny inputs, so each kernel is compiled for the types the stack passes it.
:func:`uncompiled` names the kernels no exercise reached.
"""

from __future__ import annotations

import argparse
import importlib
import itertools
import math
import pkgutil
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

import mjnav


def _room(n: int = 40) -> np.ndarray:
    """(n, n) bool occupancy: a walled room with one inner wall that has a gap."""
    occ = np.zeros((n, n), dtype=bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    occ[n // 2, : n - 8] = True
    return occ


def _scan(pose: tuple[float, float, float], beams: int = 180) -> tuple[np.ndarray, np.ndarray]:
    """Ranges (m) and angles (rad) of a lidar at ``pose`` inside the 4 m × 4 m box [0, 4]² (walls only)."""
    angles = np.linspace(-math.pi, math.pi, beams, endpoint=False)
    x, y, th = pose
    c, s = np.cos(th + angles), np.sin(th + angles)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (4.0 - x) / c, np.where(c < 0, -x / c, np.inf))
        ty = np.where(s > 0, (4.0 - y) / s, np.where(s < 0, -y / s, np.inf))
    return np.minimum(tx, ty), angles


def _planning() -> None:
    from mjnav.planning import ALGORITHMS, plan_grid

    occ = _room()
    cost = np.linspace(0.0, 1.0, occ.size).reshape(occ.shape)
    start, goal = (3, 3), (36, 36)
    for algorithm in ALGORITHMS:
        plan_grid(occ, start, goal, algorithm=algorithm, rng=np.random.default_rng(0))
    for algorithm in ("astar", "dijkstra"):
        plan_grid(occ, start, goal, algorithm=algorithm, cost=cost)
        plan_grid(occ, start, goal, algorithm=algorithm, cost=cost, corner_cutting=True)
    plan_grid(occ, start, goal, algorithm="astar", connectivity=4)
    plan_grid(occ, start, goal, algorithm="astar", cost=cost, weights=(1.0, 2.0))  # not bucketed: the binary heap
    trap = np.zeros((30, 30), dtype=bool)  # a cup open away from the goal: the potential field's local minimum
    trap[8:22, 20] = trap[8, 12:21] = trap[21, 12:21] = True
    plan_grid(trap, (15, 15), (15, 27), algorithm="potential_field")


def _mapping() -> None:
    from mjnav.mapping import OccupancyGrid, bresenham, inflation_costmap, supercover

    bresenham(0, 0, 7, 3)
    supercover(0.1, 0.2, 5.7, 3.3)
    grid = OccupancyGrid(100, 100, 0.05, (-0.5, -0.5))
    ranges, angles = _scan((2.0, 2.0, 0.3))
    grid.integrate_scan((2.0, 2.0, 0.3), angles, ranges, 12.0, min_range_m=0.1)
    inflation_costmap(grid.to_ros(), 0.05, 0.2, 0.5)


def _estimation() -> None:
    from mjnav.estimation._graph_kernels import shortest_paths
    from mjnav.estimation.slam import GraphSlam, SlamConfig

    slam = GraphSlam(SlamConfig(loop_min_travel_m=3.0))  # a loop after 3 m rather than 10: the same kernels
    # Around a 1.6 m square and back to the start: keyframes, and a loop search along the graph's chains.
    corners = np.array([[1.2, 1.2], [2.8, 1.2], [2.8, 2.8], [1.2, 2.8], [1.2, 1.2]])
    track = np.concatenate([np.linspace(a, b, 16, endpoint=False) for a, b in itertools.pairwise(corners)])
    for k, (x, y) in enumerate(np.vstack([track, track[:8]])):
        ranges, angles = _scan((x, y, 0.0), 360)
        slam.update(0.1 * k, np.array([x, y, 0.0]), ranges, angles, range_min_m=0.1, range_max_m=12.0)
    # The loop search's chain variances (GraphSlam._chain_variances), as it calls them.
    edges = np.array([[0, 1], [1, 2]], dtype=np.int64)
    shortest_paths(edges[:, 0].copy(), edges[:, 1].copy(), np.ones((2, 2)), 3, 2)


def _matching() -> None:
    from mjnav.estimation.posegraph import PoseGraph, odometry_guess
    from mjnav.estimation.scan_matching import CorrelativeGridMatcher
    from mjnav.mapping import OccupancyGrid

    grid = OccupancyGrid(100, 100, 0.05, (-0.5, -0.5))
    ranges, angles = _scan((2.0, 2.0, 0.0))
    grid.integrate_scan((2.0, 2.0, 0.0), angles, ranges, 12.0)
    scan_xy = np.column_stack([ranges * np.cos(angles), ranges * np.sin(angles)])  # laser frame
    matcher = CorrelativeGridMatcher.from_occupancy_grid(grid)
    matcher.match_brute_force(scan_xy, (2.05, 2.0, 0.0), linear_window_m=0.2, angular_window_rad=0.1)
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.1], [2.0, 0.1, 0.2]])
    edges = np.array([[0, 1], [1, 2]])
    info = np.tile(np.eye(3), (2, 1, 1))
    odometry_guess(PoseGraph(poses, edges, np.array([[1.0, 0.0, 0.1], [1.0, 0.1, 0.1]]), info))


def _filters() -> None:
    from mjnav.estimation import EKFSLAM, ExtendedKalmanFilter, FastSLAM, KalmanFilter

    eye = np.eye(2)
    kf = KalmanFilter(eye, eye, 0.1 * eye, 0.1 * eye, None, np.zeros(2), eye)
    kf.predict()
    kf.update(np.array([0.1, 0.2]))
    ekf = ExtendedKalmanFilter(
        lambda x, _u: x, lambda _x, _u: eye, lambda x: x, lambda _x: eye, 0.1 * eye, 0.1 * eye, np.zeros(2), eye
    )
    ekf.predict()
    ekf.update(np.array([0.1, 0.2]))
    observations = np.array([[2.0, 0.3], [3.0, -0.5]])  # range m, bearing rad
    for slam in (EKFSLAM(), FastSLAM(rng=0, num_particles=4)):
        slam.predict(0.2, 0.05, 0.1)
        slam.update(observations)
        slam.update(observations)


def _aerial() -> None:
    from mjnav.aerial.frames import (
        body_to_ned,
        ecef_to_geodetic,
        enu_to_geodetic,
        geodetic_to_ecef,
        geodetic_to_enu,
        quat_multiply,
    )
    from mjnav.aerial.imu_check import ImuCheck
    from mjnav.aerial.ins import GpsIns
    from mjnav.aerial.quadrotor import QuadrotorParams, hover_state, step

    lat, lon, h = np.array([47.3977, 47.3978]), np.array([8.5456, 8.5457]), np.array([488.0, 490.0])
    geodetic_to_enu(lat, lon, h, 47.397742, 8.545594, 488.0)
    geodetic_to_enu(47.3977, 8.5456, 488.0, 47.397742, 8.545594, 488.0)
    enu_to_geodetic(np.array([1.0, 2.0]), np.array([3.0, 4.0]), np.array([0.5, 0.5]), 47.397742, 8.545594, 488.0)
    ecef_to_geodetic(*geodetic_to_ecef(lat, lon, h))
    body_to_ned(np.array([1.0, 0.0, 0.0]), 0.1, 0.2, 0.3)
    quat_multiply(np.array([1.0, 0.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0, 0.0]))
    params = QuadrotorParams()
    step(hover_state(params), np.full(4, params.hover_rotor_speed_rad_s), 0.01, params)
    ins = GpsIns()
    for _ in range(3):
        ins.predict(np.array([0.0, 0.0, -9.80665]))
    ins.update_gps(np.array([0.1, 0.0, 0.0]))
    ins.update_gps(np.array([0.1, 0.0, 0.0]), ins.t_s - 0.01)  # a delayed fix
    ins.update_baro(0.1, ins.t_s - 0.005)
    ImuCheck().check([0.0, 0.01], [(1.0, 0.0, 0.0, 0.0)] * 2, [(0.0, 0.0, 0.0)] * 2, [(0.0, 0.0, 9.80665)] * 2)


def _smoothing() -> None:
    from mjnav.smoothing.gradient_descent import gradient_descent
    from mjnav.smoothing.profile import velocity_profile
    from mjnav.smoothing.qp import qp_smooth

    path = np.column_stack([np.linspace(0.0, 2.0, 21), 0.2 * np.sin(np.linspace(0.0, 3.0, 21))])
    qp_smooth(path, max_deviation_m=0.1)
    gradient_descent(path, max_deviation_m=0.1)
    velocity_profile(path)


def _control() -> None:
    from mjnav.control.pure_pursuit import PurePursuit

    path = np.column_stack([np.linspace(0.0, 3.0, 31), np.zeros(31)])
    pursuit = PurePursuit()
    obstacles = np.array([[1.5, 0.8], [2.0, -0.9]])
    pursuit.compute((0.0, 0.1, 0.0), 0.2, path, obstacles_xy=obstacles, chord_clearance_m=0.2)
    pursuit.compute((0.1, 0.1, 0.0), 0.3, path)


def _sim() -> None:
    from mjnav.sim.worldgen import merge_rectangles

    merge_rectangles(_room())


#: The exercises, by package (each imports what it calls).
EXERCISES: dict[str, Callable[[], None]] = {
    "planning": _planning,
    "mapping": _mapping,
    "estimation": _estimation,
    "matching": _matching,
    "filters": _filters,
    "aerial": _aerial,
    "smoothing": _smoothing,
    "control": _control,
    "sim": _sim,
}


def kernels() -> dict[str, Any]:
    """Every ``cache=True`` numba dispatcher of mjnav's modules, by ``module.name`` (imports every module)."""
    from numba.core.caching import NullCache
    from numba.core.registry import CPUDispatcher

    found: dict[str, Any] = {}
    for info in pkgutil.walk_packages(mjnav.__path__, "mjnav."):
        if info.name.endswith("__main__"):
            continue  # running it is the command line
        try:
            module = importlib.import_module(info.name)
        except ImportError:
            continue  # an optional dependency is missing: that module is not used here
        for name, value in vars(module).items():
            if (
                isinstance(value, CPUDispatcher)
                and value.__module__ == info.name
                and not isinstance(value._cache, NullCache)  # type: ignore[attr-defined]  # cache=True
            ):
                found[f"{info.name}.{name}"] = value
    return found


def uncompiled() -> list[str]:
    """The ``cache=True`` kernels that have no compiled signature, neither in this process nor in their on-disk
    cache (a helper that other kernels call is cached when they compile; ``inline="always"`` ones never are)."""
    missing = []
    for name, d in kernels().items():
        if d.signatures or d.targetoptions.get("inline") == "always":
            continue
        if not d._cache._cache_file._load_index():
            missing.append(name)
    return sorted(missing)


def warm(log: Callable[[str], None] = print) -> dict[str, float]:
    """Run every exercise; returns the wall seconds each took (seconds when it compiled, milliseconds when the
    caches were warm)."""
    times: dict[str, float] = {}
    for name, exercise in EXERCISES.items():
        t0 = time.perf_counter()
        exercise()
        times[name] = time.perf_counter() - t0
        log(f"mjnav warmup: {name} {times[name]:.2f} s")
    return times


def main(argv: list[str] | None = None) -> int:
    """``mjnav warmup`` / ``python -m mjnav.warmup``; exit 0 once every exercise ran."""
    parser = argparse.ArgumentParser(prog="mjnav warmup", description=__doc__.split("\n\n")[0])
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors")
    parser.add_argument("--list-missing", action="store_true", help="name the kernels no exercise compiled")
    args = parser.parse_args(argv)
    warm((lambda _m: None) if args.quiet else print)
    if args.list_missing:
        for name in uncompiled():
            print(f"not compiled by the warm-up: {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

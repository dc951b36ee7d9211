"""What a run looked like, recorded from the bus for plots: true and estimated trajectories, the plan, the path,
commanded and measured speeds (``mjnav demo --out DIR`` draws them with :mod:`mjnav.viz.plots`)."""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjnav.bus import Bus
from mjnav.msgs import ros


@dataclass(frozen=True)
class RunTrace:
    """A recorded run (sim time, map frame).

    Attributes:
        truth: (N, 3) true poses: t s, x m, y m.
        estimate: (M, 3) SLAM's ``pose``: t s, x m, y m.
        commanded: (K, 3) ``cmd_vel`` as it went out: t s (newest stamp seen), v m/s, ω rad/s.
        measured: (L, 3) wheel odometry's twist: t s, v m/s, ω rad/s.
        plans: every distinct ``plan`` received, each (P, 2) x, y in metres (the last one is the newest).
        path: (Q, 2) the newest smoothed ``path``, metres (empty before one).
        occupancy: (H, W) int8 newest ``map`` (−1 unknown, 0..100), or None without one.
        map_origin_m: (x, y) of the map's cell (0, 0) corner, metres.
        map_resolution_m: the map's cell size, metres.
    """

    truth: NDArray[np.float64]
    estimate: NDArray[np.float64]
    commanded: NDArray[np.float64]
    measured: NDArray[np.float64]
    plans: list[NDArray[np.float64]]
    path: NDArray[np.float64]
    occupancy: NDArray[np.int8] | None
    map_origin_m: tuple[float, float] = (0.0, 0.0)
    map_resolution_m: float = 0.05

    @staticmethod
    def true_speed(truth: NDArray[np.float64]) -> NDArray[np.float64]:
        """(N−1, 2) true speed from consecutive true poses: t s (midpoint), |v| m/s."""
        if len(truth) < 2:
            return np.zeros((0, 2))
        dt = np.diff(truth[:, 0])
        ok = dt > 0
        v = np.hypot(np.diff(truth[:, 1]), np.diff(truth[:, 2]))[ok] / dt[ok]
        t = 0.5 * (truth[1:, 0] + truth[:-1, 0])[ok]
        return np.column_stack((t, v))


@dataclass
class _Buffers:
    truth: list[tuple[float, float, float]] = field(default_factory=list)
    estimate: list[tuple[float, float, float]] = field(default_factory=list)
    commanded: list[tuple[float, float, float]] = field(default_factory=list)
    measured: list[tuple[float, float, float]] = field(default_factory=list)
    plans: list[Any] = field(default_factory=list)
    path: Any = None
    stamp: float = math.nan


class TraceRecorder:
    """Records a :class:`RunTrace` from ``truth``, ``pose``, ``cmd_vel``, ``odom``, ``plan``, ``path`` and ``map``
    on ``bus`` (callbacks; behind a :class:`~mjnav.runtime.simtime.SimTimeGate` they run when the clock commits
    them, in arrival order)."""

    def __init__(self, bus: Bus) -> None:
        self._lock = threading.Lock()
        self._b = _Buffers()
        self._map = bus.subscribe("map")
        bus.subscribe("truth", callback=self._on_truth)
        bus.subscribe("pose", callback=self._on_pose)
        bus.subscribe("odom", callback=self._on_odom)
        bus.subscribe("cmd_vel", callback=self._on_cmd)
        bus.subscribe("plan", callback=self._on_plan)
        bus.subscribe("path", callback=self._on_path)

    def _on_truth(self, msg: Any) -> None:
        t = ros.seconds(msg.header.stamp)
        with self._lock:
            self._b.truth.append((t, msg.pose.position.x, msg.pose.position.y))
            self._b.stamp = t

    def _on_pose(self, msg: Any) -> None:
        p = msg.pose.pose.position
        with self._lock:
            self._b.estimate.append((ros.seconds(msg.header.stamp), p.x, p.y))

    def _on_odom(self, msg: Any) -> None:
        tw = msg.twist.twist
        with self._lock:
            self._b.measured.append((ros.seconds(msg.header.stamp), tw.linear.x, tw.angular.z))

    def _on_cmd(self, msg: Any) -> None:
        with self._lock:
            if math.isfinite(self._b.stamp):
                self._b.commanded.append((self._b.stamp, msg.linear.x, msg.angular.z))

    @staticmethod
    def _points(msg: Any) -> NDArray[np.float64]:
        return np.array([(p.pose.position.x, p.pose.position.y) for p in msg.poses], dtype=np.float64).reshape(-1, 2)

    def _on_plan(self, msg: Any) -> None:
        pts = self._points(msg)
        with self._lock:
            plans = self._b.plans
            if len(pts) and not (plans and plans[-1].shape == pts.shape and np.array_equal(plans[-1], pts)):
                plans.append(pts)

    def _on_path(self, msg: Any) -> None:
        pts = self._points(msg)
        with self._lock:
            if len(pts):
                self._b.path = pts

    def trace(self) -> RunTrace:
        """The run so far."""
        msg = self._map.latest()
        occupancy, origin, res = None, (0.0, 0.0), 0.05
        if msg is not None:
            cells, frame = ros.grid_frame(msg)
            occupancy, origin, res = np.asarray(cells, dtype=np.int8), frame.origin_m, frame.resolution_m
        with self._lock:
            b = self._b

            def arr(rows: list[tuple[float, float, float]]) -> NDArray[np.float64]:
                return np.array(rows, dtype=np.float64).reshape(-1, 3)

            return RunTrace(
                truth=arr(b.truth),
                estimate=arr(b.estimate),
                commanded=arr(b.commanded),
                measured=arr(b.measured),
                plans=list(b.plans),
                path=np.zeros((0, 2)) if b.path is None else b.path,
                occupancy=occupancy,
                map_origin_m=(float(origin[0]), float(origin[1])),
                map_resolution_m=float(res),
            )

"""The smoother service: raw grid ``plan`` → smooth ``path``, never closer to obstacles than the plan allows.

The plan is resampled at ``spacing_m`` and smoothed with the configured method (QP by default; gradient descent,
SMA, WMA or a C2 spline). Every point may move at most ``max_deviation_m``, and never further than its clearance
from the costmap's inscribed obstacles (minus ``margin_m``) allows, so the smooth path does not cut corners into
walls. An empty plan (goal ended) gives an empty path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from mjnav.mapping import clearance_m
from mjnav.msgs import ros
from mjnav.planning.costmap import INSCRIBED
from mjnav.runtime import Service
from mjnav.smoothing import (
    fit_spline,
    gradient_descent,
    half_widths,
    moving_average,
    qp_smooth,
    remove_duplicates,
    resample,
    triangular_weights,
    weighted_moving_average,
)


@dataclass(frozen=True)
class SmootherConfig:
    """Smoother settings (``services/smoother.toml``).

    Attributes:
        rate_hz: loop rate (sim time).
        method: ``qp``, ``gradient_descent``, ``sma``, ``wma`` or ``spline``.
        spacing_m: resampling step of the plan before smoothing.
        max_deviation_m: most any point may move (per coordinate).
        margin_m: clearance kept on top of the costmap's inscribed radius, metres. It must exceed the controller's
            collision margin plus its tracking error: at 0.03 m a smoothed path rounded a maze corner 0.21 m from
            it, exactly where the controller's last-line check (radius 0.19 + 0.02) stops, and the robot stuck
            there (maze, seed 1, 3× odometry noise); 0.1 m leaves 8 cm for tracking.
        w_smooth, w_data: weights of the smoothing cost (qp, gradient_descent).
        window: points in the moving-average window (sma, wma), odd.
        spline_smoothing: misfit/roughness trade-off of the C2 spline (0 interpolates the plan).
    """

    rate_hz: float = 10.0
    method: Literal["qp", "gradient_descent", "sma", "wma", "spline"] = "qp"
    spacing_m: float = 0.1
    max_deviation_m: float = 0.3
    margin_m: float = 0.1
    w_smooth: float = 1.0
    w_data: float = 0.05
    window: int = 7
    spline_smoothing: float = 10.0

    def __post_init__(self) -> None:
        if not self.spacing_m > 0:
            raise ValueError(f"spacing_m must be > 0, got {self.spacing_m}")
        if not (self.max_deviation_m >= 0 and self.margin_m >= 0):
            raise ValueError("max_deviation_m and margin_m must be >= 0")
        if not self.spline_smoothing >= 0:
            raise ValueError(f"spline_smoothing must be >= 0, got {self.spline_smoothing}")
        if self.window < 3 or self.window % 2 == 0:
            raise ValueError(f"window must be odd and >= 3, got {self.window}")


class SmootherService(Service[SmootherConfig]):
    """Turns each new plan into a smooth path."""

    name = "smoother"
    config_class = SmootherConfig
    #: Read from ``self.config`` at every use: ``mjnav param set smoother KEY VALUE`` changes them while running.
    runtime_settable = frozenset({"method", "max_deviation_m", "w_smooth", "w_data", "spacing_m"})

    def configure(self) -> None:
        self.plan = self.bus.subscribe("plan")
        self.costmap = self.bus.subscribe("costmap")
        self.path_pub = self.bus.publisher("path")
        # The clearance field of the newest costmap (a distance transform of the whole grid): computed once per
        # costmap, which changes at the mapper's publish rate, not at every plan.
        self._clearance: tuple[Any, Any, Any] | None = None
        # Load the compiled kernels now, not when the first plan arrives.
        warm = np.column_stack((np.linspace(0.0, 1.0, 12), 0.05 * np.sin(np.linspace(0.0, 6.0, 12))))
        self.smooth(warm)

    def step(self, now: float) -> None:
        plan = self.plan.take()
        if plan is None:
            return
        points = ros.path_points(plan)
        if len(points) >= 2:
            points = self.smooth(points)
        self.path_pub.put(ros.path_msg(now, "map", points))

    def allowed_deviation(self, points: Any) -> Any:
        """(N,) distance each point may move: its clearance from inscribed obstacles minus the margin, metres."""
        msg = self.costmap.latest()
        if msg is None:
            return np.zeros(len(points))
        if self._clearance is None or self._clearance[0] is not msg:
            cells, frame = ros.grid_frame(msg)
            # Clearances beyond what a box of half-width max_deviation_m needs (its corners: √2·max_deviation_m)
            # plus the margin change nothing; farther cells may read +inf.
            within = math.sqrt(2.0) * self.config.max_deviation_m + self.config.margin_m + frame.resolution_m
            self._clearance = (msg, frame, clearance_m(cells >= INSCRIBED, frame.resolution_m, within_m=within))
        _, frame, field = self._clearance
        clear = frame.values_at(field, points, outside=0.0)
        return np.maximum(clear - self.config.margin_m, 0.0)

    def smooth(self, plan_points: Any) -> Any:
        """Smooth (N, 2) plan points with the configured method; returns (M, 2) points."""
        cfg = self.config
        pts = remove_duplicates(resample(plan_points, cfg.spacing_m))
        if len(pts) < 3:
            return pts
        # Every method keeps each point in the same box: min(max deviation, clearance/√2) per coordinate.
        half = half_widths(cfg.max_deviation_m, len(pts), self.allowed_deviation(pts))
        if cfg.method == "qp":
            return qp_smooth(pts, max_deviation_m=half, w_smooth=cfg.w_smooth, w_data=cfg.w_data)
        if cfg.method == "gradient_descent":
            return gradient_descent(pts, cfg.w_smooth, cfg.w_data, max_deviation_m=half)
        if cfg.method == "spline":
            spline = fit_spline(pts, continuity=2, smoothing=cfg.spline_smoothing)
            out = spline.evaluate(spline.knots)
        elif cfg.method == "sma":
            out = moving_average(pts, cfg.window)
        else:
            out = weighted_moving_average(pts, triangular_weights(cfg.window))
        return np.clip(out, pts - half[:, None], pts + half[:, None])

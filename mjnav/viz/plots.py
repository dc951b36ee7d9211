"""Plots of a run (matplotlib, the ``plot`` extra): ``run.png`` (map, true and estimated trajectories, plans, path,
goals) and ``speed.png`` (commanded and measured speed over sim time), as ``mjnav demo --out DIR`` writes them.

Figures are drawn with matplotlib's object API on an Agg canvas (no pyplot, no global backend). Each function
returns a :class:`PixelMap` that places map-frame points (or times and speeds) in the saved PNG, so tests can
check the pixels where the trajectory must be.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjnav.runtime.trace import RunTrace

#: Colours (RGB 0..255) of the plotted items; tests look for them in the PNG.
TRUE_COLOUR = (31, 119, 180)
ESTIMATE_COLOUR = (255, 127, 14)
PLAN_COLOUR = (44, 160, 44)
PATH_COLOUR = (148, 103, 189)
GOAL_COLOUR = (214, 39, 40)
COMMANDED_COLOUR = (31, 119, 180)
MEASURED_COLOUR = (255, 127, 14)
TRUE_SPEED_COLOUR = (44, 160, 44)

_DPI = 100


def _hex(rgb: tuple[int, int, int]) -> str:
    return "#{:02x}{:02x}{:02x}".format(*rgb)


@dataclass(frozen=True)
class PixelMap:
    """Where data coordinates of one axes landed in a saved PNG.

    Attributes:
        size_px: (width, height) of the image.
        matrix: 3 × 3 affine data → display transform (display = pixels from the bottom-left).
    """

    size_px: tuple[int, int]
    matrix: NDArray[np.float64]

    def pixel(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of data point (x, y) in the image (row 0 at the top)."""
        dx, dy, _ = self.matrix @ np.array([x, y, 1.0])
        return round(float(self.size_px[1] - dy - 0.5)), round(float(dx - 0.5))


def _figure(size_in: tuple[float, float]) -> tuple[Any, Any]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size_in, dpi=_DPI)
    FigureCanvasAgg(fig)
    return fig, fig.add_subplot(1, 1, 1)


def _save(fig: Any, ax: Any, out: Path) -> PixelMap:
    fig.tight_layout()
    fig.canvas.draw()
    matrix = np.asarray(ax.transData.get_affine().get_matrix(), dtype=np.float64)
    width, height = fig.canvas.get_width_height()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=_DPI)
    return PixelMap((int(width), int(height)), matrix)


def plot_run(trace: RunTrace, out: str | Path, goals: Sequence[tuple[float, float]] = (), title: str = "") -> PixelMap:
    """Draw the run on its map: grey map (white free ≤ 25, black occupied ≥ 65, light grey unknown), true trajectory
    (solid), SLAM's estimate (dashed), every plan (thin, the newest thicker), the newest smoothed path, goals
    (stars) and the start (circle). Axes in metres, equal aspect.

    Args:
        trace: the recorded run.
        out: PNG file to write.
        goals: (x, y) goals in the map frame, metres.
        title: figure title.

    Returns:
        Where map-frame points lie in the PNG.
    """
    fig, ax = _figure((8.0, 8.0))
    if trace.occupancy is not None:
        occ = trace.occupancy.astype(np.float64)
        # Like map_server's trinary reading: free (<= 25) white, occupied (>= 65) black, grey between; unknown.
        known = np.where(occ >= 65, 0.0, np.where(occ <= 25, 1.0, 1.0 - occ / 100.0))
        shade = np.where(occ < 0, 0.85, known)
        h, w = occ.shape
        x0, y0 = trace.map_origin_m
        res = trace.map_resolution_m
        ax.imshow(
            shade, cmap="gray", vmin=0.0, vmax=1.0, origin="lower", interpolation="nearest",
            extent=(x0, x0 + w * res, y0, y0 + h * res),
        )  # fmt: skip
    for i, plan in enumerate(trace.plans):
        newest = i == len(trace.plans) - 1
        style = {"lw": 1.5, "label": "plan (newest bold)"} if newest else {"lw": 0.6, "alpha": 0.5}
        ax.plot(plan[:, 0], plan[:, 1], color=_hex(PLAN_COLOUR), **style)
    if len(trace.path):
        ax.plot(trace.path[:, 0], trace.path[:, 1], color=_hex(PATH_COLOUR), lw=1.2, label="smoothed path")
    if len(trace.estimate):
        ax.plot(trace.estimate[:, 1], trace.estimate[:, 2], "--", color=_hex(ESTIMATE_COLOUR), lw=1.5,
                label="estimated (SLAM)")  # fmt: skip
    if len(trace.truth):
        ax.plot(trace.truth[:, 1], trace.truth[:, 2], color=_hex(TRUE_COLOUR), lw=2.5, label="true")
        ax.plot(trace.truth[0, 1], trace.truth[0, 2], "o", color="black", ms=8, label="start")
    for i, (gx, gy) in enumerate(goals):
        ax.plot(gx, gy, "*", color=_hex(GOAL_COLOUR), ms=16, label="goal" if i == 0 else None)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if title:
        ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    return _save(fig, ax, Path(out))


def plot_speed(trace: RunTrace, out: str | Path, title: str = "") -> PixelMap:
    """Draw commanded (``cmd_vel``), measured (wheel odometry) and true speed over sim time.

    Returns:
        Where (t s, v m/s) points lie in the PNG.
    """
    fig, ax = _figure((9.0, 4.0))
    if len(trace.commanded):
        ax.step(trace.commanded[:, 0], trace.commanded[:, 1], where="post", color=_hex(COMMANDED_COLOUR), lw=2.0,
                label="commanded (cmd_vel)")  # fmt: skip
    if len(trace.measured):
        ax.plot(trace.measured[:, 0], trace.measured[:, 1], color=_hex(MEASURED_COLOUR), lw=1.2,
                label="measured (wheel odometry)")  # fmt: skip
    true_v = RunTrace.true_speed(trace.truth)
    if len(true_v):
        ax.plot(true_v[:, 0], true_v[:, 1], ":", color=_hex(TRUE_SPEED_COLOUR), lw=1.2, label="true")
    ax.set_xlabel("sim time (s)")
    ax.set_ylabel("speed (m/s)")
    ax.grid(True, alpha=0.3)
    if title:
        ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    return _save(fig, ax, Path(out))

"""run.png and speed.png show what was recorded: the trajectory's pixels are where the trajectory is."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

pytest.importorskip("matplotlib")

from mjnav.runtime.trace import RunTrace
from mjnav.viz.plots import (
    COMMANDED_COLOUR,
    ESTIMATE_COLOUR,
    GOAL_COLOUR,
    MEASURED_COLOUR,
    TRUE_COLOUR,
    plot_run,
    plot_speed,
)


def _near(img: np.ndarray, row: int, col: int, colour: tuple[int, int, int], radius: int = 2, tol: int = 40) -> bool:
    """Some pixel within ``radius`` of (row, col) has ``colour`` (each channel within ``tol``)."""
    patch = img[max(row - radius, 0) : row + radius + 1, max(col - radius, 0) : col + radius + 1, :3].astype(int)
    return bool((np.abs(patch - np.array(colour)).max(axis=-1) <= tol).any())


def _trace() -> RunTrace:
    t = np.linspace(0.0, 20.0, 401)
    x, y = -3.0 + 0.3 * t, -3.0 + 2.0 * np.sin(0.3 * t)  # a wave from (-3, -3) to (3, ...)
    occupancy = np.zeros((200, 200), dtype=np.int8)  # 10 x 10 m at 5 cm, origin (-5, -5)
    occupancy[150:, :] = -1  # y > 2.5 unknown
    occupancy[20:24, 20:180] = 100  # a wall at y = -4.0 .. -3.8, x = -4 .. 4
    return RunTrace(
        truth=np.column_stack((t, x, y)),
        estimate=np.column_stack((t, x + 0.4, y - 0.4)),
        commanded=np.column_stack((t, np.where((t > 2) & (t < 18), 0.5, 0.0), np.zeros_like(t))),
        measured=np.column_stack((t, np.where((t > 2.5) & (t < 18.5), 0.35, 0.0), np.zeros_like(t))),
        plans=[np.column_stack((x, y + 1.0))],
        path=np.column_stack((x, y + 1.0)),
        occupancy=occupancy,
        map_origin_m=(-5.0, -5.0),
        map_resolution_m=0.05,
    )


@pytest.mark.e2e
def test_run_png_draws_the_map_trajectories_and_goal_where_they_are(tmp_path: Path) -> None:
    trace = _trace()
    goal = (float(trace.truth[-1, 1]), float(trace.truth[-1, 2]))
    px = plot_run(trace, tmp_path / "run.png", goals=[goal])
    img = np.asarray(Image.open(tmp_path / "run.png").convert("RGB"))
    assert img.shape[:2] == (px.size_px[1], px.size_px[0])
    samples = trace.truth[40:360:20]
    hits = sum(_near(img, *px.pixel(x, y), TRUE_COLOUR) for _, x, y in samples)
    assert hits >= 0.8 * len(samples)  # the legend may cover a few
    est = trace.estimate[40:360:20]
    assert sum(_near(img, *px.pixel(x, y), ESTIMATE_COLOUR, radius=4) for _, x, y in est) >= 0.6 * len(est)  # dashed
    # Nothing of the trajectory's colour where it is not: half a metre beside it, below the wave.
    away = [px.pixel(x, y - 0.7) for _, x, y in samples]
    assert sum(_near(img, r, c, TRUE_COLOUR, radius=1, tol=20) for r, c in away) <= 1
    assert _near(img, *px.pixel(*goal), GOAL_COLOUR, radius=3)
    wall = img[px.pixel(0.0, -3.9)]
    unknown = img[px.pixel(-4.0, 4.0)]
    free = img[px.pixel(-4.5, 0.0)]
    assert wall.max() < 60 and 190 < unknown.mean() < 235 and free.min() > 240


def test_speed_png_draws_commanded_and_measured_speed(tmp_path: Path) -> None:
    trace = _trace()
    px = plot_speed(trace, tmp_path / "speed.png")
    img = np.asarray(Image.open(tmp_path / "speed.png").convert("RGB"))
    for t in (5.0, 10.0, 15.0):
        assert _near(img, *px.pixel(t, 0.5), COMMANDED_COLOUR)
        assert _near(img, *px.pixel(t, 0.35), MEASURED_COLOUR)
        assert not _near(img, *px.pixel(t, 0.42), COMMANDED_COLOUR, radius=1, tol=20)

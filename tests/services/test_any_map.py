"""Any map runs: `mjnav demo --world MAP` on a Moving AI map and on a map the mapper saved, end to end.

Real processes on loopback Zenoh, in lockstep; every figure asserted is sim time or ground truth.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mjnav.sim.truth import FootprintClearance, shortest_length_m
from mjnav.sim.worlds import world_info
from tests.conftest import free_port
from tests.services.test_navigation import _mjnav

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers

DATA = Path(__file__).parent / "data"


def _demo(out: Path, world: Path, seed: int, *extra: str) -> dict[str, Any]:
    args = ["demo", "--world", str(world), "--seed", str(seed), "--rtf", "4", "--json", "--headless", "--out", str(out)]
    proc = _mjnav(*args, "--timeout", "120", "--port", str(free_port()), *extra)
    stdout, _ = proc.communicate(timeout=900)
    assert proc.returncode == 0, stdout[-3000:]
    summary: dict[str, Any] = json.loads(stdout.strip().splitlines()[-1])
    assert json.loads((out / "summary.json").read_text()) == summary
    summary["_log"] = stdout
    return summary


def _check_run(summary: dict[str, Any], scene: Path) -> None:
    """Reached without touching anything, on a path close to the shortest, in bounded sim time."""
    info = world_info(scene)
    goal = info.goal
    assert goal is not None
    (only,) = summary["goals"]
    assert only["goal"] == pytest.approx([goal.x, goal.y])
    assert only["start"] == pytest.approx([info.start.x, info.start.y], abs=0.05)
    assert summary["reached"] is True and summary["collisions"] == 0
    assert summary["min_clearance_m"] > 0.0
    optimal = shortest_length_m(scene, (info.start.x, info.start.y), (goal.x, goal.y))
    assert summary["optimal_length_m"] == pytest.approx(optimal, abs=1e-4)  # the summary rounds to 0.1 mm
    assert optimal - 0.15 <= summary["path_length_m"] <= 1.25 * optimal  # it may stop 0.1 m short (goal tolerance)
    assert summary["time_s"] <= 1.25 * optimal / summary["v_max_mps"] + 15.0  # sim seconds
    final = summary["final_pose"]
    assert math.dist(final[:2], (goal.x, goal.y)) < 0.3
    # The true clearance at the end, recomputed from the scene: the robot stands in free space.
    assert FootprintClearance(scene).clearance_m(final[0], final[1]) > 0.0


def test_den312d_runs_end_to_end(refdata: Path, tmp_path: Path) -> None:
    # Moving AI den312d (65 x 81 cells of 0.5 m: 32.5 x 40.5 m) lies far outside the former fixed 20 x 20 m costmap.
    out = tmp_path / "den"
    summary = _demo(out, refdata / "movingai" / "den312d.map", seed=0)
    scene = out / "world.xml"
    assert scene.is_file()
    bounds = world_info(scene).bounds_m
    assert bounds is not None and bounds[2] - bounds[0] > 30.0 and bounds[3] - bounds[1] > 40.0
    _check_run(summary, scene)
    _check_plots(out)


def _check_plots(out: Path) -> None:
    """run.png shows the driven trajectory and the goal, speed.png the commanded and measured speeds: counted in
    their colours (tests/viz/test_plots.py checks where they land)."""
    from PIL import Image

    from mjnav.viz.plots import COMMANDED_COLOUR, GOAL_COLOUR, MEASURED_COLOUR, TRUE_COLOUR

    def count(name: str, colour: tuple[int, int, int]) -> int:
        img = np.asarray(Image.open(out / name).convert("RGB")).astype(int)
        return int((np.abs(img - np.array(colour)).max(axis=-1) <= 10).sum())

    assert count("run.png", TRUE_COLOUR) > 300  # ~9 m of a 3.5 px line at ~15 px/m
    assert count("run.png", GOAL_COLOUR) > 100  # the star at the goal (and the legend's)
    # Both speed lines are drawn; where the robot tracks its command closely the measured line covers the other.
    assert count("speed.png", COMMANDED_COLOUR) > 50 and count("speed.png", MEASURED_COLOUR) > 150


def test_a_saved_rooms_map_runs_end_to_end(tmp_path: Path) -> None:
    # rooms_saved.yaml: the map `mjnav demo --world rooms --out DIR` saved (unknown outside the building, and where
    # the robot did not look). Start and goal come from the seed, inside the known free space.
    out = tmp_path / "saved"
    summary = _demo(out, DATA / "rooms_saved.yaml", seed=1)
    scene = out / "world.xml"
    info = world_info(scene)
    assert info.goal is not None
    for pose in (info.start, info.goal):  # inside the building (its outer walls are at x, y = ±5)
        assert abs(pose.x) < 4.9 and abs(pose.y) < 4.9
    _check_run(summary, scene)
    assert summary["known_map"] is False and "prior map" not in summary["_log"]


def test_with_known_map_the_mapper_starts_from_the_map_file(tmp_path: Path) -> None:
    summary = _demo(tmp_path / "known", DATA / "rooms_saved.yaml", 1, "--known-map")
    _check_run(summary, tmp_path / "known" / "world.xml")
    assert summary["known_map"] is True
    assert f"prior map {(DATA / 'rooms_saved.yaml').resolve()}: 243x243 cells at 0.050 m" in summary["_log"]

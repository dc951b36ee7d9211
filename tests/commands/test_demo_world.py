"""`mjnav demo --world`: map files become worlds with a seeded start and goal; a scene without a goal gets one."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mjnav.commands.demo import AUTO_CLEARANCE_M, AUTO_GOAL_DISTANCE_M, known_map, reachable_goal, world_from_map
from mjnav.mapping import read_ros_map
from mjnav.sim.truth import FootprintClearance, shortest_length_m
from mjnav.sim.worlds import MJCF_DIR, world_info

DATA = Path(__file__).resolve().parents[1] / "services" / "data"


def _without_goal(tmp_path: Path, world: str) -> Path:
    """A bundled scene minus its goal, written to ``tmp_path`` (its include made absolute)."""
    text = (MJCF_DIR / f"{world}.xml").read_text(encoding="utf-8")
    start = text.index('<numeric name="mjnav_goal"')
    text = text[:start] + text[text.index("/>", start) + 2 :]
    text = text.replace('file="assets/common.xml"', f'file="{MJCF_DIR / "assets" / "common.xml"}"')
    path = tmp_path / f"{world}_without_goal.xml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("world", ["rooms", "empty"])
def test_a_scene_without_a_goal_gets_a_reachable_seeded_one(tmp_path: Path, world: str) -> None:
    scene = _without_goal(tmp_path, world)
    info = world_info(scene)
    assert info.goal is None
    goals = [reachable_goal(info, seed) for seed in range(3)]
    assert goals[0] == reachable_goal(info, 0)  # the seed decides
    assert len({(g.x, g.y) for g in goals}) == 3
    lo, hi = AUTO_GOAL_DISTANCE_M
    clearance = FootprintClearance(scene)
    for goal in goals:
        assert lo <= math.dist((goal.x, goal.y), (info.start.x, info.start.y)) <= hi
        assert clearance.obstacle_distance_m(goal.x, goal.y) >= AUTO_CLEARANCE_M - 0.1  # grid cells: 0.1 m
        assert math.isfinite(shortest_length_m(scene, (info.start.x, info.start.y), (goal.x, goal.y)))


def test_a_map_file_becomes_a_world_with_a_seeded_start_and_goal(tmp_path: Path) -> None:
    made = [
        world_info(world_from_map(str(DATA / "rooms_saved.yaml"), tmp_path / f"{s}.xml", s, None)) for s in (0, 0, 1)
    ]
    assert (made[0].start, made[0].goal) == (made[1].start, made[1].goal)
    assert (made[0].start, made[0].goal) != (made[2].start, made[2].goal)
    with pytest.raises(ValueError, match="resolution"):  # a ROS map carries its own
        world_from_map(str(DATA / "rooms_saved.yaml"), tmp_path / "x.xml", 0, 0.5)


def test_the_known_map_is_the_map_file_itself_or_the_worlds_true_static_map(tmp_path: Path) -> None:
    saved = DATA / "rooms_saved.yaml"
    scene = world_from_map(str(saved), tmp_path / "saved.xml", 0, None)
    assert known_map(str(saved), scene, tmp_path, 0.05) == saved  # unknown cells and all, as given
    rooms = world_info("rooms")
    given = read_ros_map(known_map("rooms", rooms.path, tmp_path, 0.05))
    assert given.resolution_m == 0.05 and set(given.occupancy.ravel()) == {0, 100}
    clearance = FootprintClearance("rooms")
    cells = given.occupancy
    rng = np.random.default_rng(5)
    for r, c in rng.integers(0, cells.shape, size=(500, 2)):
        x = given.origin_m[0] + (c + 0.5) * 0.05
        y = given.origin_m[1] + (r + 0.5) * 0.05
        d = clearance.obstacle_distance_m(x, y)
        if abs(d) > 1e-9:
            assert (cells[r, c] == 100) == (d < 0), (x, y, d)

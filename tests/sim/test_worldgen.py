"""Occupancy map → world: exact greedy rectangle cover, Moving AI and ROS maps, the CLI."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mjnav.cli import main
from mjnav.geometry import Pose2D
from mjnav.sim import MapConversionError, Simulator, world_info
from mjnav.sim.worldgen import (
    GridMap,
    add_border,
    choose_goal,
    choose_start_goal,
    load_grid_map,
    merge_rectangles,
    write_scene_from_map,
)

MAP_TEXT = """type octile
height 6
width 10
map
..........
..@@@@....
..@@@@....
.......T..
.......T..
..........
"""


def _cover(rects: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    count = np.zeros(shape, dtype=int)
    for r, c, nr, nc in rects:
        count[r : r + nr, c : c + nc] += 1
    return count


@pytest.mark.parametrize("density", [0.1, 0.5, 0.9])
def test_merged_rectangles_cover_exactly_the_occupied_cells(density: float) -> None:
    rng = np.random.default_rng(42)
    occ = rng.random((40, 57)) < density
    rects = merge_rectangles(occ)
    count = _cover(rects, occ.shape)
    assert np.array_equal(count, occ.astype(int))  # no gaps, no overlaps, nothing outside
    assert len(rects) <= occ.sum()


def test_blocky_maps_merge_into_few_boxes() -> None:
    occ = np.zeros((50, 80), dtype=bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True  # a closed room
    occ[10:30, 20:45] = True  # one big block
    rects = merge_rectangles(occ)
    assert len(rects) == 5
    assert np.array_equal(_cover(rects, occ.shape), occ.astype(int))


def test_moving_ai_map_becomes_a_world_with_walls_where_the_map_says(tmp_path: Path) -> None:
    src = tmp_path / "tiny.map"
    src.write_text(MAP_TEXT)
    grid = load_grid_map(src, resolution_m=1.0)
    assert grid.occupied.shape == (6, 10)
    assert grid.occupied[-2, 2:6].all()  # row 1 of the file (from the top) is the second-highest y row
    out = tmp_path / "tiny.xml"
    summary = write_scene_from_map(src, out, resolution_m=1.0, start=Pose2D(0.5, 0.5, 0.0), goal=Pose2D(9.5, 5.5))
    assert summary.occupied_cells == 10 + 36  # the map's 10 + the border ring (12 x 8 - 10 x 6)
    assert summary.boxes == 2 + 4  # the @ block and the T column, plus four border walls
    info = world_info(out)
    assert info.start == Pose2D(0.5, 0.5, 0.0)
    assert info.goal is not None and info.goal.x == pytest.approx(9.5)
    assert info.bounds_m == pytest.approx((-1.0, -1.0, 11.0, 7.0))
    # the @ block spans x [2, 6], y [3, 5]: a robot at (4, 2) looking up sees its south face 1 m away
    sim = Simulator(out, seed=0, start=Pose2D(4.0, 2.0, math.pi / 2))
    scan = sim.lidar_scan()
    ahead = int(np.argmin(np.abs(scan.angles_rad)))
    assert scan.ranges_m[ahead] == pytest.approx(1.0, abs=0.05)
    sim.step_until(0.5)
    assert sim.mujoco_warnings() == {} and sim.collisions == 0


def _write_ros_map(tmp_path: Path, pixels: np.ndarray, origin: list[float], resolution: float) -> Path:
    h, w = pixels.shape
    (tmp_path / "m.pgm").write_bytes(f"P5\n{w} {h}\n255\n".encode() + pixels.astype(np.uint8).tobytes())
    yaml = tmp_path / "m.yaml"
    yaml.write_text(
        f"image: m.pgm\nresolution: {resolution}\norigin: {origin}\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    return yaml


def test_ros_map_keeps_its_resolution_and_origin(tmp_path: Path) -> None:
    px = np.full((40, 60), 254, dtype=np.uint8)  # free
    px[0:5, :] = 0  # top 5 image rows occupied = the highest y
    px[20:25, 10:20] = 205  # unknown
    yaml = _write_ros_map(tmp_path, px, [-3.0, -1.0, 0.0], 0.05)
    grid = load_grid_map(yaml)
    assert grid.resolution_m == 0.05 and grid.origin_m == (-3.0, -1.0, 0.0)
    assert grid.occupied.sum() == 5 * 60 and grid.occupied[-5:].all()
    assert load_grid_map(yaml, unknown_is_occupied=True).occupied.sum() == 5 * 60 + 50
    out = tmp_path / "ros.xml"
    summary = write_scene_from_map(yaml, out, border=False, start=Pose2D(-1.5, -0.5), goal=Pose2D(-0.5, -0.5))
    assert summary.boxes == 1
    info = world_info(out)
    assert info.bounds_m == pytest.approx((-3.0, -1.0 + 35 * 0.05, 0.0, 1.0))  # x [-3, 0], y [0.75, 1.0]


def test_automatic_start_and_goal_are_far_apart_and_clear(tmp_path: Path) -> None:
    src = tmp_path / "tiny.map"
    src.write_text(MAP_TEXT)
    summary = write_scene_from_map(src, tmp_path / "auto.xml", resolution_m=1.0)
    assert summary.start.distance_to(summary.goal) > 5.0
    sim = Simulator(tmp_path / "auto.xml", seed=0)
    sim.step_until(0.3)
    assert sim.collisions == 0


def test_bad_maps_are_typed_errors(tmp_path: Path) -> None:
    bad = tmp_path / "bad.map"
    bad.write_text("type octile\nheight 2\nwidth 2\nmap\n..\n")
    with pytest.raises(MapConversionError):
        load_grid_map(bad)
    with pytest.raises(MapConversionError, match="unknown map format"):
        load_grid_map(tmp_path / "x.png")
    full = tmp_path / "full.map"
    full.write_text("type octile\nheight 2\nwidth 2\nmap\n@@\n@@\n")
    with pytest.raises(MapConversionError, match=r"does not fit|keeps"):
        write_scene_from_map(full, tmp_path / "full.xml")
    assert add_border(load_grid_map(full)).occupied.all()


def test_cli_from_map(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "tiny.map"
    src.write_text(MAP_TEXT)
    out = tmp_path / "cli.xml"
    assert main(["world", "from-map", str(src), "--out", str(out), "--resolution", "1.0", "--start", "0.5", "0.5"]) == 0
    assert "6 boxes" in capsys.readouterr().out
    assert world_info(out).start == Pose2D(0.5, 0.5, 0.0)
    assert main(["world", "from-map", str(tmp_path / "nope.map"), "--out", str(out)]) == 2
    assert "error" in capsys.readouterr().err


def test_cli_from_map_takes_a_png_map_as_its_pgm(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from PIL import Image

    px = np.full((40, 60), 254, dtype=np.uint8)
    px[0:5, :] = 0
    px[15:30, 20:24] = 0
    px[20:25, 40:50] = 205
    yaml = _write_ros_map(tmp_path, px, [-3.0, -1.0, 0.0], 0.05)
    (tmp_path / "png").mkdir()
    Image.fromarray(px, mode="L").save(tmp_path / "png" / "m.png")
    png_yaml = tmp_path / "png" / "m.yaml"
    png_yaml.write_text(yaml.read_text().replace("image: m.pgm", "image: m.png"))
    args = ["--start", "-2.5", "0.2", "--goal", "-0.5", "0.2"]
    assert main(["world", "from-map", str(yaml), "--out", str(tmp_path / "pgm.xml"), *args]) == 0
    assert main(["world", "from-map", str(png_yaml), "--out", str(tmp_path / "png.xml"), *args]) == 0
    pgm_line, png_line = capsys.readouterr().out.splitlines()
    assert "occupied cells -> " in png_line and png_line.replace("png.xml", "pgm.xml") == pgm_line
    assert (tmp_path / "png.xml").read_text() == (tmp_path / "pgm.xml").read_text()


def test_reference_movingai_map_converts(refdata: Path, tmp_path: Path) -> None:
    src = refdata / "movingai" / "arena.map"
    summary = write_scene_from_map(src, tmp_path / "arena.xml")
    assert summary.boxes < summary.occupied_cells / 5
    sim = Simulator(summary.path, seed=0)
    sim.step_until(0.5)
    assert sim.mujoco_warnings() == {} and sim.collisions == 0


def _saved_building_map(tmp_path: Path) -> Path:
    """A map as the mapper saves it: a walled 4 x 4 m building in a 12 x 12 m grid whose outside is unknown."""
    px = np.full((240, 240), 205, dtype=np.uint8)  # unknown
    px[80:160, 80:160] = 254  # the building's inside: known free
    px[80:82, 80:160] = px[158:160, 80:160] = 0  # walls
    px[80:160, 80:82] = px[80:160, 158:160] = 0
    return _write_ros_map(tmp_path, px, [-6.0, -6.0, 0.0], 0.05)


def test_automatic_start_and_goal_stay_in_known_free_space(tmp_path: Path) -> None:
    # The saved rooms map gave a goal outside the building: unknown space is never a start or a goal.
    yaml = _saved_building_map(tmp_path)
    inside = (-2.0 + 0.1, 2.0 - 0.1)  # the building spans x, y in [-2, 2] (walls 0.1 m thick)
    for rng in (None, np.random.default_rng(0), np.random.default_rng(1)):
        summary = write_scene_from_map(yaml, tmp_path / "b.xml", clearance_m=0.5, rng=rng)
        for pose in (summary.start, summary.goal):
            assert inside[0] + 0.5 <= pose.x <= inside[1] - 0.5 and inside[0] + 0.5 <= pose.y <= inside[1] - 0.5


def test_seeded_start_and_goal_are_repeatable_reachable_and_in_the_band(tmp_path: Path) -> None:
    src = tmp_path / "tiny.map"
    src.write_text(MAP_TEXT)
    grid = add_border(load_grid_map(src, resolution_m=1.0))
    picks = [
        choose_start_goal(grid, 0.35, np.random.default_rng(seed), min_distance_m=3.0, max_distance_m=5.0)
        for seed in range(8)
    ]
    again = [
        choose_start_goal(grid, 0.35, np.random.default_rng(seed), min_distance_m=3.0, max_distance_m=5.0)
        for seed in range(8)
    ]
    assert picks == again
    assert len({(s.x, s.y) for s, _ in picks}) > 1  # the seed matters
    for start, goal in picks:
        assert 3.0 <= start.distance_to(goal) <= 5.0
        for pose in (start, goal):  # free cells of the map, away from walls
            row, col = int(pose.y // 1.0) + 1, int(pose.x // 1.0) + 1  # +1: the border moved the origin
            assert not grid.occupied[row, col]


def test_goal_for_a_scene_is_reachable_from_its_start() -> None:
    from mjnav.sim.truth import shortest_length_m, true_grid

    info = world_info("maze")
    occupied, frame = true_grid(info.path)
    grid = GridMap(occupied, frame.resolution_m, (frame.origin_m[0], frame.origin_m[1], 0.0), "maze")
    for seed in range(3):
        goal = choose_goal(grid, info.start, 0.5, np.random.default_rng(seed), min_distance_m=2.0, max_distance_m=6.0)
        assert 2.0 <= info.start.distance_to(goal) <= 6.0
        # shortest_length_m raises NoPathFound when the goal is unreachable for the robot's radius
        assert math.isfinite(shortest_length_m(info.path, (info.start.x, info.start.y), (goal.x, goal.y)))

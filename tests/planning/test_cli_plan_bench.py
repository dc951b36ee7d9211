"""``mjnav plan`` and ``mjnav bench movingai`` through :func:`mjnav.cli.main` (real files, no mocks)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from mjnav.cli import main
from tests.planning import oracle

SQRT2 = math.sqrt(2.0)
MAP_ROWS = [
    "......",
    ".@@@..",
    "......",
    "T.....",
]


def write_movingai(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.map"
    path.write_text("type octile\nheight 4\nwidth 6\nmap\n" + "\n".join(MAP_ROWS) + "\n")
    return path


def run_json(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, dict]:
    code = main(argv)
    out = capsys.readouterr().out
    return code, (json.loads(out) if code == 0 and out.strip().startswith("{") else {})


def test_plan_moving_ai_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_movingai(tmp_path)
    # x = column, y = row: from the top-left corner to the right end of row 2.
    code, res = run_json(capsys, ["plan", "--map", str(path), "--start", "0,0", "--goal", "5,2", "--json"])
    assert code == 0
    assert res["map_type"] == "moving-ai"
    assert res["start"] == [0, 0] and res["goal"] == [5, 2]
    assert res["path"][0] == [0, 0] and res["path"][-1] == [5, 2]
    # By hand: east along row 0 to column 4, diagonal to (x 5, y 1) (its corner cells (x 4, y 1) and (x 5, y 0)
    # are free), down to (5, 2): 4 + √2 + 1. Around the left end the diagonal would cut the wall's corner.
    assert res["cost_cells"] == pytest.approx(5 + SQRT2)
    assert res["cost_m"] is None
    assert res["num_cells"] == len(res["path"])


@pytest.mark.parametrize("algorithm", ["astar", "jps", "dijkstra", "bfs", "dfs", "greedy", "potential_field"])
def test_plan_every_algorithm_text_output(tmp_path: Path, capsys: pytest.CaptureFixture[str], algorithm: str) -> None:
    path = write_movingai(tmp_path)
    code = main(["plan", "--map", str(path), "--start", "0,2", "--goal", "5,0", "--algorithm", algorithm])
    out = capsys.readouterr().out
    assert code == 0
    assert f"algorithm:  {algorithm}" in out
    assert out.strip().splitlines()[-1].split()[0] == "0,2"


def test_plan_options_reach_the_planner(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_movingai(tmp_path)
    args = ["plan", "--map", str(path), "--start", "0,0", "--goal", "5,2", "--json"]
    _, four = run_json(capsys, [*args, "--connectivity", "4"])
    assert four["cost_cells"] == 7.0
    _, weighted = run_json(capsys, [*args, "--weights", "1,5", "--heuristic", "euclidean"])
    assert weighted["weights"] == [1.0, 5.0] and weighted["heuristic"] == "euclidean"
    _, cut = run_json(capsys, [*args, "--corner-cutting"])
    assert cut["corner_cutting"] is True


def test_plan_ros_map_in_metres(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from mjnav.mapping import write_ros_map

    occ = np.zeros((4, 6), dtype=np.int8)
    occ[1, 1:4] = 100  # a wall in the second-lowest row, columns 1..3
    yaml_path = tmp_path / "office.yaml"
    write_ros_map(yaml_path, occ, 0.5, (1.0, 2.0, 0.0))
    code, res = run_json(capsys, ["plan", "--map", str(yaml_path), "--start", "1.1,2.1", "--goal", "3.9,2.9", "--json"])
    assert code == 0
    assert res["map_type"] == "ros"
    # Cell (row 0, col 0) to (row 1, col 5); centres in metres.
    assert res["path"][0] == pytest.approx([1.25, 2.25])
    assert res["path"][-1] == pytest.approx([3.75, 2.75])
    assert res["cost_cells"] == pytest.approx(4 + SQRT2)
    assert res["cost_m"] == pytest.approx(0.5 * (4 + SQRT2))
    # A start on the wall is a planning failure (exit 1) with a typed message.
    assert main(["plan", "--map", str(yaml_path), "--start", "1.8,2.7", "--goal", "3.9,2.9"]) == 1
    assert "StartOccupied" in capsys.readouterr().err
    # Outside the map.
    assert main(["plan", "--map", str(yaml_path), "--start", "0.0,0.0", "--goal", "3.9,2.9"]) == 1
    assert "StartOutsideMap" in capsys.readouterr().err


def test_plan_ros_map_with_rotated_origin(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from mjnav.mapping import write_ros_map

    yaml_path = tmp_path / "rot.yaml"
    write_ros_map(yaml_path, np.zeros((3, 3), dtype=np.int8), 1.0, (10.0, 20.0, math.pi / 2))
    # With yaw 90° the map's +col axis points along world +y and +row along world −x.
    code, res = run_json(
        capsys, ["plan", "--map", str(yaml_path), "--start", "9.5,20.5", "--goal", "7.5,22.5", "--json"]
    )
    assert code == 0
    assert res["path"][0] == pytest.approx([9.5, 20.5])
    assert res["path"][-1] == pytest.approx([7.5, 22.5])
    assert res["cost_cells"] == pytest.approx(2 * SQRT2)


def test_plan_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_movingai(tmp_path)
    assert main(["plan", "--map", str(path), "--start", "1,1", "--goal", "5,2"]) == 1  # on '@'
    assert "StartOccupied" in capsys.readouterr().err
    assert main(["plan", "--map", str(path), "--start", "0,0", "--goal", "9,9"]) == 1
    assert "GoalOutsideMap" in capsys.readouterr().err
    assert main(["plan", "--map", str(path), "--start", "0.5,0", "--goal", "5,2"]) == 2
    assert main(["plan", "--map", str(tmp_path / "none.map"), "--start", "0,0", "--goal", "5,2"]) == 2
    bad = tmp_path / "bad.map"
    bad.write_text("type octile\nheight 1\nwidth 2\nmap\n.x\n")
    assert main(["plan", "--map", str(bad), "--start", "0,0", "--goal", "1,0"]) == 2
    assert "unknown terrain" in capsys.readouterr().err
    assert main(["plan", "--map", str(tmp_path / "m.png"), "--start", "0,0", "--goal", "1,0"]) == 2
    walled = tmp_path / "walled.map"
    walled.write_text("type octile\nheight 2\nwidth 3\nmap\n.@.\n.@.\n")
    assert main(["plan", "--map", str(walled), "--start", "0,0", "--goal", "2,0"]) == 1
    assert "NoPathFound" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["plan", "--map", str(path), "--start", "nan,0", "--goal", "5,2"])
    with pytest.raises(SystemExit):
        main(["plan", "--map", str(path), "--start", "0,0", "--goal", "5,2", "--weights", "0,0"])


def write_scenarios(tmp_path: Path, lengths: list[float] | None = None) -> tuple[Path, Path]:
    path = write_movingai(tmp_path)
    occ = np.array([[ch != "." for ch in row] for row in MAP_ROWS])
    queries = [((0, 0), (2, 5)), ((3, 1), (0, 5)), ((2, 0), (2, 5)), ((0, 5), (3, 1))]
    lines = ["version 1"]
    for i, (s, g) in enumerate(queries):
        length = oracle.distances(occ, s)[g] if lengths is None else lengths[i]
        lines.append(f"0\ttiny.map\t6\t4\t{s[1]}\t{s[0]}\t{g[1]}\t{g[0]}\t{length:.8f}")
    scen = tmp_path / "tiny.map.scen"
    scen.write_text("\n".join(lines) + "\n")
    return path, scen


@pytest.mark.parametrize("algorithm", ["astar", "jps", "dijkstra"])
def test_bench_movingai_matches(tmp_path: Path, capsys: pytest.CaptureFixture[str], algorithm: str) -> None:
    path, scen = write_scenarios(tmp_path)
    code, res = run_json(capsys, ["bench", "movingai", str(path), str(scen), "--algorithm", algorithm, "--json"])
    assert code == 0
    assert res["queries"] == 4 and res["matched"] == 4 and res["invalid_paths"] == 0
    assert res["max_error"] < 1e-7
    assert main(["bench", "movingai", str(path), str(scen), "--limit", "2"]) == 0
    out = capsys.readouterr().out
    assert "queries:        2" in out and "matched:        2" in out


def test_bench_movingai_reports_mismatch(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path, scen = write_scenarios(tmp_path, lengths=[1.0, 1.0, 5.0, 1.0])
    code = main(["bench", "movingai", str(path), str(scen), "--json"])
    res = json.loads(capsys.readouterr().out)
    assert code == 1
    assert res["matched"] == 1  # (2, 0) -> (2, 5) is 5 straight steps
    assert res["worst"]["reason"].startswith("cost")


def test_bench_movingai_bad_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path, scen = write_scenarios(tmp_path)
    assert main(["bench", "movingai", str(path), str(tmp_path / "none.scen")]) == 2
    other = tmp_path / "other.map"
    other.write_text("type octile\nheight 2\nwidth 2\nmap\n..\n..\n")
    assert main(["bench", "movingai", str(other), str(scen)]) == 2
    assert "scenario for a 6×4 map" in capsys.readouterr().err
    assert main(["bench"]) == 2


def test_bench_movingai_reference_arena(refdata: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = refdata / "movingai"
    code, res = run_json(capsys, ["bench", "movingai", str(d / "arena.map"), str(d / "arena.map.scen"), "--json"])
    assert code == 0
    assert res["queries"] == res["matched"] == 130

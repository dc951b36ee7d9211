"""Published optimal lengths of every shared Moving AI map (a fixed-seed sample; the full scenario files run via
``mjnav bench movingai``): astar, dijkstra and jps match within 1e-4 with valid paths whose recomputed cost
equals the reported one. Data: N. Sturtevant, "Benchmarks for Grid-Based Pathfinding", IEEE TCIAIG 2012."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mjnav.mapping.movingai import read_movingai_map, read_movingai_scen
from mjnav.planning import check_path, path_cost, plan_grid

MAPS = [
    "arena",
    "den201d",
    "den312d",
    "Boston_0_256",
    "Paris_1_256",
    "maze512-1-0",
    "maze512-32-9",
    "random512-40-5",
]
SAMPLE = 20  # per map: 17 random scenarios and the 3 longest


@pytest.mark.e2e
@pytest.mark.parametrize("name", MAPS)
def test_sampled_scenarios_match_published_optimum(refdata: Path, name: str) -> None:
    mai = read_movingai_map(refdata / "movingai" / f"{name}.map")
    scen = read_movingai_scen(refdata / "movingai" / f"{name}.map.scen")
    rng = np.random.default_rng(2012)
    order = sorted(range(len(scen)), key=lambda i: scen[i].optimal_length)
    picked = set(order[-3:]) | {int(i) for i in rng.choice(len(scen), SAMPLE - 3, replace=False)}
    for i in sorted(picked):
        s = scen[i]
        for alg in ("jps", "astar", "dijkstra"):
            plan = plan_grid(mai.blocked, s.start, s.goal, algorithm=alg)
            assert abs(plan.cost - s.optimal_length) <= 1e-4, (name, i, alg, plan.cost, s.optimal_length)
            check_path(mai.blocked, plan.cells, start=s.start, goal=s.goal)
            assert path_cost(plan.cells) == pytest.approx(plan.cost, rel=1e-12)


def test_corner_cutting_changes_the_lengths(refdata: Path) -> None:
    """The published lengths assume no corner cutting: allowing it makes some paths shorter."""
    mai = read_movingai_map(refdata / "movingai" / "random512-40-5.map")
    scen = read_movingai_scen(refdata / "movingai" / "random512-40-5.map.scen")
    s = scen[len(scen) // 2]
    cut = plan_grid(mai.blocked, s.start, s.goal, corner_cutting=True)
    assert cut.cost < s.optimal_length - 1.0

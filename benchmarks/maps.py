"""Maps benchmark (issue 30): ``mjnav demo --world MAP`` over a collection of public maps, several seeds each.

Each run is the command a new user types: ``mjnav demo --world MAP --seed S --headless --json --rtf max`` (SLAM's
pose, an unknown map, the start and goal drawn from the seed: a goal 2 to 12 m away in the start's free region). The
maps: the Moving AI benchmark maps in ``../shared/refdata/movingai`` (Sturtevant 2012: game maps, city streets,
mazes, random obstacles; 0.5 m per cell, so a 512 x 512 map is a 256 m x 256 m world, except
:data:`RESOLUTION_M`) and ``wall``, a
40 m x 24 m room split by a 2 m thick wall with a single opening at its far end, start and goal on either side of it
(issue 30's livelock: written here as a ROS map and turned into a world with ``mjnav world from-map``; its start
and goal are fixed, so its seeds differ in their noise only).

Per run it prints the result (``reached``, ``failed``, ``timeout``, ``mislocalized``: reported reached more than
0.5 m from the goal's true position), collisions, sim time beside the optimal time (optimal length / v_max) and
their ratio, path length beside the optimal length, SLAM's ATE, the wall time from start-up to sim time starting,
and how long the command ran on after the robot arrived (the planner's "goal N reached" line to the process's end).

Goals (issue 30): every run reached with 0 collisions, the command ends <= 5 s after the arrival, and the wall map
reached within 2x the optimal time.

    python benchmarks/maps.py                                  # every map, seeds 0-2
    python benchmarks/maps.py --maps wall,arena --seeds 0      # a few
    python benchmarks/maps.py --json results.json              # also write the rows
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
#: The wall map: 5 cm cells, 40 m x 24 m.
WALL_RESOLUTION_M = 0.05
WALL_SIZE_M = (40.0, 24.0)
WALL_START = (20.0, 6.0, math.pi / 2)
WALL_GOAL = (20.0, 18.0)
#: Metres per Moving AI cell where the default 0.5 m does not fit the robot: maze512-1-0's corridors are one cell
#: wide, and the demo refuses a map with no free cell 0.5 m from the walls.
RESOLUTION_M = {"maze512-1-0": 1.0}


def refdata() -> Path:
    env = os.environ.get("MJNAV_REFDATA")
    return Path(env) if env else REPO.parent / "shared" / "refdata"


def write_wall_map(folder: Path) -> Path:
    """Write the wall map (PGM + YAML) into ``folder`` and turn it into a world; returns the world's MJCF."""
    res = WALL_RESOLUTION_M
    w, h = WALL_SIZE_M
    img = np.full((round(h / res), round(w / res)), 254, dtype=np.uint8)

    def box(x0: float, y0: float, x1: float, y1: float) -> None:
        rows = slice(img.shape[0] - round(y1 / res), img.shape[0] - round(y0 / res))  # row 0 is the top (max y)
        img[rows, round(x0 / res) : round(x1 / res)] = 0

    box(0.0, 0.0, w, 0.2)
    box(0.0, h - 0.2, w, h)
    box(0.0, 0.0, 0.2, h)
    box(w - 0.2, 0.0, w, h)
    box(0.0, 11.0, 36.5, 13.0)  # the 2 m thick wall; its one opening is x in [36.5, 38.5]
    box(38.5, 11.0, w, 13.0)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "wall.pgm").write_bytes(b"P5\n%d %d\n255\n" % (img.shape[1], img.shape[0]) + img.tobytes())
    (folder / "wall.yaml").write_text(
        f"image: wall.pgm\nresolution: {res}\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n",
        encoding="utf-8",
    )
    scene = folder / "wall.xml"
    subprocess.run(
        [sys.executable, "-m", "mjnav", "world", "from-map", str(folder / "wall.yaml"), "--out", str(scene),
         "--start", *map(str, WALL_START), "--goal", *map(str, WALL_GOAL)],
        check=True, cwd=REPO, capture_output=True,
    )  # fmt: skip
    return scene


def run_demo(world: str, seed: int, timeout_s: float, resolution_m: float | None = None) -> dict[str, Any]:
    """One ``mjnav demo`` run: its summary plus the wall times this benchmark measures."""
    cmd = [sys.executable, "-m", "mjnav", "demo", "--world", world, "--seed", str(seed), "--headless", "--json",
           "--rtf", "max", "--timeout", str(timeout_s)]  # fmt: skip
    if resolution_m is not None:
        cmd += ["--map-resolution", str(resolution_m)]
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert proc.stdout is not None
    started = arrived = math.nan
    last = ""
    for line in proc.stdout:
        now = time.monotonic() - t0
        if math.isnan(started) and "sim time starts" in line:
            started = now
        if math.isnan(arrived) and "mjnav.planner: goal" in line and line.rstrip().endswith("reached"):
            arrived = now
        if line.startswith("{"):
            last = line
    proc.wait()
    ended = time.monotonic() - t0
    summary: dict[str, Any] = json.loads(last) if last else {"reached": False, "error": f"exit {proc.returncode}"}
    summary.update(startup_s=started, after_arrival_s=ended - arrived if math.isfinite(arrived) else math.nan)
    return summary


def row(name: str, seed: int, s: dict[str, Any]) -> dict[str, Any]:
    goal = (s.get("goals") or [{}])[0]
    v = s.get("v_max_mps") or math.nan
    optimal = s.get("optimal_length_m", math.nan)
    optimal_time = optimal / v if v and v == v else math.nan
    return {
        "map": name,
        "seed": seed,
        "result": goal.get("result", s.get("error", "?")),
        "collisions": s.get("collisions"),
        "time_s": s.get("time_s", math.nan),
        "optimal_time_s": optimal_time,
        "time_ratio": s.get("time_s", math.nan) / optimal_time if optimal_time == optimal_time else math.nan,
        "path_length_m": s.get("path_length_m", math.nan),
        "optimal_length_m": optimal,
        "ate_rms_m": s.get("ate_rms_m"),
        "startup_s": s["startup_s"],
        "after_arrival_s": s["after_arrival_s"],
        "true_distance_m": goal.get("true_distance_m"),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--maps", default="", help="comma-separated names (wall, or Moving AI map names); default all")
    parser.add_argument("--seeds", default="0,1,2", help="comma-separated seeds (default 0,1,2)")
    parser.add_argument("--timeout", type=float, default=240.0, help="sim seconds per goal (default 240)")
    parser.add_argument("--json", type=Path, help="also write the rows to this JSON file")
    args = parser.parse_args()
    movingai = sorted(refdata().joinpath("movingai").glob("*.map"))
    if not movingai:
        print(f"maps: no Moving AI maps in {refdata() / 'movingai'} (set MJNAV_REFDATA)", file=sys.stderr)
    maps = {"wall": None, **{p.stem: p for p in movingai}}
    chosen = [m for m in args.maps.split(",") if m] or list(maps)
    unknown = [m for m in chosen if m not in maps]
    if unknown:
        parser.error(f"unknown map(s) {unknown}; choose from {sorted(maps)}")
    seeds = [int(s) for s in args.seeds.split(",")]
    rows = []
    with tempfile.TemporaryDirectory(prefix="mjnav-maps-") as tmp:
        for name in chosen:
            world = str(write_wall_map(Path(tmp) / "wall")) if name == "wall" else str(maps[name])
            for seed in seeds:
                r = row(name, seed, run_demo(world, seed, args.timeout, RESOLUTION_M.get(name)))
                rows.append(r)
                print(
                    f"{r['map']:>16} seed {r['seed']}: {r['result']:<12} collisions {r['collisions']}  "
                    f"time {r['time_s']:.1f} s / optimal {r['optimal_time_s']:.1f} s (x{r['time_ratio']:.2f})  "
                    f"path {r['path_length_m']:.1f} / {r['optimal_length_m']:.1f} m  ATE {r['ate_rms_m']}  "
                    f"start-up {r['startup_s']:.1f} s  after arrival {r['after_arrival_s']:.1f} s",
                    flush=True,
                )
    reached = sum(r["result"] == "reached" for r in rows)
    late = [r for r in rows if not r["after_arrival_s"] <= 5.0 and r["result"] == "reached"]
    print(
        f"reached {reached} of {len(rows)}; collisions {sum(r['collisions'] or 0 for r in rows)}; "
        f"runs ending more than 5 s after the arrival: {len(late)}"
    )
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1), encoding="utf-8")
    return 0 if reached == len(rows) and not late else 1


if __name__ == "__main__":
    sys.exit(main())

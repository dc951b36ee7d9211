"""``mjnav world``: list the bundled worlds, or build a world from an occupancy map (``from-map``)."""

from __future__ import annotations

import argparse
import json
import math
import sys


def _pose(values: list[float] | None, name: str) -> tuple[float, float, float] | None:
    if values is None:
        return None
    if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"{name} needs X Y [YAW] (metres, radians), got {values}")
    return (values[0], values[1], values[2] if len(values) == 3 else 0.0)


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``world`` sub-command with ``list`` and ``from-map``."""
    p = subparsers.add_parser(
        "world",
        help="list the bundled worlds or build a world from a map",
        description="Inspect the bundled worlds or turn an occupancy map into a MuJoCo world.",
    )
    sub = p.add_subparsers(dest="world_command", metavar="ACTION")

    def _help(args: argparse.Namespace) -> int:
        p.print_help()
        return 2

    p.set_defaults(func=_help)

    ls = sub.add_parser("list", help="list the bundled worlds with their start, goal and size")
    ls.add_argument("--json", action="store_true", help="one JSON object per line instead of a table")
    ls.set_defaults(func=run_list)

    fm = sub.add_parser(
        "from-map",
        help="build a world from a ROS map (.yaml + PGM, PNG, BMP, JPEG, TIFF, ... image) or a Moving AI map (.map)",
        description=(
            "Read an occupancy grid, merge its occupied cells into few boxes (greedy rectangles), add a "
            "floor and the robot, and write one self-contained MJCF scene. ROS maps keep their resolution "
            "and origin (the world frame is the map frame); Moving AI cells become --resolution metres with "
            "row 0 at the top (highest y). Start and goal are picked automatically unless given, in known free "
            "space (a saved map's unknown outside is never picked). mjnav demo --world MAP does this itself, with "
            "a start and goal drawn from --seed."
        ),
    )
    fm.add_argument("map", metavar="MAP", help="ROS map YAML (with its image) or Moving AI .map file")
    fm.add_argument("--out", required=True, metavar="SCENE.xml", help="MJCF file to write")
    fm.add_argument("--resolution", type=float, default=None, help="Moving AI maps: cell size in metres (default 0.5)")
    fm.add_argument("--wall-height", type=float, default=0.5, help="wall height in metres (default 0.5)")
    fm.add_argument("--no-border", action="store_true", help="do not close the map with a one-cell wall ring")
    fm.add_argument("--unknown-occupied", action="store_true", help="ROS maps: turn unknown cells into walls as well")
    fm.add_argument("--start", nargs="+", type=float, metavar="X Y [YAW]", help="robot start pose (map frame)")
    fm.add_argument("--goal", nargs="+", type=float, metavar="X Y [YAW]", help="default goal pose (map frame)")
    fm.add_argument(
        "--clearance",
        type=float,
        default=0.35,
        help="free distance to walls for automatically chosen start/goal cells, metres (default 0.35)",
    )
    fm.set_defaults(func=run_from_map)


def run_list(args: argparse.Namespace) -> int:
    """Print every bundled world with its start, goal and bounds."""
    from mjnav.sim.errors import SimError
    from mjnav.sim.worlds import available_worlds, world_info

    for name in available_worlds():
        try:
            info = world_info(name)
        except SimError as exc:
            print(f"{name}: error: {exc}", file=sys.stderr)
            return 1
        goal = None if info.goal is None else [info.goal.x, info.goal.y, info.goal.theta]
        if args.json:
            record = {
                "name": name,
                "path": str(info.path),
                "start": [info.start.x, info.start.y, info.start.theta],
                "goal": goal,
                "bounds_m": info.bounds_m,
            }
            print(json.dumps(record))
        else:
            g = "none" if goal is None else f"({goal[0]:.2f}, {goal[1]:.2f}, {goal[2]:.2f})"
            b = "open"
            if info.bounds_m is not None:
                x0, y0, x1, y1 = info.bounds_m
                b = f"x [{x0:.1f}, {x1:.1f}] y [{y0:.1f}, {y1:.1f}]"
            s = info.start
            print(f"{name:10s} start ({s.x:.2f}, {s.y:.2f}, {s.theta:.2f})  goal {g}  {b}")
    return 0


def run_from_map(args: argparse.Namespace) -> int:
    """Convert the map; exit code 0, 2 for a bad argument or map."""
    from mjnav.geometry import Pose2D
    from mjnav.sim.errors import MapConversionError
    from mjnav.sim.worldgen import write_scene_from_map

    try:
        start = _pose(args.start, "--start")
        goal = _pose(args.goal, "--goal")
        summary = write_scene_from_map(
            args.map,
            args.out,
            resolution_m=args.resolution,
            wall_height_m=args.wall_height,
            border=not args.no_border,
            unknown_is_occupied=args.unknown_occupied,
            start=None if start is None else Pose2D(*start),
            goal=None if goal is None else Pose2D(*goal),
            clearance_m=args.clearance,
        )
    except (argparse.ArgumentTypeError, MapConversionError) as exc:
        print(f"mjnav world from-map: error: {exc}", file=sys.stderr)
        return 2
    s, g = summary.start, summary.goal
    print(
        f"wrote {summary.path}: {summary.occupied_cells} occupied cells -> {summary.boxes} boxes; "
        f"start ({s.x:.2f}, {s.y:.2f}, {s.theta:.2f}), goal ({g.x:.2f}, {g.y:.2f}, {g.theta:.2f})"
    )
    return 0

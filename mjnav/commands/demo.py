"""``mjnav demo``: the whole stack on an embedded router, a navigation mission, and its summary."""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from mjnav import jsonsafe
from mjnav.commands._args import add_packing_argument, add_port_argument
from mjnav.commands._launch import run_beside_launcher, write_summary

#: The demo's mission client: a lockstep participant, so goals leave at the same sim time in every run.
MISSION = "mission"


def register(sub: Any) -> None:
    """Add the ``demo`` command."""
    p = sub.add_parser(
        "demo",
        help="run the navigation mission end to end and print its summary",
        description=(
            "Start a Zenoh router and every service of the stack (sim, mapper, planner, smoother, controller, …), "
            "send the goal(s), and end with a summary. The robot starts with an unknown map and explores (--known-map: "
            "it is given the map: the ROS map file itself, or the world's true static map). Exit code 0 only when "
            "every goal was reached: the planner said so and the robot's true position was within 0.5 m of the goal "
            "(farther, the goal ends 'mislocalized'). With --json the last stdout line is the summary as JSON: "
            "reached, goals (each with its result and true_distance_m), collisions, "
            "time_s (sim), path_length_m (driven), optimal_length_m (shortest collision-free path for the robot's "
            "radius on the true map), v_max_mps, min_clearance_m (smallest distance between the robot's footprint, "
            "the disc of its radius, and the world's static obstacles at the true poses; negative = overlap, "
            "counted in collisions as well as the sim's contacts), seed, lockstep, final_pose ([x, y, yaw] true pose "
            "in map at the end), wall_s (start-up to the end) and achieved_rtf (sim s per wall s while the robot "
            "drove). The stack runs in lockstep by default: sim time advances only when every service has finished "
            "the step that is due, so the same --seed gives the same run to the last bit on a busy or an idle "
            "machine. Any map runs: --world MAP.yaml (a ROS map, e.g. one saved with 'mjnav map save') or MAP.map "
            "(Moving AI) is turned into a world first (as 'mjnav world from-map'; written to DIR/world.xml with "
            "--out), with a start and a goal drawn from --seed: a random known-free cell at least 0.5 m from walls "
            "and unknown space, and a goal 2 to 12 m away in the same connected free region, so it is reachable. "
            "A scene without a goal (and no --goal) gets its goal drawn the same way from its start."
        ),
        epilog="Example: mjnav demo --world rooms --rtf 4 --out runs/first --record",
    )
    p.add_argument(
        "--world",
        default="rooms",
        help="empty, rooms, maze, warehouse, an MJCF path, a ROS map .yaml or a Moving AI .map (default rooms)",
    )
    p.add_argument(
        "--map-resolution",
        type=float,
        default=None,
        metavar="M",
        help="--world MAP.map: metres per Moving AI cell (default 0.5)",
    )
    goals = p.add_mutually_exclusive_group()
    goals.add_argument(
        "--goal",
        metavar="X,Y",
        help="goal in the map frame, metres; negative values work (--goal -3,2) (default: the world's goal)",
    )
    goals.add_argument("--goals", metavar="FILE", help='JSON list of goals: [[x, y], …] or [{"x": …, "y": …}, …]')
    p.add_argument(
        "--rtf",
        default="4",
        metavar="FACTOR|max",
        help="at most FACTOR x real time, or max: as fast as the services allow (default 4)",
    )
    p.add_argument(
        "--seed", type=int, default=0, help="seed of the sim's noise and every service's randomness (default 0)"
    )
    p.add_argument(
        "--free-running",
        action="store_true",
        help="let the sim run on wall time without waiting for the services (like hardware; results then depend "
        "on the machine's load)",
    )
    p.add_argument(
        "--record",
        nargs="?",
        const="",
        metavar="MP4",
        help="record a video (default file: DIR/video.mp4 with --out)",
    )
    p.add_argument("--headless", action="store_true", help="open no browser or window")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on the last stdout line")
    p.add_argument(
        "--out",
        metavar="DIR",
        help="write summary.json, the final map (map.yaml + map.pgm), run.png (map, true and estimated trajectories, "
        "plans, path, goals), speed.png (commanded and measured speed over sim time), scene.html and the video here",
    )
    p.add_argument(
        "--timeout", type=float, default=240.0, metavar="S", help="sim seconds allowed per goal (default 240)"
    )
    p.add_argument(
        "--known-map",
        action="store_true",
        help="give the robot the map at the start (the mapper's prior_map): a --world MAP.yaml as it is, any other "
        "world as its true static map at the mapper's resolution; default: the robot starts on an unknown map",
    )
    add_port_argument(p, 7447)
    p.add_argument("--stack", metavar="FILE", help="stack file (default services/stack.toml)")
    add_packing_argument(p)
    p.add_argument(
        "--secure",
        metavar="DIR",
        help="mutual TLS and access control as 'mjnav up --secure DIR'; the mission client joins as 'operator'",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SERVICE.KEY=VALUE",
        help="override a service's config value, e.g. --set planner.algorithm=dijkstra; repeatable",
    )
    p.add_argument("--log-level", default="INFO", help="log level of the services (default INFO)")
    p.set_defaults(func=run)


def _parse_goals(args: argparse.Namespace, default: Any) -> list[tuple[float, float]]:
    if args.goal:
        parts = args.goal.split(",")
        if len(parts) != 2:
            raise ValueError(f"--goal must be X,Y, got {args.goal!r}")
        return [(float(parts[0]), float(parts[1]))]
    if args.goals:
        data = json.loads(Path(args.goals).read_text(encoding="utf-8"))
        if not isinstance(data, list) or not data:
            raise ValueError(f"{args.goals}: expected a non-empty JSON list of goals")
        out = []
        for item in data:
            x, y = (item["x"], item["y"]) if isinstance(item, dict) else (item[0], item[1])
            out.append((float(x), float(y)))
        return out
    if default is None:
        raise ValueError("this world defines no default goal: give --goal X,Y")
    return [(default.x, default.y)]


#: World arguments that are map files, turned into a world before the run.
MAP_SUFFIXES = (".yaml", ".yml", ".map")
#: Distance (m) the automatically chosen start and goal keep from walls and unknown space.
AUTO_CLEARANCE_M = 0.5
#: Straight-line distance band (m) between the automatically chosen start and goal.
AUTO_GOAL_DISTANCE_M = (2.0, 12.0)


def known_map(world_arg: str, scene: Path, folder: Path, resolution_m: float) -> Path:
    """The ROS map ``--known-map`` gives the robot: a ``--world MAP.yaml`` itself (unknown cells and all), for any
    other world its true static map at ``resolution_m`` (occupied or free), written to ``folder/known_map.yaml``."""
    import numpy as np

    from mjnav.mapping import write_ros_map
    from mjnav.sim.truth import true_grid

    if Path(world_arg).suffix.lower() in (".yaml", ".yml"):
        return Path(world_arg)
    occupied, frame = true_grid(scene, resolution_m=resolution_m)
    path = folder / "known_map.yaml"
    write_ros_map(path, np.where(occupied, 100, 0).astype(np.int8), frame.resolution_m, frame.origin_m)
    return path


def world_from_map(map_path: str, scene: Path, seed: int, resolution_m: float | None) -> Path:
    """Write the world of a ROS or Moving AI map to ``scene`` with a start and goal drawn from ``seed``.

    Raises:
        MapConversionError: unreadable map, or no room for the robot.
    """
    import numpy as np

    from mjnav.sim.worldgen import write_scene_from_map

    lo, hi = AUTO_GOAL_DISTANCE_M
    summary = write_scene_from_map(
        map_path,
        scene,
        resolution_m=resolution_m,
        clearance_m=AUTO_CLEARANCE_M,
        rng=np.random.default_rng(seed),
        min_distance_m=lo,
        max_distance_m=hi,
    )
    return summary.path


def reachable_goal(info: Any, seed: int) -> Any:
    """A goal drawn from ``seed`` that the robot can reach from the world's start on its true static map.

    Raises:
        MapConversionError: no free cell with the clearance is reachable from the start.
    """
    import numpy as np

    from mjnav.sim.truth import true_grid
    from mjnav.sim.worldgen import GridMap, choose_goal

    lo, hi = AUTO_GOAL_DISTANCE_M
    occupied, frame = true_grid(info.path, border_m=1.0 if info.bounds_m is not None else hi)  # open world: room
    grid = GridMap(occupied, frame.resolution_m, (frame.origin_m[0], frame.origin_m[1], 0.0), info.name)
    rng = np.random.default_rng(seed)
    return choose_goal(grid, info.start, AUTO_CLEARANCE_M, rng, min_distance_m=lo, max_distance_m=hi)


def run(args: argparse.Namespace) -> int:
    """``mjnav demo``."""
    from mjnav.runtime.config import ConfigError
    from mjnav.runtime.logs import setup_logging
    from mjnav.runtime.stack import add_service_overrides, load_stack, port_overrides
    from mjnav.sim.errors import SimError
    from mjnav.sim.truth import compiled_world

    setup_logging(args.log_level)
    scratch: tempfile.TemporaryDirectory[str] | None = None
    try:
        out = Path(args.out) if args.out else None
        if out is not None:
            out.mkdir(parents=True, exist_ok=True)
        world: str | Path = args.world
        if Path(args.world).suffix.lower() in MAP_SUFFIXES:
            folder = out
            if folder is None:
                scratch = tempfile.TemporaryDirectory(prefix="mjnav-demo-")
                folder = Path(scratch.name)
            world = world_from_map(args.world, folder / "world.xml", args.seed, args.map_resolution)
        elif args.map_resolution is not None:
            raise ValueError("--map-resolution applies to a Moving AI --world MAP.map only")
        info = compiled_world(world)[0]  # compiled once: the scoring uses the same model
        default_goal = info.goal
        if default_goal is None and not (args.goal or args.goals):
            default_goal = reachable_goal(info, args.seed)
        goals = _parse_goals(args, default_goal)
        if any(not (math.isfinite(x) and math.isfinite(y)) for x, y in goals):
            raise ValueError("goals must be finite numbers")
        rtf = 0.0 if args.rtf.strip().lower() == "max" else float(args.rtf)
        if not (math.isfinite(rtf) and rtf >= 0):
            raise ValueError(f"--rtf must be a positive number or 'max', got {args.rtf!r}")
        stack = load_stack(args.stack)
        overrides = port_overrides(stack.select(None), args.port) if args.port is not None else {}
        overrides["sim"] = [f"world={json.dumps(str(info.path))}", f"rtf={rtf}"]
        if args.record is not None:
            video = Path(args.record) if args.record else (out / "video.mp4" if out else None)
            if video is None:
                raise ValueError("--record without a file needs --out DIR")
            overrides["sim"].append(f"record_path={json.dumps(str(video.resolve()))}")
        if out is not None and "mapper" in stack.names():
            overrides.setdefault("mapper", []).append(f"save_path={json.dumps(str((out / 'map.yaml').resolve()))}")
        if out is not None and "viz" in stack.names():
            overrides.setdefault("viz", []).append(f"static_html={json.dumps(str((out / 'scene.html').resolve()))}")
        if args.known_map:
            if "mapper" not in stack.names():
                raise ValueError("--known-map gives the map to the mapper, and this stack has none")
            folder = out
            if folder is None:
                scratch = scratch or tempfile.TemporaryDirectory(prefix="mjnav-demo-")
                folder = Path(scratch.name)
            resolution = float(stack.get("mapper").load_config().resolution_m)
            prior = known_map(args.world, info.path, folder, resolution)
            overrides.setdefault("mapper", []).append(f"prior_map={json.dumps(str(prior.resolve()))}")
        add_service_overrides(stack, args.set, overrides)
    except (ConfigError, ValueError, OSError, LookupError, SimError) as exc:  # LookupError: an unknown world
        print(f"mjnav demo: {exc}", file=sys.stderr)
        if scratch is not None:
            scratch.cleanup()
        return 2
    try:
        return _run(args, stack, overrides, info, goals, rtf, out)
    finally:
        if scratch is not None:
            scratch.cleanup()


def _run(
    args: argparse.Namespace,
    stack: Any,
    overrides: dict[str, list[str]],
    info: Any,
    goals: list[tuple[float, float]],
    rtf: float,
    out: Path | None,
) -> int:
    from mjnav.bus import BusConfig, BusConfigError
    from mjnav.bus.acl import AclError
    from mjnav.bus.config import tls_files
    from mjnav.msgs.topics import OPERATOR
    from mjnav.runtime.config import ConfigError
    from mjnav.runtime.launcher import Launcher
    from mjnav.runtime.trace import TraceRecorder

    wall0 = time.monotonic()
    try:
        launcher = Launcher(
            stack,
            port=7447 if args.port is None else args.port,
            overrides=overrides,
            out=sys.stderr if args.json else sys.stdout,
            extra_env={"MJNAV_HEADLESS": "1"} if args.headless else None,
            lockstep=not args.free_running,
            extra_participants=[MISSION],
            seed=args.seed,
            secure=args.secure,
            packed=not args.process_per_service,
        )
        launcher.check()
        bus_config = BusConfig(mode="client", connect=(launcher.endpoint,))
        if args.secure:
            bus_config = BusConfig(
                mode="client", connect=(launcher.endpoint,), listen=(), **tls_files(args.secure, OPERATOR)
            )
    except (ConfigError, BusConfigError, AclError, ValueError) as exc:
        print(f"mjnav demo: {exc}", file=sys.stderr)
        return 2

    def client(bus: Any) -> tuple[Any, Any]:
        recorder = TraceRecorder(bus) if out is not None else None
        summary = _mission(bus, stack.names(), goals, info, args.timeout, rtf)
        summary.seed = args.seed
        summary.lockstep = not args.free_running
        summary.known_map = args.known_map
        summary.wall_s = time.monotonic() - wall0
        return summary, (recorder.trace() if recorder is not None else None)

    result = run_beside_launcher(launcher, bus_config, stack.namespace, client, "demo")
    if result is None:
        return 1
    summary, trace = result
    data = summary.to_dict()
    write_summary(data, out)
    if out is not None and trace is not None:
        _plots(trace, goals, Path(args.world).stem, out)  # the map's name, not world.xml's
    _print_summary(data, out)
    if args.json:
        print(jsonsafe.dumps(data))
    return 0 if summary.reached else 1


def _mission(
    bus: Any, services: list[str], goals: list[tuple[float, float]], info: Any, timeout_s: float, rtf: float
) -> Any:
    from mjnav.bus import NoReply, wait_until
    from mjnav.runtime.mission import MissionClient, MissionSummary

    log = sys.stderr
    from mjnav.sim.truth import FootprintClearance

    footprint = FootprintClearance(info.path)  # scoring only: the true static map
    client = MissionClient(bus, name=MISSION, clearance=footprint.clearance_m)
    if not wait_until(lambda: set(services) <= set(bus.alive_services(0.5)), 180.0):
        raise RuntimeError(f"services did not come up within 180 s (alive: {bus.alive_services(0.5)})")
    v_max = math.nan
    pose_source = ""
    try:
        config = json.loads(bus.call("config", service="controller", timeout_s=5.0).data)
        v_max = float(config.get("max_speed_mps", math.nan))
        pose_source = str(config.get("pose_source", ""))
    except (NoReply, ValueError, KeyError) as exc:
        print(f"mjnav demo: could not read the controller's settings: {exc}", file=log)
    wall_limit = len(goals) * (3 * timeout_s / (rtf if rtf > 0 else 10.0) + 60.0)
    print(f"mjnav demo: goals {', '.join(f'({x:.2f}, {y:.2f})' for x, y in goals)}", file=log)
    outcomes = client.run_goals(goals, timeout_s=timeout_s, wall_timeout_s=wall_limit)
    for o in outcomes:
        print(
            f"mjnav demo: goal ({o.goal[0]:.2f}, {o.goal[1]:.2f}) {o.result} after {o.time_s:.2f} s sim {o.error_text}",
            file=log,
        )
    optimal = _optimal_length(info, outcomes)
    pose = client.final_pose
    loops: int | None = None
    if "slam" in services:
        try:
            loops = int(json.loads(bus.call("slam_info", timeout_s=5.0).data)["loop_closures"])
        except (NoReply, ValueError, KeyError) as exc:
            print(f"mjnav demo: could not read SLAM's statistics: {exc}", file=log)
    accuracy = _map_accuracy(info, client.final_map())  # frozen at the end: sim time may go on
    return MissionSummary(
        reached=len(outcomes) == len(goals) and all(o.result == "reached" for o in outcomes),
        collisions=max(client.collisions(), client.overlaps()),  # an overlap counts even without a contact
        time_s=sum(o.time_s for o in outcomes),
        path_length_m=sum(o.path_length_m for o in outcomes),
        optimal_length_m=optimal,
        v_max_mps=v_max,
        min_clearance_m=client.min_clearance_m(),
        goals=[o.__dict__ for o in outcomes],
        final_pose=None if pose is None else [pose.x, pose.y, pose.theta],
        achieved_rtf=client.achieved_rtf,
        pose_source=pose_source,
        ate_rms_m=client.ate_rms_m(),
        loop_closures=loops,
        map_accuracy=accuracy,
    )


def _map_accuracy(info: Any, msg: Any) -> list[float] | None:
    """[recall, precision] of the newest ``map`` against the world's true obstacles (None without a map)."""
    from mjnav.msgs import ros
    from mjnav.sim.truth import map_accuracy

    if msg is None:
        return None
    cells, frame = ros.grid_frame(msg)
    return list(map_accuracy(info.path, cells, frame))


def _optimal_length(info: Any, outcomes: list[Any]) -> float:
    """Sum over the goals of the shortest collision-free path on the true map (NaN when it cannot be computed)."""
    from mjnav.planning import PlanningError
    from mjnav.sim.truth import shortest_length_m

    try:
        return sum(shortest_length_m(info.path, o.start, o.goal) for o in outcomes)
    except PlanningError:
        return math.nan


def _plots(trace: Any, goals: list[tuple[float, float]], world: str, out: Path) -> None:
    """Write ``run.png`` and ``speed.png`` (matplotlib, the ``plot`` extra; without it, say so and go on)."""
    try:
        from mjnav.viz.plots import plot_run, plot_speed
    except ImportError as exc:
        print(f"mjnav demo: no plots ({exc}); install the plot extra: pip install 'mjnav[plot]'", file=sys.stderr)
        return
    plot_run(trace, out / "run.png", goals, title=f"{world}: true (solid) and estimated (dashed) trajectories")
    plot_speed(trace, out / "speed.png", title=f"{world}: speed")


def _print_summary(data: dict[str, Any], out: Path | None) -> None:
    lines = [
        f"reached: {data['reached']}   collisions: {data['collisions']}   "
        f"map: {'known (--known-map)' if data['known_map'] else 'unknown at the start, explored'}",
        f"time: {data['time_s']} s sim   driven: {data['path_length_m']} m   optimal: {data['optimal_length_m']} m",
        f"v_max: {data['v_max_mps']} m/s   min clearance: {data['min_clearance_m']} m",
        f"pose source: {data['pose_source']}   ATE: {data['ate_rms_m']} m   loop closures: {data['loop_closures']}"
        f"   map accuracy (recall, precision): {data['map_accuracy']}",
    ]
    if out is not None:
        names = ("run.png", "speed.png", "video.mp4", "scene.html", "world.xml", "known_map.yaml")
        extra = "".join(f", {name}" for name in names if (out / name).exists())
        lines.append(f"files in {out}: summary.json, map.yaml + map.pgm{extra}")
    print("\n".join(lines), file=sys.stderr)

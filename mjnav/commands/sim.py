"""``mjnav sim``: run the MuJoCo simulation of a world.

The loop is :class:`mjnav.sim.SimRunner`; everything periodic is a *hook* on it. :func:`make_hooks` returns
the hooks of this command (constant command, recording); the bus-backed sim service adds its publishers and
subscribers the same way (see :func:`run`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

from mjnav.commands._args import non_negative_float

if TYPE_CHECKING:
    from mjnav.sim import Simulator
    from mjnav.sim.runner import Hook


def parse_rtf(text: str) -> float | None:
    """``--rtf`` value: ``max`` (as fast as possible → None) or a positive real-time factor."""
    if text.strip().lower() in ("max", "inf", "none"):
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number or 'max', got {text!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"expected a positive number or 'max', got {text!r}")
    return value


def add_world_arguments(parser: argparse.ArgumentParser) -> None:
    """Options shared by ``sim`` and ``record``: world, seed and an optional constant command."""
    parser.add_argument(
        "--world",
        default="rooms",
        help="bundled world (empty, rooms, maze, warehouse) or path to an MJCF file with the robot (default: rooms)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of all sensor noise and odometry drift (default 0)")


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``sim`` sub-command."""
    p = subparsers.add_parser(
        "sim",
        help="run the MuJoCo simulation of a world",
        description=(
            "Step the diff-drive robot in a MuJoCo world at 2 ms with its lidar (10 Hz, 360 beams), wheel "
            "encoders, odometry and IMU. Prints the sim time and the wall time of the stepping loop."
        ),
    )
    add_world_arguments(p)
    p.add_argument("--duration", type=non_negative_float, default=10.0, help="sim seconds to run (default 10)")
    p.add_argument(
        "--rtf",
        type=parse_rtf,
        default=1.0,
        metavar="max|FACTOR",
        help="real-time factor: 1 = real time (default), 2 = twice as fast, 'max' = as fast as possible",
    )
    p.add_argument(
        "--no-bus",
        action="store_true",
        help="run the simulation alone; by default it publishes clock, scan, odom, imu, joint_states, tf and "
        "ground_truth on Zenoh and obeys cmd_vel, like the sim service",
    )
    p.add_argument("--ns", default="robot0", help="robot namespace on the bus (default robot0)")
    p.add_argument(
        "--json",
        action="store_true",
        help='print a JSON summary as the last stdout line: {"sim_time_s": ..., "wall_s": ..., ...}',
    )
    p.add_argument(
        "--cmd",
        nargs=2,
        type=float,
        metavar=("V", "OMEGA"),
        default=None,
        help="drive with a constant command (m/s, rad/s), re-sent at 10 Hz as a controller would",
    )
    p.add_argument(
        "--lidar-beams", type=int, default=None, help="lidar beams per scan (default: the robot model's, 360)"
    )
    p.add_argument(
        "--lidar-rate", type=float, default=None, help="lidar scans per sim second (default: the robot model's, 10)"
    )
    p.add_argument("--record", metavar="MP4", default=None, help="also record an H.264 video to this file")
    p.add_argument("--record-fps", type=float, default=30.0, help="video frame rate (default 30)")
    p.add_argument("--camera", default="top", help="video camera: top, follow or a model camera (default top)")
    from mjnav.bus import add_bus_arguments

    add_bus_arguments(p)
    p.set_defaults(func=run)


def build_simulator(args: argparse.Namespace) -> Simulator:
    """The :class:`~mjnav.sim.Simulator` described by the parsed arguments."""
    from dataclasses import replace

    from mjnav.sim import Simulator

    sim = Simulator(args.world, seed=args.seed)
    changes = {
        name: value
        for name, value in (("num_beams", args.lidar_beams), ("rate_hz", args.lidar_rate))
        if value is not None
    }
    if not changes or sim.lidar_config is None:
        return sim
    return Simulator(args.world, seed=args.seed, lidar=replace(sim.lidar_config, **changes))


def command_hook(v_mps: float, omega_radps: float) -> Callable[[Simulator], None]:
    """A hook that (re-)sends a constant command, as a controller would (keeps the watchdog fed)."""

    def hook(sim: Simulator) -> None:
        sim.set_command(v_mps, omega_radps)

    return hook


def make_hooks(args: argparse.Namespace, sim: Simulator) -> list[tuple[Hook, float | None]]:
    """Hooks (callable, period in sim seconds or None for every step) this command runs besides recording."""
    hooks: list[tuple[Hook, float | None]] = []
    if args.cmd is not None:
        hooks.append((command_hook(float(args.cmd[0]), float(args.cmd[1])), 0.1))
    return hooks


def run(args: argparse.Namespace) -> int:
    """Run the simulation; exit code 0, 2 for a bad world or argument, 1 for another simulation error."""
    from mjnav.bus import Bus, BusConfigError, bus_config_from_args
    from mjnav.services.sim import SimBridge, SimConfig
    from mjnav.sim import Recorder, SimRunner
    from mjnav.sim.errors import InvalidCommandError, ModelLoadError, SimError, UnknownWorldError

    bus = None
    try:
        sim = build_simulator(args)
        runner = SimRunner(sim, rtf=args.rtf)
        for hook, period in make_hooks(args, sim):
            runner.add_hook(hook, period)
        if not args.no_bus:
            bus = Bus.open(bus_config_from_args(args), args.ns)
            config = SimConfig(world=args.world, seed=args.seed)
            bridge = SimBridge(sim, bus, config)
            bridge.attach(runner)
        recorder = None
        if args.record:
            recorder = Recorder(
                sim.model,
                sim.data,
                args.record,
                fps=args.record_fps,
                camera=args.camera,
                track_body=sim.robot.root_body,
            )
            recorder.add_to(runner)
        try:
            stats = runner.run(args.duration)
        finally:
            if recorder is not None:
                recorder.close()
    except (UnknownWorldError, ModelLoadError, InvalidCommandError, BusConfigError, ValueError) as exc:
        print(f"mjnav sim: error: {exc}", file=sys.stderr)
        return 2
    except SimError as exc:
        print(f"mjnav sim: error: {exc}", file=sys.stderr)
        return 1
    finally:
        if bus is not None:
            bus.close()
    pose = sim.ground_truth_pose()
    rtf = stats.real_time_factor
    print(
        f"world {sim.world.name}: {stats.sim_time_s:.3f} s sim in {stats.wall_s:.3f} s wall "
        f"({rtf:.1f}x real time), {stats.steps} steps, {sim.collisions} collisions, "
        f"robot at ({pose.x:.2f}, {pose.y:.2f}, {pose.theta:.2f})"
    )
    if recorder is not None:
        print(f"recorded {recorder.frames} frames to {recorder.path} ({recorder.render_fps:.0f} frames/s rendered)")
    if args.json:
        summary = {
            "sim_time_s": round(stats.sim_time_s, 6),
            "wall_s": round(stats.wall_s, 6),
            "real_time_factor": round(rtf, 3) if math.isfinite(rtf) else None,
            "steps": stats.steps,
            "world": sim.world.name,
            "collisions": sim.collisions,
        }
        print(json.dumps(summary))
    return 0

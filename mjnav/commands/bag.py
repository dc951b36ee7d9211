"""``mjnav bag record|play|info``: MCAP recordings of the bus (ROS 2 profile, readable by Foxglove)."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from pathlib import Path
from types import FrameType
from typing import Any


def register(sub: Any) -> None:
    """Add ``bag`` with its ``record``, ``play`` and ``info`` sub-commands."""
    from mjnav.bus import add_bus_arguments

    bag = sub.add_parser(
        "bag",
        help="record, replay and inspect MCAP bags",
        description=(
            "MCAP bags of the bus in the ROS 2 profile: schemas are the full .msg definitions (encoding ros2msg), "
            "messages are the CDR payloads as sent (encoding cdr), topics are /<namespace>/<topic>. Foxglove, "
            "ros2 bag (MCAP plugin) and mcap_ros2.reader open them."
        ),
    )
    bag_sub = bag.add_subparsers(dest="bag_command", metavar="SUBCOMMAND")
    bag.set_defaults(func=lambda _args: _help(bag))

    rec = bag_sub.add_parser(
        "record",
        help="record keys to an MCAP file",
        description=(
            "Subscribe to keys (default: every key of the namespace) and write each message to OUT with its ROS 2 "
            "schema until --duration passes or Ctrl-C. Payloads of unknown keys, other encodings or that do not "
            "decode are skipped and counted."
        ),
        epilog="Example: mjnav bag record --connect tcp/127.0.0.1:7447 --duration 6 --keys scan odom out.mcap",
    )
    rec.add_argument("out", metavar="OUT.mcap", nargs="?", help="output file (may also come last after --keys)")
    rec.add_argument(
        "--keys",
        nargs="+",
        metavar="K",
        help="keys or key expressions (robot0/scan, robot0/status/*) or bare topic names (scan, odom); "
        "default: every key of --ns",
    )
    rec.add_argument("--ns", default="robot0", help="namespace of bare topic names and of the default (robot0)")
    rec.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (default: until Ctrl-C)")
    rec.add_argument("--compression", choices=("zstd", "lz4", "none"), default="zstd", help="chunk compression")
    rec.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    add_bus_arguments(rec)
    rec.set_defaults(func=run_record)

    play = bag_sub.add_parser(
        "play",
        help="republish a bag with its original timing",
        description=(
            "Publish every message of IN on the key it was recorded from, at its recorded log time (scaled by "
            "--rtf), keeping each topic's delivery (snapshot or event). Recorded clock messages drive sim-time "
            "services as the sim would."
        ),
        epilog="Example: mjnav bag play run.mcap --rtf 2 --keys scan odom",
    )
    play.add_argument("bag_in", metavar="IN.mcap", nargs="?", help="bag to replay (may also come last after --keys)")
    play.add_argument("--rtf", type=float, default=1.0, help="real-time factor (default 1; 0 = as fast as possible)")
    play.add_argument("--keys", nargs="+", metavar="K", help="replay only these keys / key expressions / topics")
    play.add_argument("--ns", metavar="NAMESPACE", help="publish under this namespace instead of the recorded one")
    play.add_argument(
        "--wait", type=float, default=2.0, metavar="S", help="wait up to S seconds for a subscriber first (default 2)"
    )
    add_bus_arguments(play)
    play.set_defaults(func=run_play)

    info = bag_sub.add_parser(
        "info",
        help="summarise bags",
        description="Time span, message count and per-topic type, count and rate of each bag.",
    )
    info.add_argument("bags", nargs="+", metavar="BAG.mcap", help="bag file(s)")
    info.add_argument("--json", action="store_true", help="print JSON instead of text")
    info.set_defaults(func=run_info)


def _help(parser: argparse.ArgumentParser) -> int:
    parser.print_help()
    return 2


def _file_argument(value: str | None, keys: list[str] | None) -> str | None:
    """The file positional; ``--keys a b out.mcap`` leaves it inside ``--keys`` (argparse is greedy): take it back."""
    if value is None and keys and keys[-1].endswith(".mcap"):
        return keys.pop()
    return value


def _stop_on_signals(stop: threading.Event) -> None:
    """SIGINT/SIGTERM set ``stop`` (a clean end: the bag is finished); a second one exits at once."""
    count = 0

    def handler(signum: int, frame: FrameType | None) -> None:
        nonlocal count
        count += 1
        if count > 1:
            raise KeyboardInterrupt
        stop.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)


def run_record(args: argparse.Namespace) -> int:
    """``mjnav bag record``."""
    from mjnav.bag import BagError, key_expressions, record
    from mjnav.bus import Bus, BusConfigError, bus_config_from_args
    from mjnav.runtime.logs import setup_logging

    setup_logging("WARNING")
    name = _file_argument(args.out, args.keys)
    if name is None:
        print("mjnav bag record: give the output file, e.g. mjnav bag record --duration 6 out.mcap", file=sys.stderr)
        return 2
    out = Path(name)
    try:
        if out.exists() and not args.force:
            raise BagError(f"{out} exists; use --force to overwrite it")
        if args.duration is not None and not args.duration > 0:
            raise BagError("--duration must be > 0")
        exprs = key_expressions(args.keys, args.ns)
        config = bus_config_from_args(args)
    except (BagError, BusConfigError) as exc:
        print(f"mjnav bag record: {exc}", file=sys.stderr)
        return 2
    stop = threading.Event()
    _stop_on_signals(stop)
    print(f"recording {', '.join(exprs)} to {out} (Ctrl-C to stop)", file=sys.stderr)
    try:
        with Bus.open(config) as bus:
            stats = record(bus, out, exprs, duration_s=args.duration, stop=stop, compression=args.compression)
    except BagError as exc:
        print(f"mjnav bag record: {exc}", file=sys.stderr)
        return 1
    skipped = ", ".join(f"{n} {reason}" for reason, n in sorted(stats.skipped.items()))
    print(
        f"recorded {stats.total} messages on {len(stats.messages)} keys over {stats.span_s:.2f} s to {out}"
        + (f" (skipped: {skipped})" if skipped else ""),
        file=sys.stderr,
    )
    return 0


def run_play(args: argparse.Namespace) -> int:
    """``mjnav bag play``."""
    from mjnav.bag import BagError, key_expressions, play
    from mjnav.bus import Bus, BusConfigError, bus_config_from_args
    from mjnav.runtime.logs import setup_logging

    setup_logging("WARNING")
    bag_in = _file_argument(args.bag_in, args.keys)
    try:
        if bag_in is None:
            raise BagError("give the bag to replay, e.g. mjnav bag play run.mcap")
        if not args.rtf >= 0:
            raise BagError("--rtf must be >= 0 (0 = as fast as possible)")
        exprs = None
        if args.keys:
            exprs = key_expressions(args.keys, args.ns or "robot0")
        if not Path(bag_in).is_file():
            raise BagError(f"no such bag: {bag_in}")
        config = bus_config_from_args(args)
    except (BagError, BusConfigError) as exc:
        print(f"mjnav bag play: {exc}", file=sys.stderr)
        return 2
    stop = threading.Event()
    _stop_on_signals(stop)
    try:
        with Bus.open(config) as bus:
            stats = play(
                bag_in,
                bus,
                rtf=args.rtf,
                key_expressions=exprs,
                namespace=args.ns,
                stop=stop,
                wait_subscribers_s=args.wait,
            )
    except BagError as exc:
        print(f"mjnav bag play: {exc}", file=sys.stderr)
        return 1
    for topic, reason in sorted(stats.skipped_channels.items()):
        print(f"skipped {topic}: {reason}", file=sys.stderr)
    print(
        f"published {stats.total} messages on {len(stats.messages)} keys: {stats.bag_span_s:.2f} s of bag in "
        f"{stats.wall_s:.2f} s (max lag {1e3 * stats.max_lag_s:.1f} ms)",
        file=sys.stderr,
    )
    return 0


def run_info(args: argparse.Namespace) -> int:
    """``mjnav bag info``."""
    from mjnav.bag import BagError, bag_info, format_info

    code = 0
    infos = []
    for path in args.bags:
        try:
            infos.append(bag_info(path))
        except BagError as exc:
            print(f"mjnav bag info: {exc}", file=sys.stderr)
            code = 1
    if args.json:
        print(json.dumps([i.to_dict() for i in infos], indent=2))
    else:
        print("\n\n".join(format_info(i) for i in infos))
    return code

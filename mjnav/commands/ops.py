"""``mjnav map save`` (the mapper writes the map) and ``mjnav param get|set`` (a running service's settings)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

#: Exit codes of ``mjnav map save`` and ``mjnav param`` (documented in their --help).
EXIT_OK = 0
EXIT_REFUSED = 1
EXIT_USAGE = 2
EXIT_UNREACHABLE = 3

_EXIT_HELP = (
    "Exit status: 0 done; 1 the service refused (the reason is printed); 2 bad arguments; 3 nobody answered (no "
    "router, or the service is not running)."
)


def register(sub: Any) -> None:
    """Add ``map`` (``save``) and ``param`` (``get``, ``set``)."""
    from mjnav.bus import add_bus_arguments

    m = sub.add_parser("map", help="save the map the stack built", description="Work with the running stack's map.")
    msub = m.add_subparsers(dest="map_command", metavar="ACTION")
    m.set_defaults(func=lambda _args: (m.print_help(), EXIT_USAGE)[1])
    save = msub.add_parser(
        "save",
        help="ask the mapper to write the map as PGM + YAML",
        description=(
            "Ask the mapper (endpoint <ns>/save_map) to write the map as a ROS map (trinary PGM + YAML, what "
            "map_server and 'mjnav demo --world FILE' read). FILE is taken relative to the mapper's maps_dir "
            "(services/mapper.toml, default maps/; paths outside it are refused); without FILE the mapper's "
            "save_path is used. Prints the written YAML's path."
        ),
        epilog=f"Example: mjnav map save rooms.yaml && mjnav demo --world maps/rooms.yaml. {_EXIT_HELP}",
    )
    save.add_argument("file", nargs="?", default="", metavar="FILE", help="YAML file inside the mapper's maps_dir")
    save.add_argument("--timeout", type=float, default=10.0, metavar="S", help="seconds to wait (default 10)")
    save.add_argument("--ns", default="robot0", help="robot namespace (default robot0)")
    add_bus_arguments(save)
    save.set_defaults(func=run_map_save)

    p = sub.add_parser(
        "param",
        help="read or change a running service's settings",
        description=(
            "Read a running service's settings (endpoint <ns>/config/<service>) or change one that the service "
            "reads afresh at every use (<ns>/set_param/<service>; the service's runtime_settable keys, e.g. "
            "planner.algorithm, mapper.inflation_radius_m). A new value is validated like the service's TOML file "
            "(type and range) and takes effect before the service's next step."
        ),
        epilog=_EXIT_HELP,
    )
    psub = p.add_subparsers(dest="param_command", metavar="ACTION")
    p.set_defaults(func=lambda _args: (p.print_help(), EXIT_USAGE)[1])
    get = psub.add_parser("get", help="print one setting (or all, as JSON) of a running service")
    get.add_argument("service", metavar="SERVICE")
    get.add_argument("key", nargs="?", metavar="KEY", help="setting name (default: all settings as JSON)")
    setp = psub.add_parser(
        "set",
        help="change a runtime-settable setting of a running service",
        epilog='VALUE is read as in --set: a TOML value (0.5, true, [1, 2], "astar") or else a bare string.',
    )
    setp.add_argument("service", metavar="SERVICE")
    setp.add_argument("key", metavar="KEY")
    setp.add_argument("value", metavar="VALUE")
    for q in (get, setp):
        q.add_argument("--timeout", type=float, default=5.0, metavar="S", help="seconds to wait (default 5)")
        q.add_argument("--ns", default="robot0", help="robot namespace (default robot0)")
        add_bus_arguments(q)
    get.set_defaults(func=run_param_get)
    setp.set_defaults(func=run_param_set)


def _call(args: argparse.Namespace, command: str, endpoint: str, data: str, service: str | None) -> Any:
    """Call ``endpoint`` with a ``std_msgs/String`` request; returns the reply's text, or an exit code (int) after
    printing why there is none."""
    from mjnav.bus import BusConfigError, BusUnavailable, NoReply, RemoteError
    from mjnav.commands.bustools import open_connected
    from mjnav.msgs import msg_class
    from mjnav.runtime.logs import setup_logging

    if not args.timeout > 0:
        print(f"mjnav {command}: --timeout must be > 0", file=sys.stderr)
        return EXIT_USAGE
    setup_logging("WARNING")
    try:
        bus = open_connected(args, args.ns)
    except (BusUnavailable, BusConfigError) as exc:
        print(f"mjnav {command}: {exc}", file=sys.stderr)
        return EXIT_UNREACHABLE
    with bus:
        who = f"{args.ns}/{endpoint}" + (f"/{service}" if service else "")
        try:
            reply = bus.call(
                endpoint, msg_class("std_msgs/msg/String")(data=data), timeout_s=args.timeout, service=service
            )
        except NoReply:
            print(
                f"mjnav {command}: nobody answered on {who} within {args.timeout:g} s (is it running?)", file=sys.stderr
            )
            return EXIT_UNREACHABLE
        except RemoteError as exc:
            print(f"mjnav {command}: {exc}", file=sys.stderr)
            return EXIT_REFUSED
    return str(reply.data)


def run_map_save(args: argparse.Namespace) -> int:
    """``mjnav map save [FILE]``."""
    reply = _call(args, "map save", "save_map", args.file, None)
    if isinstance(reply, int):
        return reply
    print(json.loads(reply)["yaml"])
    return EXIT_OK


def run_param_get(args: argparse.Namespace) -> int:
    """``mjnav param get SERVICE [KEY]``."""
    reply = _call(args, "param get", "config", "", args.service)
    if isinstance(reply, int):
        return reply
    config = json.loads(reply)
    if args.key is None:
        print(json.dumps(config, indent=2))
        return EXIT_OK
    if args.key not in config:
        print(f"mjnav param get: {args.service} has no setting {args.key!r}; valid: {sorted(config)}", file=sys.stderr)
        return EXIT_REFUSED
    print(json.dumps(config[args.key]))
    return EXIT_OK


def run_param_set(args: argparse.Namespace) -> int:
    """``mjnav param set SERVICE KEY VALUE``."""
    from mjnav.runtime.config import ConfigError, parse_override

    try:
        key, value = parse_override(f"{args.key}={args.value}")
    except ConfigError as exc:
        print(f"mjnav param set: {exc}", file=sys.stderr)
        return EXIT_USAGE
    reply = _call(args, "param set", "set_param", json.dumps({"key": key, "value": value}), args.service)
    if isinstance(reply, int):
        return reply
    result = json.loads(reply)
    print(f"{args.service}.{result['key']}: {json.dumps(result['previous'])} -> {json.dumps(result['value'])}")
    return EXIT_OK

"""``mjnav router``: a standalone Zenoh router (what the router container of docker compose runs)."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from types import FrameType
from typing import Any

DEFAULT_LISTEN = "tcp/127.0.0.1:7447"
DEFAULT_TLS_LISTEN = "tls/127.0.0.1:7447"


def register(sub: Any) -> None:
    """Add the ``router`` command."""
    p = sub.add_parser(
        "router",
        help="run a Zenoh router",
        description=(
            "Run a Zenoh router until Ctrl-C/SIGTERM: services, mjnav tools and any Zenoh client connect to it. "
            "Connect it to other routers (--connect tcp/HOST:7447) to join machines. The environment "
            "(MJNAV_ZENOH_LISTEN, MJNAV_ZENOH_CONNECT) wins over the flags, as for every mjnav process."
        ),
        epilog="Examples: mjnav router --listen tcp/0.0.0.0:7447 --connect tcp/192.168.1.20:7447   "
        "mjnav router --secure certs --listen tls/0.0.0.0:7447",
    )
    p.add_argument(
        "--listen",
        action="append",
        metavar="ENDPOINT",
        help=f"endpoint to listen on (repeatable; default {DEFAULT_LISTEN}; tcp/0.0.0.0:7447 serves the network)",
    )
    p.add_argument(
        "--connect",
        action="append",
        metavar="ENDPOINT",
        help="another router to connect to (repeatable; default none)",
    )
    p.add_argument("--bus-config", metavar="FILE", help="TOML file with connect/listen (env MJNAV_ZENOH_CONFIG)")
    p.add_argument("--multicast", action="store_true", help="also discover peers by UDP multicast scouting")
    p.add_argument(
        "--secure",
        metavar="DIR",
        help="mutual TLS and the stack's access control with the certificates in DIR ('mjnav certs'), as "
        "'mjnav up --secure' does; listen endpoints must then be tls/… (default tls/127.0.0.1:7447)",
    )
    p.add_argument("--stack", metavar="FILE", help="with --secure: the stack whose rights apply (default services/)")
    p.add_argument("--ns", metavar="NAMESPACE", help="with --secure: the stack's namespace (default: the stack's)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``mjnav router``."""
    import os
    from dataclasses import replace

    from mjnav.bus import Bus, BusConfigError, load_bus_config
    from mjnav.bus.acl import AclError, secure_router_config
    from mjnav.runtime.config import ConfigError
    from mjnav.runtime.logs import setup_logging
    from mjnav.runtime.stack import load_stack

    setup_logging("INFO")
    try:
        config = load_bus_config(
            config_file=args.bus_config,
            mode="router",
            connect=args.connect,
            listen=args.listen or [DEFAULT_TLS_LISTEN if args.secure else DEFAULT_LISTEN],
        )
        if not args.connect and not os.environ.get("MJNAV_ZENOH_CONNECT") and not _file_sets_connect(args):
            config = replace(config, connect=())  # a router connects to nobody unless told (not to itself)
        if args.secure:
            stack = load_stack(args.stack)
            secure = secure_router_config(args.secure, config.listen, args.ns or stack.namespace, stack.names())
            config = replace(secure, connect=config.connect)
        config = replace(config, mode="router", multicast_scouting=config.multicast_scouting or args.multicast)
    except (BusConfigError, AclError, ConfigError, ValueError) as exc:
        print(f"mjnav router: {exc}", file=sys.stderr)
        return 2
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        router = Bus.open(config)
    except Exception as exc:  # zenoh raises its own error type for a taken port or a bad endpoint
        print(f"mjnav router: cannot start on {', '.join(config.listen)}: {exc}", file=sys.stderr)
        return 1
    try:
        print(
            f"zenoh router listening on {', '.join(config.listen)}"
            + (f", connected to {', '.join(config.connect)}" if config.connect else ""),
            file=sys.stderr,
            flush=True,
        )
        stop.wait()
    finally:
        router.close()
    print("zenoh router stopped", file=sys.stderr)
    return 0


def _file_sets_connect(args: argparse.Namespace) -> bool:
    """Whether the bus config file (flag or MJNAV_ZENOH_CONFIG) sets ``connect`` itself."""
    import os
    import tomllib
    from pathlib import Path

    file = os.environ.get("MJNAV_ZENOH_CONFIG") or args.bus_config
    if not file:
        return False
    try:
        return "connect" in tomllib.loads(Path(file).read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError):
        return False

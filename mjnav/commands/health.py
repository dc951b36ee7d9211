"""``mjnav health``: is the router reachable and are these services alive? (container healthchecks, scripts)."""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

#: ``mjnav_msgs/ServiceStatus.state`` of a running service.
_ACTIVE = 2


def register(sub: Any) -> None:
    """Add the ``health`` command."""
    from mjnav.bus import add_bus_arguments

    p = sub.add_parser(
        "health",
        help="check that the router answers and services are alive",
        description=(
            "Exit 0 when the Zenoh router (or a peer) is reachable and every named service holds its liveliness "
            "token mjnav/alive/<ns>/<service> (with --status: also reports itself active on <ns>/status/<service>); "
            "exit 1 otherwise, naming what is missing. With no service named, only the connection is checked."
        ),
        epilog="Examples: mjnav health --connect tcp/127.0.0.1:7447   mjnav health sim mapper --timeout 5",
    )
    p.add_argument("services", nargs="*", metavar="SERVICE", help="services that must be alive")
    p.add_argument("--ns", default="robot0", help="namespace of the services (default robot0)")
    p.add_argument("--timeout", type=float, default=5.0, metavar="S", help="give up after S seconds (default 5)")
    p.add_argument("--status", action="store_true", help="also require an 'active' status message from each")
    add_bus_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``mjnav health``."""
    from mjnav.bus import Bus, BusConfigError, bus_config_from_args, wait_until
    from mjnav.runtime.logs import setup_logging

    setup_logging("ERROR")
    try:
        config = bus_config_from_args(args)
        if not args.timeout > 0:
            raise ValueError("--timeout must be > 0")
        bus = Bus.open(config, args.ns)
    except (BusConfigError, ValueError) as exc:
        print(f"mjnav health: {exc}", file=sys.stderr)
        return 2
    deadline = time.monotonic() + args.timeout
    problems: list[str] = []
    with bus:
        info = bus.session.info
        if not wait_until(lambda: bool(info.routers_zid() or info.peers_zid()), args.timeout, 0.05):
            print(f"unhealthy: no Zenoh router or peer reachable at {', '.join(config.connect)}", file=sys.stderr)
            return 1
        status_sub = bus.subscribe("status", service="*") if args.status else None
        missing = list(args.services)
        while missing and time.monotonic() < deadline:
            alive = set(bus.alive_services(min(1.0, max(0.1, deadline - time.monotonic()))))
            missing = [s for s in missing if s not in alive]
        problems += [f"{s}: not alive" for s in missing]
        if status_sub is not None:
            keys = {s: bus.key("status", service=s) for s in args.services if s not in missing}

            def states() -> dict[str, int | None]:
                latest = status_sub.latest_by_key()
                return {s: (int(latest[k].state) if k in latest else None) for s, k in keys.items()}

            wait_until(lambda: all(v == _ACTIVE for v in states().values()), max(0.0, deadline - time.monotonic()))
            for s, state in states().items():
                if state is None:
                    problems.append(f"{s}: no status on {keys[s]}")
                elif state != _ACTIVE:
                    problems.append(f"{s}: status state {state}, not active")
    if problems:
        print("unhealthy: " + "; ".join(problems), file=sys.stderr)
        return 1
    print("healthy" + (f": {', '.join(args.services)} alive" if args.services else ": router reachable"))
    return 0

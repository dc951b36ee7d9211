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
            "token mjnav/alive/<ns>/<service> (with --status: also reports itself active on <ns>/status/<service>, "
            "its loop is moving — its step count grows between two status messages — and it lacks no input: a "
            "service starved of one, such as slam without an initialpose or the mapper without a pose, names it in "
            "its status); exit 1 otherwise, naming what is missing, stalled, starved or unreachable (never waits "
            "longer than --timeout). With no service named, only the connection is checked."
        ),
        epilog="Examples: mjnav health --connect tcp/127.0.0.1:7447   mjnav health sim mapper --timeout 5",
    )
    p.add_argument("services", nargs="*", metavar="SERVICE", help="services that must be alive")
    p.add_argument("--ns", default="robot0", help="namespace of the services (default robot0)")
    p.add_argument("--timeout", type=float, default=5.0, metavar="S", help="give up after S seconds (default 5)")
    p.add_argument(
        "--status",
        action="store_true",
        help="also require an 'active' status from each, with a step count that moves and no input missing "
        "(statuses come every second)",
    )
    add_bus_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``mjnav health``."""
    from dataclasses import replace

    from mjnav.bus import Bus, BusConfigError, BusUnavailable, bus_config_from_args, wait_until
    from mjnav.runtime.logs import setup_logging

    setup_logging("ERROR")
    try:
        if not args.timeout > 0:
            raise ValueError("--timeout must be > 0")
        config = replace(bus_config_from_args(args), connect_timeout_s=args.timeout)
    except (BusConfigError, ValueError) as exc:
        print(f"mjnav health: {exc}", file=sys.stderr)
        return 2
    try:
        bus = Bus.open(config, args.ns)
    except BusUnavailable:
        print(f"unhealthy: no Zenoh router or peer reachable at {', '.join(config.connect)}", file=sys.stderr)
        return 1
    deadline = time.monotonic() + args.timeout
    problems: list[str] = []
    with bus:
        if not wait_until(bus.connected, args.timeout, 0.05):
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

            first_steps: dict[str, int] = {}

            def states() -> dict[str, tuple[int, int, str] | None]:
                latest = status_sub.latest_by_key()
                out: dict[str, tuple[int, int, str] | None] = {}
                for s, k in keys.items():
                    if k in latest:
                        first_steps.setdefault(s, int(latest[k].steps))
                        out[s] = (int(latest[k].state), int(latest[k].steps), str(latest[k].waiting_for))
                    else:
                        out[s] = None
                return out

            def good() -> bool:
                return all(
                    v is not None and v[0] == _ACTIVE and v[1] > first_steps[s] and not v[2]
                    for s, v in states().items()
                )

            wait_until(good, max(0.0, deadline - time.monotonic()), 0.05)
            for s, latest in states().items():
                if latest is None:
                    problems.append(f"{s}: no status on {keys[s]}")
                elif latest[0] != _ACTIVE:
                    problems.append(f"{s}: status state {latest[0]}, not active")
                elif latest[2]:
                    problems.append(f"{s}: waiting for {latest[2]}")
                elif latest[1] <= first_steps[s]:
                    problems.append(f"{s}: loop stalled (step count stuck at {latest[1]})")
    if problems:
        print("unhealthy: " + "; ".join(problems), file=sys.stderr)
        return 1
    print("healthy" + (f": {', '.join(args.services)} alive" if args.services else ": router reachable"))
    return 0

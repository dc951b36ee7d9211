"""``mjnav run`` (one service) and ``mjnav up`` (the whole stack on an embedded router)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from mjnav.commands._args import add_packing_argument, add_port_argument


def register(sub: Any) -> None:
    """Add the ``run`` and ``up`` commands."""
    from mjnav.bus import DEFAULT_PORT, add_bus_arguments
    from mjnav.runtime.launcher import FIRST_STEP_TIMEOUT_S, HUNG_TIMEOUT_S

    run = sub.add_parser(
        "run",
        help="run one service of the stack, or several in one process",
        description=(
            "Run one service (e.g. sim) in this process, connected to a Zenoh router; or several (a container: "
            "'mjnav run slam mapper planner', or the name of a [[container]] of the stack file), which share one "
            "Zenoh session and one clock and keep their own config, lifecycle, status and lockstep slot. Each "
            "service steps at its configured rate on sim time (the clock topic) or wall time, publishes "
            "<ns>/status/<service> every second and holds the liveliness token mjnav/alive/<ns>/<service>. "
            "Ctrl-C stops it cleanly."
        ),
        epilog="Examples: mjnav run sim --set world=maze; mjnav run nav; mjnav run slam mapper --set slam.seed=3",
    )
    run.add_argument(
        "service",
        nargs="+",
        help="service name(s) from the stack file, or a container's name (see 'mjnav up --list')",
    )
    run.add_argument("--stack", metavar="FILE", help="stack file (default services/stack.toml)")
    run.add_argument("--ns", metavar="NAMESPACE", help="robot namespace (default: the stack's, robot0)")
    run.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a config value (TOML syntax: --set rate_hz=20 --set world=maze; with several services "
        "SERVICE.KEY=VALUE: --set slam.seed=3); repeatable",
    )
    run.add_argument("--log-level", default="INFO", help="DEBUG, INFO, WARNING (default INFO)")
    add_bus_arguments(run, identity=None)
    run.set_defaults(func=run_service)

    up = sub.add_parser(
        "up",
        help="run the whole stack on an embedded Zenoh router",
        description=(
            "Start a Zenoh router in this process on 127.0.0.1:PORT and every service of the stack as a child "
            "process connected to it. Output is prefixed [service]; a crashed or hung service (no status for "
            "--hung-timeout seconds) is restarted (bounded, logged); services resume from the run's checkpoints "
            "(the map, the active goal). Every setting, the world and the port are checked before anything "
            "starts (exit 2 naming the problem). Ctrl-C or --duration stops the services in reverse order and "
            "exits 0; the services die with this process, however it dies. Any Zenoh client can join at "
            "tcp/127.0.0.1:PORT."
        ),
        epilog="Example: mjnav up --only sim --duration 10 --set sim.world=maze",
    )
    up.add_argument("--only", metavar="A,B", help="comma-separated services to run (default: all)")
    up.add_argument("--ns", metavar="NAMESPACE", help="robot namespace (default: the stack's, robot0)")
    add_port_argument(up, DEFAULT_PORT)
    up.add_argument("--duration", type=float, metavar="S", help="stop after S wall seconds (default: run until Ctrl-C)")
    up.add_argument("--headless", action="store_true", help="open no browser or window (always true without a display)")
    up.add_argument(
        "--world",
        metavar="W",
        help="the sim's world: empty, rooms, maze, warehouse or an MJCF path (= --set sim.world=W)",
    )
    up.add_argument(
        "--static-html",
        metavar="FILE",
        help="write a self-contained HTML snapshot of the viz scene when the stack stops",
    )
    up.add_argument("--stack", metavar="FILE", help="stack file (default services/stack.toml)")
    add_packing_argument(up)
    up.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SERVICE.KEY=VALUE",
        help="override a service's config value, e.g. --set sim.world=maze; repeatable",
    )
    up.add_argument("--seed", type=int, help="seed of the sim's noise and every service's randomness")
    up.add_argument(
        "--free-running",
        action="store_true",
        help="let the sim run on wall time without waiting for the services (default: lockstep, sim time advances "
        "only when every service on sim time has finished the step that is due)",
    )
    up.add_argument(
        "--hung-timeout",
        type=float,
        default=HUNG_TIMEOUT_S,
        metavar="S",
        help=f"kill and restart a running service whose status heartbeat stopped for S wall seconds "
        f"(default {HUNG_TIMEOUT_S:g}; before its first step {FIRST_STEP_TIMEOUT_S:g} s: numba compiles on first use)",
    )
    up.add_argument(
        "--secure",
        metavar="DIR",
        help="mutual TLS and access control with the certificates in DIR (make them with 'mjnav certs --out DIR'): "
        "the router listens on tls/127.0.0.1:PORT, accepts only clients with a certificate of DIR's CA and lets "
        "each identity publish only its own topics (README 'Security'); default: plain TCP on loopback, no access "
        "control",
    )
    up.add_argument(
        "--ros",
        choices=["rmw_zenoh"],
        help="also run the ros_bridge service: every topic on rmw_zenoh's keys, with its graph tokens, so ROS 2 nodes "
        "on RMW_IMPLEMENTATION=rmw_zenoh_cpp (ROS_DOMAIN_ID, or --set ros_bridge.domain_id=N) see the stack and can "
        "send cmd_vel and goals (README 'ROS 2 over rmw_zenoh')",
    )
    up.add_argument(
        "--foxglove",
        action="store_true",
        help="also run the foxglove service: a Foxglove WebSocket server on ws://127.0.0.1:8765 streaming every "
        "topic with its ROS 2 schema (--set foxglove.port=N; layout: services/foxglove_layout.json)",
    )
    up.add_argument("--list", action="store_true", help="list the stack's services and exit")
    up.add_argument("--log-level", default="INFO", help="DEBUG, INFO, WARNING (default INFO)")
    up.set_defaults(func=run_up)


def run_service(args: argparse.Namespace) -> int:
    """``mjnav run``."""
    from mjnav.bus import BusConfigError, bus_config_from_args
    from mjnav.runtime.config import ConfigError
    from mjnav.runtime.logs import setup_logging
    from mjnav.runtime.process import build_runner, resolve_services
    from mjnav.runtime.stack import load_stack

    setup_logging(args.log_level)
    try:
        stack = load_stack(args.stack)
        specs = resolve_services(stack, args.service)
        if len(specs) > 1 and args.secure and not args.identity:
            raise ConfigError(
                "--secure gives a process one identity and each service has its own: run each service alone, or "
                "name a certificate whose rights cover them all with --identity"
            )
        bus_config = bus_config_from_args(args, identity=specs[0].name)
        runner = build_runner(stack, specs, args.set, bus_config, args.ns)
    except (ConfigError, BusConfigError, ValueError) as exc:
        print(f"mjnav run: {exc}", file=sys.stderr)
        return 2
    runner.install_signal_handlers()
    return runner.run()


def run_up(args: argparse.Namespace) -> int:
    """``mjnav up``."""
    from mjnav.bus import DEFAULT_PORT, BusConfigError
    from mjnav.bus.acl import AclError
    from mjnav.runtime.config import ConfigError
    from mjnav.runtime.launcher import Launcher
    from mjnav.runtime.logs import setup_logging
    from mjnav.runtime.stack import add_service_overrides, load_stack, port_overrides

    setup_logging(args.log_level)
    try:
        stack = load_stack(args.stack)
        optional = (["ros_bridge"] if args.ros == "rmw_zenoh" else []) + (["foxglove"] if args.foxglove else [])
        if args.ros and args.secure:
            raise ConfigError("--ros rmw_zenoh does not work with --secure (the ACL has no rules for ROS 2 keys)")
        stack = stack.with_services(optional)
        if args.list:
            for spec in stack.services:
                print(f"{spec.name:12s} {spec.class_path}  config={spec.config_file}  restarts={spec.restarts}")
            for proc in stack.processes(list(stack.services), packed=not args.process_per_service):
                if proc.container:
                    print(f"container {proc.name}: {' '.join(proc.service_names())} (one process)")
            return 0
        only = [s.strip() for s in args.only.split(",") if s.strip()] + optional if args.only else None
        overrides = port_overrides(stack.select(only), args.port) if args.port is not None else {}
        if args.world:
            stack.get("sim")
            overrides.setdefault("sim", []).append(f"world={json.dumps(args.world)}")
        if args.static_html:
            stack.get("viz")
            overrides.setdefault("viz", []).append(f"static_html={json.dumps(str(Path(args.static_html).resolve()))}")
        add_service_overrides(stack, args.set, overrides)
        launcher = Launcher(
            stack,
            only=only,
            namespace=args.ns,
            port=DEFAULT_PORT if args.port is None else args.port,
            duration_s=args.duration,
            overrides=overrides,
            extra_env={"MJNAV_HEADLESS": "1"} if args.headless else None,
            lockstep=not args.free_running,
            seed=args.seed,
            hung_timeout_s=args.hung_timeout,
            secure=args.secure,
            fork_services=True,
            packed=not args.process_per_service,
        )
        launcher.check()
    except (ConfigError, BusConfigError, AclError, ValueError) as exc:
        print(f"mjnav up: {exc}", file=sys.stderr)
        return 2
    return launcher.run()

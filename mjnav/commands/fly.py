"""``mjnav fly``: the UAV stack on an embedded router, one flight in lockstep, and its summary."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

from mjnav import jsonsafe
from mjnav.commands._args import add_packing_argument, add_port_argument, non_negative_float
from mjnav.commands._launch import run_beside_launcher, write_summary

#: The flight client's lockstep name.
FLIGHT = "flight"
#: Sim seconds on the pad before take-off, per state source (the INS averages GPS fixes before it is trusted).
PREFLIGHT_S = {"ins": 10.0, "mocap": 1.0}


def register(sub: Any) -> None:
    """Add the ``fly`` command."""
    p = sub.add_parser(
        "fly",
        help="fly the quadrotor (MuJoCo sim, GPS/INS and flight controller over Zenoh) and print the summary",
        description=(
            "Start a Zenoh router and the UAV stack (services/uav_stack.toml: uav_sim, ins, flight_controller in "
            "namespace uav0) in lockstep, arm the quadrotor, take off from the pad, fly the trajectory, land, and "
            "print a summary. Figure-8: x = sin(2πt/8), y = 0.5 sin(4πt/8), z = 1.5 m, three periods after "
            "take-off. With --json the last stdout line is the summary as JSON: rms_error_m and max_error_m (true "
            "position against the reference over the scored part), ins_rms_m (INS estimate against the truth), "
            "gps_rms_m (GPS fixes against the truth), time_s (sim, arming to touchdown), achieved_rtf (sim s per "
            "wall s), seed, and more. The same --seed gives the same flight to the last bit."
        ),
        epilog="Example: mjnav fly --trajectory figure8 --controller rpt --state mocap --wind 3 --gust 6 --rtf max",
    )
    p.add_argument(
        "--trajectory",
        nargs="+",
        default=["figure8"],
        metavar="figure8|hover|waypoints FILE",
        help="figure8 (default), hover, or waypoints FILE (JSON list of [x, y, z] in ENU metres)",
    )
    p.add_argument("--controller", choices=("pid", "lqr", "hinf", "rpt"), default="rpt", help="default rpt")
    p.add_argument("--state", choices=("ins", "mocap"), default="mocap", help="state source (default mocap)")
    p.add_argument("--wind", type=non_negative_float, default=0.0, metavar="MPS", help="mean wind, m/s (default 0)")
    p.add_argument("--gust", type=non_negative_float, default=0.0, metavar="MPS", help="peak gusts, m/s (default 0)")
    p.add_argument("--seed", type=int, default=0, help="seed of the wind and the sensors' noise (default 0)")
    p.add_argument(
        "--rtf",
        default="1",
        metavar="FACTOR|max",
        help="at most FACTOR x real time, or max: as fast as the services allow (default 1)",
    )
    p.add_argument(
        "--record", nargs="?", const="", metavar="MP4", help="record a chase-camera video (default DIR/fly.mp4)"
    )
    p.add_argument("--out", metavar="DIR", help="write summary.json (and the video) here")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on the last stdout line")
    p.add_argument("--world", default="field", help="UAV scene of mjcf/uav/ or an MJCF path (default field)")
    p.add_argument("--headless", action="store_true", help="open no browser or window")
    add_port_argument(p, 7448)
    p.add_argument("--stack", metavar="FILE", help="stack file (default services/uav_stack.toml)")
    add_packing_argument(p)
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SERVICE.KEY=VALUE",
        help="override a service's config value, e.g. --set uav_sim.gps_noise_m=2; repeatable",
    )
    p.add_argument("--log-level", default="INFO", help="log level of the services (default INFO)")
    p.set_defaults(func=run)


def _plan(args: argparse.Namespace, pad: Any) -> Any:
    from mjnav.aerial.trajectories import figure8_plan, hover_plan, waypoints_plan

    kind, rest = args.trajectory[0], args.trajectory[1:]
    t0 = PREFLIGHT_S[args.state]
    if kind == "figure8" and not rest:
        return figure8_plan(pad, t0)
    if kind == "hover" and not rest:
        return hover_plan(pad, t0)
    if kind == "waypoints" and len(rest) == 1:
        try:
            data = json.loads(Path(rest[0]).read_text(encoding="utf-8"))
        except json.JSONDecodeError as exc:
            raise ValueError(
                f"waypoints file {rest[0]}: not JSON ({exc}); write a list of [x, y, z] in ENU metres, "
                "e.g. [[0, 0, 1.5], [1, 0, 1.5], [1, 1, 1.5]]"
            ) from None
        return waypoints_plan(pad, t0, data)
    raise ValueError(f"--trajectory must be figure8, hover or waypoints FILE, got {' '.join(args.trajectory)!r}")


def run(args: argparse.Namespace) -> int:
    """``mjnav fly``."""
    from mjnav.bus import BusConfig
    from mjnav.runtime.config import ConfigError
    from mjnav.runtime.launcher import Launcher
    from mjnav.runtime.logs import setup_logging
    from mjnav.runtime.stack import add_service_overrides, load_stack, port_overrides, services_dir
    from mjnav.sim.uav import UavSimulator

    setup_logging(args.log_level)
    try:
        sim = UavSimulator(args.world)
        truth = sim.truth()
        plan = _plan(args, truth.position_m)
        rtf = 0.0 if args.rtf.strip().lower() == "max" else float(args.rtf)
        if not (math.isfinite(rtf) and rtf >= 0):
            raise ValueError(f"--rtf must be a positive number or 'max', got {args.rtf!r}")
        stack = load_stack(args.stack or services_dir() / "uav_stack.toml")
        out = Path(args.out) if args.out else None
        if out is not None:
            out.mkdir(parents=True, exist_ok=True)
        overrides = port_overrides(stack.select(None), args.port) if args.port is not None else {}
        overrides |= {
            "uav_sim": [
                f"world={json.dumps(str(sim.path))}",
                f"rtf={rtf}",
                f"wind_mps={args.wind}",
                f"gust_mps={args.gust}",
            ],
            "flight_controller": [
                f"controller={json.dumps(args.controller)}",
                f"state_source={json.dumps(args.state)}",
            ],
        }
        if "uav_viz" in stack.names() and out is not None:
            overrides.setdefault("uav_viz", []).append(f"static_html={json.dumps(str((out / 'scene.html').resolve()))}")
        if args.record is not None:
            video = Path(args.record) if args.record else (out / "fly.mp4" if out else None)
            if video is None:
                raise ValueError("--record without a file needs --out DIR")
            overrides["uav_sim"].append(f"record_path={json.dumps(str(video.resolve()))}")
        add_service_overrides(stack, args.set, overrides)
    except (ConfigError, ValueError, OSError, LookupError) as exc:
        print(f"mjnav fly: {exc}", file=sys.stderr)
        return 2

    wall0 = time.monotonic()
    try:
        launcher = Launcher(
            stack,
            port=7448 if args.port is None else args.port,
            overrides=overrides,
            out=sys.stderr if args.json else sys.stdout,
            extra_env={"MJNAV_HEADLESS": "1"} if args.headless else None,
            extra_participants=[FLIGHT],
            seed=args.seed,
            packed=not args.process_per_service,
        )
    except ConfigError as exc:
        print(f"mjnav fly: {exc}", file=sys.stderr)
        return 2

    def fly(bus: Any) -> Any:
        summary = fly_on_bus(bus, stack.names(), plan, rtf)
        summary.seed = args.seed
        summary.controller, summary.state = args.controller, args.state
        summary.wind_mps, summary.gust_mps = args.wind, args.gust
        summary.wall_s = time.monotonic() - wall0
        return summary

    bus_config = BusConfig(mode="client", connect=(launcher.endpoint,))
    summary = run_beside_launcher(launcher, bus_config, stack.namespace, fly, "fly")
    if summary is None:
        return 1
    data = summary.to_dict()
    write_summary(data, out)
    print(
        f"{data['trajectory']} with {data['controller']} on {data['state']}: RMS {data['rms_error_m']} m, "
        f"max {data['max_error_m']} m; INS RMS {data['ins_rms_m']} m, GPS RMS {data['gps_rms_m']} m; "
        f"{data['time_s']} s sim at {data['achieved_rtf']}x real time; landed: {data['landed']}",
        file=sys.stderr,
    )
    if args.json:
        print(jsonsafe.dumps(data))
    return 0 if summary.landed and summary.collisions == 0 else 1


def fly_on_bus(bus: Any, services: list[str], plan: Any, rtf: float, *, stream_until_s: float | None = None) -> Any:
    """Wait for the UAV services, read the sim's origin and clock, fly ``plan`` with a `FlightClient`."""
    from mjnav.bus import wait_until
    from mjnav.runtime.flight import FlightClient

    if not wait_until(lambda: set(services) <= set(bus.alive_services(0.5)), 180.0):
        raise RuntimeError(f"services did not come up within 180 s (alive: {bus.alive_services(0.5)})")
    cfg = json.loads(bus.call("config", service="uav_sim", timeout_s=10.0).data)
    origin = (float(cfg["origin_lat_deg"]), float(cfg["origin_lon_deg"]), float(cfg["origin_alt_m"]))
    # The client steps every ~0.2 s of sim time (whole clock ticks), its resend period: the sim waits for it only
    # then (it measures on every tick).
    rate = float(cfg["clock_rate_hz"])
    period = max(1, round(0.2 * rate)) / rate
    client = FlightClient(bus, origin, name=FLIGHT, period_s=period, resend_s=period)
    timeout = plan.end_s + 30.0
    wall = 3.0 * timeout / (rtf if rtf > 0 else 5.0) + 120.0
    return client.fly(plan, timeout_s=timeout, wall_timeout_s=wall, stream_until_s=stream_until_s)

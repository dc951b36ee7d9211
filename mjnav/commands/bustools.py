"""Bus tools: ``mjnav topics``, ``mjnav echo KEY``, ``mjnav pub KEY``."""

from __future__ import annotations

import argparse
import json
import os
import sys
import threading
import time
from typing import Any

from mjnav import jsonsafe

_TOPICS_EPILOG = "Keys are <namespace>/<topic>; see the topic table in README.md."


def register(sub: Any) -> None:
    """Add ``topics``, ``echo`` and ``pub``."""
    from mjnav.bus import add_bus_arguments

    topics = sub.add_parser(
        "topics",
        help="list live keys with their type and rate",
        description="Listen to every key for a while and list what is being published, with rates, "
        "plus the services whose liveliness token is up. " + _TOPICS_EPILOG,
    )
    topics.add_argument("--duration", type=float, default=2.0, metavar="S", help="seconds to listen (default 2)")
    topics.add_argument("--ns", default="robot0", help="namespace whose services to list (default robot0)")
    topics.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    add_bus_arguments(topics)
    topics.set_defaults(func=run_topics)

    echo = sub.add_parser(
        "echo",
        help="print decoded messages of a key",
        description="Subscribe to KEY (e.g. robot0/odom, or robot0/status/* for every service) and print each "
        "decoded message as a JSON line (or YAML); enumerated fields get their name beside them (state_name: "
        "REACHED, error_code_name: ERROR_NO_PATH). Payloads that fail to decode or validate are reported on stderr. "
        + _TOPICS_EPILOG,
    )
    echo.add_argument("key", help="Zenoh key, e.g. robot0/scan")
    echo.add_argument("--count", type=int, metavar="N", help="exit after N messages")
    echo.add_argument("--timeout", type=float, metavar="S", help="exit with code 1 if no message within S seconds")
    echo.add_argument("--format", choices=("json", "yaml"), default="json", help="output format (default json)")
    add_bus_arguments(echo)
    echo.set_defaults(func=run_echo)

    pub = sub.add_parser(
        "pub",
        help="publish a message built from YAML",
        description="Publish a message of KEY's type built from YAML; fields left out take ROS defaults (0, '', [], "
        "a quaternion's w = 1). On an event topic (goal, cancel) every message asks for a delivery receipt and the "
        "command waits until each subscriber the topic table names (the planner) confirmed every message: exit 0, "
        "or exit 1 naming who did not within --timeout. On a snapshot topic it waits up to --timeout for any "
        "subscriber before the first message. " + _TOPICS_EPILOG,
        epilog="Examples: mjnav pub robot0/cmd_vel_teleop --yaml '{linear: {x: 0.25}, angular: {z: -0.5}}' "
        "--count 20   "
        "mjnav pub /robot0/goal --yaml '{header: {frame_id: map}, pose: {position: {x: -3.0, y: 2.0}}}'",
    )
    pub.add_argument("key", help="Zenoh key, e.g. robot0/cmd_vel")
    pub.add_argument("--yaml", default="{}", help="message fields as YAML (default: all defaults)")
    pub.add_argument("--count", type=int, default=1, metavar="N", help="messages to send (default 1)")
    pub.add_argument("--rate", type=float, default=10.0, metavar="HZ", help="send rate (default 10 Hz)")
    pub.add_argument(
        "--timeout", type=float, default=5.0, metavar="S", help="seconds to wait for subscribers/receipts (default 5)"
    )
    add_bus_arguments(pub)
    pub.set_defaults(func=run_pub)


def open_connected(args: argparse.Namespace, namespace: str) -> Any:
    """A bus for a command's ``--connect``/``--mode`` flags that reaches someone.

    Raises:
        BusUnavailable: no router or peer is reachable (a peer session opens fine with nobody to talk to, and the
            command would then wait for nothing).
        BusConfigError: bad bus flags or config file.
    """
    from mjnav.bus import Bus, BusUnavailable, bus_config_from_args

    config = bus_config_from_args(args)
    bus = Bus.open(config, namespace)
    if config.mode != "router" and not bus.connected():
        bus.close()
        raise BusUnavailable(f"no Zenoh router reachable at {', '.join(config.connect)} (is `mjnav up` running?)")
    return bus


def _resolve(key: str) -> tuple[str, Any, str | None]:
    from mjnav.msgs import resolve_key

    key = key.lstrip("/")  # ROS 2 spelling of the topic (/robot0/goal) is the same key
    namespace, row = resolve_key(key)
    service = key.rsplit("/", 1)[1] if row.per_service else None
    return namespace, row, service


#: Integer fields whose value is one of the message type's constants of this prefix (GoalStatus, ServiceStatus).
_NAMED_FIELDS = {"state": "STATE_", "error_code": "ERROR_"}


def with_constant_names(msg: Any, data: dict[str, Any]) -> dict[str, Any]:
    """``data`` (the dict of ``msg``) with ``<field>_name`` beside each enumerated integer field: ``"state": 4,
    "state_name": "REACHED"``, ``"error_code": 2, "error_code_name": "ERROR_GOAL_OCCUPIED"``."""
    out: dict[str, Any] = {}
    for key, value in data.items():
        out[key] = value
        prefix = _NAMED_FIELDS.get(key)
        if prefix is None or not isinstance(value, int):
            continue
        names = [n for n in dir(type(msg)) if n.startswith(prefix) and getattr(type(msg), n) == value]
        if names:
            out[f"{key}_name"] = names[0][len(prefix) :] if prefix == "STATE_" else names[0]
    return out


def run_topics(args: argparse.Namespace) -> int:
    """``mjnav topics``."""
    from mjnav.msgs import resolve_key

    counts: dict[str, int] = {}
    first: dict[str, float] = {}
    last: dict[str, float] = {}
    lock = threading.Lock()

    def on_sample(sample: Any) -> None:
        key = sample.key
        now = time.monotonic()
        with lock:
            counts[key] = counts.get(key, 0) + 1
            first.setdefault(key, now)
            last[key] = now

    alive_now: set[str] = set()

    def on_alive(service: str, up: bool) -> None:
        with lock:
            (alive_now.add if up else alive_now.discard)(service)

    from mjnav.bus import BusConfigError, BusUnavailable

    try:
        bus = open_connected(args, args.ns)
    except (BusUnavailable, BusConfigError) as exc:
        print(f"mjnav topics: {exc}", file=sys.stderr)
        return 1
    with bus:
        sub = bus.subscribe_raw("**", on_sample)
        bus.watch_alive(on_alive)  # tokens already up arrive during the window too, however slow the router is
        time.sleep(args.duration)  # listening window, not synchronisation
        sub.undeclare()
        with lock:
            alive = sorted(alive_now)
    rows: list[dict[str, Any]] = []
    for key in sorted(counts):
        try:
            _, row = resolve_key(key)
            msgtype, kind = row.msgtype, row.kind.value
        except KeyError:
            msgtype, kind = "?", "?"
        span = last[key] - first[key]
        rate = (counts[key] - 1) / span if counts[key] > 1 and span > 0 else 0.0
        rows.append(
            {
                "key": key,
                "type": msgtype,
                "delivery": kind,
                "rate_hz": round(rate, 2),
                "messages": counts[key],
            }
        )
    if args.json:
        print(json.dumps({"topics": rows, "services_alive": alive}))
        return 0
    if not rows:
        print(f"no messages in {args.duration:.1f} s")
    else:
        width = max(len(r["key"]) for r in rows)
        print(f"{'key':{width}s}  {'type':32s} {'delivery':9s} {'rate Hz':>8s} {'msgs':>6s}")
        for r in rows:
            print(f"{r['key']:{width}s}  {r['type']:32s} {r['delivery']:9s} {r['rate_hz']:8.2f} {r['messages']:6d}")
    print(f"services alive in {args.ns}: {', '.join(alive) if alive else 'none'}")
    return 0


def run_echo(args: argparse.Namespace) -> int:
    """``mjnav echo``."""
    import yaml

    from mjnav.msgs import to_dict

    try:
        namespace, row, service = _resolve(args.key)
    except (KeyError, ValueError) as exc:
        print(f"mjnav echo: {exc}", file=sys.stderr)
        return 2
    done = threading.Event()
    printed = 0
    lock = threading.Lock()

    def on_msg(msg: Any) -> None:
        nonlocal printed
        with lock:
            if done.is_set():
                return
            data = with_constant_names(msg, to_dict(msg))
            try:
                if args.format == "json":
                    sys.stdout.write(jsonsafe.dumps(data) + "\n")
                else:
                    sys.stdout.write("---\n" + yaml.safe_dump(data, sort_keys=False))
                sys.stdout.flush()
            except BrokenPipeError:  # the reader went away (e.g. `| head -1`): stop quietly
                done.set()
                return
            printed += 1
            if args.count is not None and printed >= args.count:
                done.set()

    from mjnav.bus import BusConfigError, BusUnavailable
    from mjnav.runtime.logs import setup_logging

    setup_logging("WARNING")
    try:
        bus = open_connected(args, namespace)
    except (BusUnavailable, BusConfigError) as exc:
        print(f"mjnav echo: {exc}", file=sys.stderr)
        return 1
    with bus:
        bus.subscribe(row.name, callback=on_msg, service=service)
        deadline = None if args.timeout is None else time.monotonic() + args.timeout
        try:
            while not done.wait(0.1):
                if deadline is not None and printed == 0 and time.monotonic() >= deadline:
                    print(f"mjnav echo: no message on {args.key} within {args.timeout} s", file=sys.stderr)
                    return 1
        except KeyboardInterrupt:
            pass
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        # Python would report the closed pipe again at exit: point stdout at /dev/null first.
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115
    return 0


def run_pub(args: argparse.Namespace) -> int:
    """``mjnav pub``."""
    import yaml

    from mjnav.bus import BusConfigError, BusUnavailable, NotDelivered
    from mjnav.msgs import Kind, MessageError, from_dict, validate

    try:
        namespace, row, service = _resolve(args.key)
        data = yaml.safe_load(args.yaml)
        msg = from_dict(row.msgtype, data if data is not None else {})
        validate(msg)
        if args.count < 1 or not args.rate > 0 or not args.timeout > 0:
            raise ValueError("--count must be >= 1, --rate and --timeout > 0")
    except (KeyError, ValueError, MessageError, yaml.YAMLError) as exc:
        print(f"mjnav pub: {exc}", file=sys.stderr)
        return 2
    try:
        bus = open_connected(args, namespace)
    except (BusUnavailable, BusConfigError) as exc:
        print(f"mjnav pub: {exc}", file=sys.stderr)
        return 1
    if row.kind is Kind.EVENT and row.subscribers:
        with bus:
            try:
                receipts = bus.put_confirmed(
                    row.name, [msg] * args.count, timeout_s=args.timeout, period_s=1.0 / args.rate
                )
            except NotDelivered as exc:
                print(f"mjnav pub: NOT DELIVERED: {exc}", file=sys.stderr)
                return 1
        who = ", ".join(f"{s} ({receipts[s]})" for s in row.subscribers)
        print(f"published {args.count} {row.msgtype} on {bus.key(row.name)}; received by {who}", file=sys.stderr)
        return 0
    with bus:
        pub = bus.publisher(row.name, service=service)
        if not pub.wait_for_subscribers(args.timeout):
            print(f"mjnav pub: no subscriber on {pub.key} yet; publishing anyway", file=sys.stderr)
        period = 1.0 / args.rate
        start = time.monotonic()
        for i in range(args.count):
            if i:
                time.sleep(max(0.0, start + i * period - time.monotonic()))  # pacing at --rate
            pub.put(msg)
        print(f"published {args.count} {row.msgtype} on {pub.key}", file=sys.stderr)
    return 0

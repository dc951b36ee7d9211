"""Zenoh session configuration, layered: defaults → config file → command-line flags → environment.

Defaults keep everything on this machine: peer mode, multicast scouting off, listening on loopback only, and
connecting to a router at ``tcp/127.0.0.1:7447`` (what ``mjnav up`` starts).

Config file (TOML), all keys optional::

    mode = "peer"                      # peer | client | router
    connect = ["tcp/127.0.0.1:7447"]
    listen = ["tcp/127.0.0.1:0"]
    multicast_scouting = false

Environment (wins over flags, so containers can be pointed elsewhere without touching commands):
``MJNAV_ZENOH_CONFIG`` (file path), ``MJNAV_ZENOH_MODE``, ``MJNAV_ZENOH_CONNECT`` and ``MJNAV_ZENOH_LISTEN``
(comma-separated endpoints), ``MJNAV_ZENOH_MULTICAST`` (``1``/``0``).
"""

from __future__ import annotations

import argparse
import json
import os
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

DEFAULT_PORT = 7447
DEFAULT_ROUTER = f"tcp/127.0.0.1:{DEFAULT_PORT}"
MODES = ("peer", "client", "router")


class BusConfigError(ValueError):
    """A bus configuration value that cannot be used (bad mode, endpoint, file)."""


@dataclass(frozen=True, slots=True)
class BusConfig:
    """How a process joins the Zenoh network.

    Attributes:
        mode: ``peer``, ``client`` or ``router``.
        connect: endpoints to connect to, e.g. ``("tcp/127.0.0.1:7447",)``.
        listen: endpoints to listen on; ``tcp/127.0.0.1:0`` picks a free loopback port.
        multicast_scouting: discover peers by UDP multicast (off by default: explicit endpoints only).
        connect_timeout_s: give up opening the session when no ``connect`` endpoint answers within this many
            seconds (:class:`~mjnav.bus.BusUnavailable`); None (services) keeps retrying until a router appears.
    """

    mode: str = "peer"
    connect: tuple[str, ...] = (DEFAULT_ROUTER,)
    listen: tuple[str, ...] = ("tcp/127.0.0.1:0",)
    multicast_scouting: bool = False
    connect_timeout_s: float | None = None

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise BusConfigError(f"zenoh mode must be one of {MODES}, got {self.mode!r}")
        for endpoint in (*self.connect, *self.listen):
            _check_endpoint(endpoint)
        if self.connect_timeout_s is not None and not self.connect_timeout_s > 0:
            raise BusConfigError(f"connect_timeout_s must be > 0, got {self.connect_timeout_s}")

    def to_zenoh(self) -> Any:
        """A ``zenoh.Config`` for this configuration."""
        import zenoh

        cfg = zenoh.Config()
        cfg.insert_json5("mode", json.dumps(self.mode))
        cfg.insert_json5("connect/endpoints", json.dumps(list(self.connect)))
        cfg.insert_json5("listen/endpoints", json.dumps(list(self.listen)))
        cfg.insert_json5("scouting/multicast/enabled", json.dumps(self.multicast_scouting))
        if self.mode != "router":
            if self.connect_timeout_s is None:
                # Keep retrying the router instead of failing when a service starts before it.
                cfg.insert_json5("connect/timeout_ms", json.dumps(-1))
                cfg.insert_json5("connect/exit_on_failure", json.dumps(False))
            else:
                cfg.insert_json5("connect/timeout_ms", json.dumps(max(1, round(1000 * self.connect_timeout_s))))
                cfg.insert_json5("connect/exit_on_failure", json.dumps(True))
        return cfg


def _check_endpoint(endpoint: str) -> None:
    proto, sep, rest = endpoint.partition("/")
    if not sep or not proto or not rest:
        raise BusConfigError(f"invalid zenoh endpoint {endpoint!r}: expected e.g. tcp/127.0.0.1:7447")


def _split(value: str) -> tuple[str, ...]:
    return tuple(part.strip() for part in value.split(",") if part.strip())


def _from_mapping(base: BusConfig, data: Mapping[str, Any], where: str) -> BusConfig:
    known = {"mode", "connect", "listen", "multicast_scouting"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise BusConfigError(f"{where}: unknown key(s) {unknown}; known: {sorted(known)}")
    changes: dict[str, Any] = {}
    if "mode" in data:
        changes["mode"] = str(data["mode"])
    for key in ("connect", "listen"):
        if key in data:
            value = data[key]
            if isinstance(value, str):
                value = [value]
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                raise BusConfigError(f"{where}: {key} must be a list of endpoint strings")
            changes[key] = tuple(value)
    if "multicast_scouting" in data:
        if not isinstance(data["multicast_scouting"], bool):
            raise BusConfigError(f"{where}: multicast_scouting must be true or false")
        changes["multicast_scouting"] = data["multicast_scouting"]
    return replace(base, **changes)


def load_bus_config(
    *,
    config_file: str | Path | None = None,
    mode: str | None = None,
    connect: Sequence[str] | None = None,
    listen: Sequence[str] | None = None,
    env: Mapping[str, str] | None = None,
) -> BusConfig:
    """Resolve the bus configuration from its four layers (later layers win).

    Args:
        config_file: TOML file (see the module docstring); ``MJNAV_ZENOH_CONFIG`` names one too.
        mode, connect, listen: command-line values (``None`` = not given).
        env: environment to read (default ``os.environ``).
    """
    env = os.environ if env is None else env
    cfg = BusConfig()
    file = env.get("MJNAV_ZENOH_CONFIG") or config_file
    if file:
        path = Path(file)
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except OSError as exc:
            raise BusConfigError(f"cannot read bus config {path}: {exc.strerror}") from exc
        except tomllib.TOMLDecodeError as exc:
            raise BusConfigError(f"bus config {path} is not valid TOML: {exc}") from exc
        cfg = _from_mapping(cfg, data, str(path))
    flags: dict[str, Any] = {}
    if mode is not None:
        flags["mode"] = mode
    if connect:
        flags["connect"] = tuple(connect)
    if listen:
        flags["listen"] = tuple(listen)
    cfg = replace(cfg, **flags)
    env_changes: dict[str, Any] = {}
    if env.get("MJNAV_ZENOH_MODE"):
        env_changes["mode"] = env["MJNAV_ZENOH_MODE"]
    if env.get("MJNAV_ZENOH_CONNECT"):
        env_changes["connect"] = _split(env["MJNAV_ZENOH_CONNECT"])
    if env.get("MJNAV_ZENOH_LISTEN"):
        env_changes["listen"] = _split(env["MJNAV_ZENOH_LISTEN"])
    if env.get("MJNAV_ZENOH_MULTICAST"):
        env_changes["multicast_scouting"] = env["MJNAV_ZENOH_MULTICAST"].strip().lower() in (
            "1",
            "true",
            "yes",
        )
    return replace(cfg, **env_changes)


def add_bus_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--connect``, ``--listen``, ``--mode`` and ``--bus-config`` to a command's parser."""
    group = parser.add_argument_group("zenoh bus")
    group.add_argument(
        "--connect",
        action="append",
        metavar="ENDPOINT",
        help=f"Zenoh endpoint to connect to (repeatable; default {DEFAULT_ROUTER}, env MJNAV_ZENOH_CONNECT)",
    )
    group.add_argument(
        "--listen",
        action="append",
        metavar="ENDPOINT",
        help="endpoint to listen on (repeatable; default tcp/127.0.0.1:0, env MJNAV_ZENOH_LISTEN)",
    )
    group.add_argument("--mode", choices=MODES, help="Zenoh mode (default peer, env MJNAV_ZENOH_MODE)")
    group.add_argument(
        "--bus-config", metavar="FILE", help="TOML file with mode/connect/listen (env MJNAV_ZENOH_CONFIG)"
    )


def bus_config_from_args(args: argparse.Namespace) -> BusConfig:
    """Resolve the layered configuration for a command that used :func:`add_bus_arguments`."""
    return load_bus_config(config_file=args.bus_config, mode=args.mode, connect=args.connect, listen=args.listen)

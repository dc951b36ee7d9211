"""Zenoh session configuration, layered: defaults → config file → command-line flags → environment.

Defaults keep everything on this machine: peer mode, multicast scouting off, listening on loopback only, and
connecting to a router at ``tcp/127.0.0.1:7447`` (what ``mjnav up`` starts).

Config file (TOML), all keys optional::

    mode = "peer"                      # peer | client | router
    connect = ["tcp/127.0.0.1:7447"]
    listen = ["tcp/127.0.0.1:0"]
    multicast_scouting = false
    tls_ca = "certs/ca.crt"            # TLS: the CA that signed the router's and the clients' certificates
    tls_cert = "certs/planner.crt"     # this process's certificate (its common name is its identity)
    tls_key = "certs/planner.key"

Environment (wins over flags, so containers can be pointed elsewhere without touching commands):
``MJNAV_ZENOH_CONFIG`` (file path), ``MJNAV_ZENOH_MODE``, ``MJNAV_ZENOH_CONNECT`` and ``MJNAV_ZENOH_LISTEN``
(comma-separated endpoints), ``MJNAV_ZENOH_MULTICAST`` (``1``/``0``), ``MJNAV_ZENOH_TLS_CA``,
``MJNAV_ZENOH_TLS_CERT`` and ``MJNAV_ZENOH_TLS_KEY`` (file paths).

TLS (``mjnav up --secure DIR``, certificates from ``mjnav certs``): with ``tls_ca`` set every endpoint must be
``tls/…``; the default endpoints then become ``tls/127.0.0.1:7447`` (connect) and none (listen), so no plain-TCP
side door stays open. A router with a certificate requires one from every client (mutual TLS).
"""

from __future__ import annotations

import argparse
import json
import os
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypedDict

DEFAULT_PORT = 7447
DEFAULT_ROUTER = f"tcp/127.0.0.1:{DEFAULT_PORT}"
#: The router endpoint clients connect to by default when TLS is on.
DEFAULT_TLS_ROUTER = f"tls/127.0.0.1:{DEFAULT_PORT}"
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
        tls_ca: PEM file of the CA every TLS certificate is checked against ("" = no TLS).
        tls_cert: PEM certificate of this process: a router's server certificate (then clients must present one
            too: mutual TLS), or a client's certificate, whose common name is its identity for access control.
        tls_key: PEM private key of ``tls_cert``.
        access_control: the ``access_control`` section of a router's Zenoh config, as JSON (see
            :func:`mjnav.bus.acl.access_control`; "" = none). Needs a router with a certificate.
    """

    mode: str = "peer"
    connect: tuple[str, ...] = (DEFAULT_ROUTER,)
    listen: tuple[str, ...] = ("tcp/127.0.0.1:0",)
    multicast_scouting: bool = False
    connect_timeout_s: float | None = None
    tls_ca: str = ""
    tls_cert: str = ""
    tls_key: str = ""
    access_control: str = ""

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise BusConfigError(f"zenoh mode must be one of {MODES}, got {self.mode!r}")
        for endpoint in (*self.connect, *self.listen):
            _check_endpoint(endpoint)
        if self.connect_timeout_s is not None and not self.connect_timeout_s > 0:
            raise BusConfigError(f"connect_timeout_s must be > 0, got {self.connect_timeout_s}")
        self._check_tls()

    @property
    def tls(self) -> bool:
        """Whether links use TLS (``tls_ca`` is set)."""
        return bool(self.tls_ca)

    def _check_tls(self) -> None:
        if bool(self.tls_cert) != bool(self.tls_key):
            raise BusConfigError("tls_cert and tls_key go together: give both or neither")
        if (self.tls_cert or self.access_control) and not self.tls_ca:
            raise BusConfigError("tls_ca is missing: a certificate or access control needs the CA to check peers")
        if self.tls:
            plain = [e for e in (*self.connect, *self.listen) if not e.startswith("tls/")]
            if plain:
                raise BusConfigError(
                    f"TLS is on but endpoint(s) {plain} are not tls/…: they would accept unauthenticated links"
                )
            if self.mode == "router" and not self.tls_cert:
                raise BusConfigError("a TLS router needs its certificate: set tls_cert and tls_key")
        if self.access_control and (self.mode != "router" or not self.tls_cert):
            raise BusConfigError("access_control needs a router with a certificate (identities come from TLS)")

    def to_zenoh(self) -> Any:
        """A ``zenoh.Config`` for this configuration."""
        import zenoh

        cfg = zenoh.Config()
        cfg.insert_json5("mode", json.dumps(self.mode))
        cfg.insert_json5("connect/endpoints", json.dumps(list(self.connect)))
        cfg.insert_json5("listen/endpoints", json.dumps(list(self.listen)))
        cfg.insert_json5("scouting/multicast/enabled", json.dumps(self.multicast_scouting))
        # Zenoh's shared-memory transport (on by default: payloads over 3 KB go through a 16 MB pool in /dev/shm)
        # maps segments that closing a session does not release (+4 open segments, +39 MB per session in a process
        # that opens many: tests, benchmarks) and that a killed process leaves in /dev/shm; it bought no measurable
        # speed here (interleaved maze runs). Loopback TCP carries everything.
        cfg.insert_json5("transport/shared_memory/enabled", "false")
        if self.mode == "router" and not self.connect and not self.multicast_scouting:
            # Zenoh holds open() back for its scouting delay (500 ms) to discover peers first; a router that
            # connects nowhere and does not scout has none to discover.
            cfg.insert_json5("scouting/delay", "0")
        if self.mode != "router":
            if self.connect_timeout_s is None:
                # Keep retrying the router instead of failing when a service starts before it.
                cfg.insert_json5("connect/timeout_ms", json.dumps(-1))
                cfg.insert_json5("connect/exit_on_failure", json.dumps(False))
            else:
                cfg.insert_json5("connect/timeout_ms", json.dumps(max(1, round(1000 * self.connect_timeout_s))))
                cfg.insert_json5("connect/exit_on_failure", json.dumps(True))
        if self.tls:
            tls = "transport/link/tls/"
            cfg.insert_json5(tls + "root_ca_certificate", json.dumps(self.tls_ca))
            cfg.insert_json5(tls + "verify_name_on_connect", json.dumps(True))
            if self.tls_cert:
                # Presented when connecting and, on a router, when accepting; a router then requires client
                # certificates (mutual TLS): the common name of each is its identity for access control.
                for side in ("connect", "listen"):
                    cfg.insert_json5(tls + f"{side}_certificate", json.dumps(self.tls_cert))
                    cfg.insert_json5(tls + f"{side}_private_key", json.dumps(self.tls_key))
                cfg.insert_json5(tls + "enable_mtls", json.dumps(True))
        if self.access_control:
            cfg.insert_json5("access_control", self.access_control)
        return cfg


def _check_endpoint(endpoint: str) -> None:
    proto, sep, rest = endpoint.partition("/")
    if not sep or not proto or not rest:
        raise BusConfigError(f"invalid zenoh endpoint {endpoint!r}: expected e.g. tcp/127.0.0.1:7447")


def _split(value: str) -> tuple[str, ...]:
    return tuple(part.strip() for part in value.split(",") if part.strip())


def _from_mapping(data: Mapping[str, Any], where: Path) -> dict[str, Any]:
    """The values a config file sets (relative TLS paths are relative to the file)."""
    known = {"mode", "connect", "listen", "multicast_scouting", "tls_ca", "tls_cert", "tls_key"}
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
    for key in ("tls_ca", "tls_cert", "tls_key"):
        if key in data:
            if not isinstance(data[key], str) or not data[key]:
                raise BusConfigError(f"{where}: {key} must be a file path")
            changes[key] = str(where.parent / data[key])
    return changes


class TlsFiles(TypedDict):
    """The TLS fields of :class:`BusConfig` for one identity (``BusConfig(..., **files)``)."""

    tls_ca: str
    tls_cert: str
    tls_key: str


def tls_files(directory: str | Path, identity: str) -> TlsFiles:
    """``tls_ca``, ``tls_cert`` and ``tls_key`` of ``identity`` in a folder written by ``mjnav certs``.

    Raises:
        BusConfigError: a file is missing (the message says how to make them).
    """
    d = Path(directory)
    files = {"tls_ca": d / "ca.crt", "tls_cert": d / f"{identity}.crt", "tls_key": d / f"{identity}.key"}
    missing = [str(f) for f in files.values() if not f.is_file()]
    if missing:
        raise BusConfigError(
            f"no TLS files for {identity!r} in {d} (missing {', '.join(missing)}): "
            f"run 'mjnav certs --out {d}' (add '--client {identity}' for an identity that is not a service)"
        )
    return TlsFiles(
        tls_ca=str(files["tls_ca"].resolve()),
        tls_cert=str(files["tls_cert"].resolve()),
        tls_key=str(files["tls_key"].resolve()),
    )


def tls_env(directory: str | Path, identity: str) -> dict[str, str]:
    """The ``MJNAV_ZENOH_TLS_*`` environment that gives a child process ``identity``'s TLS files
    (:func:`tls_files`)."""
    files = tls_files(directory, identity)
    return {
        "MJNAV_ZENOH_TLS_CA": files["tls_ca"],
        "MJNAV_ZENOH_TLS_CERT": files["tls_cert"],
        "MJNAV_ZENOH_TLS_KEY": files["tls_key"],
    }


def load_bus_config(
    *,
    config_file: str | Path | None = None,
    mode: str | None = None,
    connect: Sequence[str] | None = None,
    listen: Sequence[str] | None = None,
    tls: TlsFiles | None = None,
    env: Mapping[str, str] | None = None,
) -> BusConfig:
    """Resolve the bus configuration from its four layers (later layers win).

    Args:
        config_file: TOML file (see the module docstring); ``MJNAV_ZENOH_CONFIG`` names one too.
        mode, connect, listen: command-line values (``None`` = not given).
        tls: command-line TLS files, keys ``tls_ca``, ``tls_cert``, ``tls_key`` (e.g. from :func:`tls_files`).
        env: environment to read (default ``os.environ``).
    """
    env = os.environ if env is None else env
    values: dict[str, Any] = {}
    file = env.get("MJNAV_ZENOH_CONFIG") or config_file
    if file:
        path = Path(file)
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except OSError as exc:
            raise BusConfigError(f"cannot read bus config {path}: {exc.strerror}") from exc
        except tomllib.TOMLDecodeError as exc:
            raise BusConfigError(f"bus config {path} is not valid TOML: {exc}") from exc
        values.update(_from_mapping(data, path))
    if mode is not None:
        values["mode"] = mode
    if connect:
        values["connect"] = tuple(connect)
    if listen:
        values["listen"] = tuple(listen)
    if tls is not None:
        values.update(tls)
    if env.get("MJNAV_ZENOH_MODE"):
        values["mode"] = env["MJNAV_ZENOH_MODE"]
    if env.get("MJNAV_ZENOH_CONNECT"):
        values["connect"] = _split(env["MJNAV_ZENOH_CONNECT"])
    if env.get("MJNAV_ZENOH_LISTEN"):
        values["listen"] = _split(env["MJNAV_ZENOH_LISTEN"])
    if env.get("MJNAV_ZENOH_MULTICAST"):
        values["multicast_scouting"] = env["MJNAV_ZENOH_MULTICAST"].strip().lower() in ("1", "true", "yes")
    for key in ("tls_ca", "tls_cert", "tls_key"):
        if env.get(f"MJNAV_ZENOH_{key.upper()}"):
            values[key] = env[f"MJNAV_ZENOH_{key.upper()}"]
    if values.get("tls_ca"):
        # With TLS the defaults must not leave a plain-TCP way in: connect over TLS, listen nowhere (a router is
        # always given its endpoints).
        values.setdefault("connect", (DEFAULT_TLS_ROUTER,))
        if values.get("mode", "peer") != "router":
            values.setdefault("listen", ())
    return BusConfig(**values)


def add_bus_arguments(parser: argparse.ArgumentParser, *, identity: str | None = "operator") -> None:
    """Add ``--connect``, ``--listen``, ``--mode``, ``--bus-config`` and ``--secure`` to a command's parser.

    Args:
        parser: the command's parser.
        identity: whose certificate ``--secure DIR`` uses by default (None: the command decides, e.g. the service
            of ``mjnav run``); ``--identity`` overrides it.
    """
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
        "--bus-config", metavar="FILE", help="TOML file with mode/connect/listen/tls_* (env MJNAV_ZENOH_CONFIG)"
    )
    group.add_argument(
        "--secure",
        metavar="DIR",
        help=f"join a 'mjnav up --secure' stack over mutual TLS with the certificates in DIR ('mjnav certs'); "
        f"default endpoint then {DEFAULT_TLS_ROUTER} (env MJNAV_ZENOH_TLS_CA/CERT/KEY)",
    )
    group.add_argument(
        "--identity",
        metavar="NAME",
        default=identity,
        help=f"whose certificate --secure uses (default {identity or 'the service'}); its rights depend on it",
    )


def bus_config_from_args(args: argparse.Namespace, identity: str | None = None) -> BusConfig:
    """Resolve the layered configuration for a command that used :func:`add_bus_arguments`.

    Args:
        args: the parsed arguments.
        identity: the certificate ``--secure`` uses when ``--identity`` is not given.
    """
    who = args.identity or identity
    if args.secure and not who:
        raise BusConfigError("--secure needs --identity NAME")
    tls = tls_files(args.secure, who) if args.secure and who else None
    return load_bus_config(
        config_file=args.bus_config, mode=args.mode, connect=args.connect, listen=args.listen, tls=tls
    )

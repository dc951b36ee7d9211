"""The stack definition: which services exist, where their code and config live, how they are run.

``services/stack.toml`` (one file, read by ``mjnav up``, ``mjnav run`` and checked against docker compose)::

    namespace = "robot0"

    [[service]]
    name = "sim"                                  # service name: status key, liveliness token
    class = "mjnav.services.sim:SimService"       # module:Class of the Service subclass
    config = "sim.toml"                           # relative to the stack file
    restarts = 3                                  # how often the launcher restarts it after a crash

    [[container]]                                 # optional: services that share one process
    name = "nav"                                  # the process's name (``mjnav run nav``)
    services = ["slam", "mapper", "planner"]      # stepped in this order, on one clock (sim or wall time)
    restarts = 3                                  # the container restarts as a unit

How services are packed into processes is a deployment choice (ROS 2's composition): the services of a container
share one Zenoh session and one clock, and what they send each other stays in the process; every service that is
in no container runs in a process of its own. ``mjnav up --process-per-service`` ignores the containers.
"""

from __future__ import annotations

import dataclasses
import importlib
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import mjnav
from mjnav.msgs.topics import DEFAULT_NAMESPACE, check_namespace
from mjnav.runtime.config import ConfigError, build_config, parse_override, read_toml
from mjnav.runtime.service import Service

#: Services a stack runs only when asked (``mjnav up --ros rmw_zenoh``, ``--foxglove``): name → ``module:Class``.
#: Their config is ``<name>.toml`` beside the stack file (all defaults when there is none).
OPTIONAL_SERVICES = {
    "ros_bridge": "mjnav.services.ros_bridge:RosBridgeService",
    "foxglove": "mjnav.services.foxglove:FoxgloveService",
}


def services_dir() -> Path:
    """The folder holding the stack and service configs: ``$MJNAV_SERVICES_DIR`` or ``<repo>/services``."""
    env = os.environ.get("MJNAV_SERVICES_DIR")
    return Path(env) if env else mjnav.REPO_ROOT / "services"


def default_stack_file() -> Path:
    """``services/stack.toml``."""
    return services_dir() / "stack.toml"


@dataclass(frozen=True, slots=True)
class ServiceSpec:
    """One service of the stack.

    Attributes:
        name: service name.
        class_path: ``module:Class`` of its :class:`~mjnav.runtime.service.Service` subclass.
        config_file: its TOML config (absolute), or None for all defaults.
        restarts: restarts the launcher allows after crashes.
    """

    name: str
    class_path: str
    config_file: Path | None
    restarts: int = 3

    def load_class(self) -> type[Service[Any]]:
        """Import the service class."""
        module_name, _, cls_name = self.class_path.partition(":")
        if not cls_name:
            raise ConfigError(f"service {self.name}: class must be 'module:Class', got {self.class_path!r}")
        try:
            module = importlib.import_module(module_name)
        except ImportError as exc:
            raise ConfigError(f"service {self.name}: cannot import {module_name}: {exc}") from exc
        cls = getattr(module, cls_name, None)
        if not (isinstance(cls, type) and issubclass(cls, Service)):
            raise ConfigError(f"service {self.name}: {self.class_path} is not a Service subclass")
        return cls

    def load_config(self, overrides: dict[str, Any] | None = None) -> Any:
        """The validated config dataclass: file values, then ``overrides`` (from ``--set key=value``)."""
        cls = self.load_class()
        data: dict[str, Any] = read_toml(self.config_file) if self.config_file else {}
        data.update(overrides or {})
        where = str(self.config_file) if self.config_file else f"{self.name} config"
        config = build_config(cls.config_class, data, where)
        rate = getattr(config, "rate_hz", None)
        if not isinstance(rate, float) or not rate > 0:
            raise ConfigError(f"{where}: rate_hz must be a positive number")
        return config


@dataclass(frozen=True, slots=True)
class ProcessSpec:
    """One process of a deployment: a service alone, or the services of a container.

    Attributes:
        name: the container's name, or the service's when it runs alone.
        services: what it hosts, in the order they step (a container's own list).
        restarts: restarts the launcher allows after crashes (the process restarts as a unit).
    """

    name: str
    services: tuple[ServiceSpec, ...]
    restarts: int

    @property
    def container(self) -> bool:
        """Whether it hosts several services."""
        return len(self.services) > 1

    def service_names(self) -> list[str]:
        """Names of the services it hosts."""
        return [s.name for s in self.services]

    def check_clocks(self) -> None:
        """The services of one process step on one clock, and none of them must run alone.

        Raises:
            ConfigError: a container mixing sim-time and wall-time services, or hosting one that runs alone
                (:attr:`~mjnav.runtime.service.Service.runs_alone`).
        """
        classes = {spec.name: spec.load_class() for spec in self.services}
        alone = [n for n, cls in classes.items() if cls.runs_alone]
        if alone and self.container:
            raise ConfigError(f"container {self.name}: {', '.join(alone)} must run in a process of its own")
        kinds = {n: cls.uses_sim_time for n, cls in classes.items()}
        if len(set(kinds.values())) > 1:
            clocks = ", ".join(f"{n} ({'sim' if sim else 'wall'} time)" for n, sim in kinds.items())
            raise ConfigError(f"container {self.name}: its services must step on one clock, sim or wall time: {clocks}")


@dataclass(frozen=True, slots=True)
class Stack:
    """The services to run, in start order (the launcher stops them in reverse), and the containers that pack some
    of them into shared processes."""

    path: Path
    namespace: str
    services: tuple[ServiceSpec, ...]
    containers: tuple[tuple[str, tuple[str, ...], int], ...] = ()  # (name, service names, restarts)

    def names(self) -> list[str]:
        """Service names in start order."""
        return [s.name for s in self.services]

    def get(self, name: str) -> ServiceSpec:
        """The service called ``name``; ConfigError lists the known ones."""
        for spec in self.services:
            if spec.name == name:
                return spec
        class_path = OPTIONAL_SERVICES.get(name)
        if class_path is not None:
            config = self.path.parent / f"{name}.toml"
            return ServiceSpec(name, class_path, config if config.is_file() else None)
        optional = ", ".join(OPTIONAL_SERVICES)
        raise ConfigError(
            f"no service {name!r} in {self.path}; services: {', '.join(self.names())} (optional: {optional})"
        )

    def with_services(self, names: list[str]) -> Stack:
        """This stack with the optional services ``names`` appended (those it runs already are kept as they are).

        Raises:
            ConfigError: a name is neither in the stack nor optional.
        """
        extra = tuple(self.get(name) for name in names if name not in self.names())
        return dataclasses.replace(self, services=self.services + extra)

    def select(self, only: list[str] | None) -> list[ServiceSpec]:
        """The services named in ``only`` (all when None), in stack order; unknown names are an error."""
        if not only:
            return list(self.services)
        for name in only:
            self.get(name)
        return [s for s in self.services if s.name in only]

    def container(self, name: str) -> ProcessSpec | None:
        """The container called ``name`` with all its services (None when there is none)."""
        for cname, members, restarts in self.containers:
            if cname == name:
                return ProcessSpec(cname, tuple(self.get(m) for m in members), restarts)
        return None

    def processes(self, specs: list[ServiceSpec], *, packed: bool = True) -> list[ProcessSpec]:
        """How ``specs`` (from :meth:`select`) run: the selected members of each container in one process (with
        ``packed``), in the container's order, every other service alone (so is a container's only selected member);
        processes in start order (a container where its first member is).

        Raises:
            ConfigError: a container mixing sim-time and wall-time services.
        """
        where = {m: (cname, restarts) for cname, members, restarts in self.containers for m in members}
        rank = {m: i for _, members, _ in self.containers for i, m in enumerate(members)}
        out: list[ProcessSpec] = []
        placed: dict[str, int] = {}  # container name -> index in out
        for spec in specs:
            home = where.get(spec.name) if packed else None
            if home is None:
                out.append(ProcessSpec(spec.name, (spec,), spec.restarts))
            elif home[0] in placed:
                i = placed[home[0]]
                out[i] = ProcessSpec(out[i].name, (*out[i].services, spec), out[i].restarts)
            else:
                placed[home[0]] = len(out)
                out.append(ProcessSpec(home[0], (spec,), home[1]))
        # a container steps its services in the order it lists them; one with a single selected member is that
        # service alone
        out = [
            replace(p, services=tuple(sorted(p.services, key=lambda s: rank[s.name])))
            if p.container
            else ProcessSpec(p.services[0].name, p.services, p.services[0].restarts)
            for p in out
        ]
        for proc in out:
            proc.check_clocks()
        return out


def load_stack(path: str | Path | None = None) -> Stack:
    """Read a stack file (default ``services/stack.toml``)."""
    p = Path(path) if path else default_stack_file()
    data = read_toml(p)
    unknown = sorted(set(data) - {"namespace", "service", "container"})
    if unknown:
        raise ConfigError(f"{p}: unknown key(s) {unknown}; expected 'namespace', [[service]] and [[container]] tables")
    namespace = data.get("namespace", DEFAULT_NAMESPACE)
    try:
        check_namespace(namespace)
    except ValueError as exc:
        raise ConfigError(f"{p}: {exc}") from exc
    specs = []
    seen = set()
    for i, entry in enumerate(data.get("service", [])):
        where = f"{p}: service #{i + 1}"
        unknown = sorted(set(entry) - {"name", "class", "config", "restarts"})
        if unknown:
            raise ConfigError(f"{where}: unknown key(s) {unknown}")
        name, class_path = entry.get("name"), entry.get("class")
        if not isinstance(name, str) or not name.isidentifier():
            raise ConfigError(f"{where}: 'name' must be an identifier, got {name!r}")
        if name in seen:
            raise ConfigError(f"{where}: duplicate service name {name!r}")
        if not isinstance(class_path, str):
            raise ConfigError(f"{where}: 'class' (module:Class) is required")
        restarts = _restarts(entry, where)
        config = entry.get("config")
        specs.append(ServiceSpec(name, class_path, (p.parent / config) if config else None, restarts))
        seen.add(name)
    if not specs:
        raise ConfigError(f"{p}: defines no [[service]]")
    return Stack(p, namespace, tuple(specs), _containers(p, data.get("container", []), seen))


def _restarts(entry: dict[str, Any], where: str) -> int:
    restarts = entry.get("restarts", 3)
    if isinstance(restarts, bool) or not isinstance(restarts, int) or restarts < 0:
        raise ConfigError(f"{where}: 'restarts' must be a non-negative integer")
    return restarts


def _containers(p: Path, entries: list[Any], services: set[str]) -> tuple[tuple[str, tuple[str, ...], int], ...]:
    """The ``[[container]]`` tables: each a new name and at least one service of the stack, no service in two."""
    out: list[tuple[str, tuple[str, ...], int]] = []
    housed: dict[str, str] = {}
    for i, entry in enumerate(entries):
        where = f"{p}: container #{i + 1}"
        unknown = sorted(set(entry) - {"name", "services", "restarts"})
        if unknown:
            raise ConfigError(f"{where}: unknown key(s) {unknown}; expected name, services, restarts")
        name, members = entry.get("name"), entry.get("services")
        if not isinstance(name, str) or not name.isidentifier():
            raise ConfigError(f"{where}: 'name' must be an identifier, got {name!r}")
        if name in services or any(name == c for c, _, _ in out):
            raise ConfigError(f"{where}: the name {name!r} is taken by a service or another container")
        if not (isinstance(members, list) and members and all(isinstance(m, str) for m in members)):
            raise ConfigError(f"{where}: 'services' must be a non-empty list of service names")
        for m in members:
            if m not in services:
                raise ConfigError(f"{where}: no service {m!r} in the stack; services: {', '.join(sorted(services))}")
            if m in housed:
                raise ConfigError(f"{where}: {m} is already in container {housed[m]}")
            housed[m] = name
        out.append((name, tuple(members), _restarts(entry, where)))
    return tuple(out)


def port_overrides(specs: list[ServiceSpec], base: int) -> dict[str, list[str]]:
    """``--port BASE``: every port the services open, numbered after the router's: BASE + 1, BASE + 2, … in the order
    of ``specs`` and of each service's :attr:`~mjnav.runtime.service.Service.port_settings`, with no search for
    a free one (``port_search = 0`` where a service has it): one base moves them all, and a taken port is an error
    (:meth:`mjnav.runtime.launcher.Launcher.check`), never a silent move to another.

    Raises:
        ConfigError: a port beyond 65535.
    """
    out: dict[str, list[str]] = {}
    port = base
    for spec in specs:
        cls = spec.load_class()
        for key in cls.port_settings:
            port += 1
            if port > 65535:
                raise ConfigError(f"--port {base}: {spec.name}.{key} would be {port}, beyond 65535")
            out.setdefault(spec.name, []).append(f"{key}={port}")
        if cls.port_settings and "port_search" in {f.name for f in dataclasses.fields(cls.config_class)}:
            out[spec.name].append("port_search=0")
    return out


def add_service_overrides(stack: Stack, items: list[str], overrides: dict[str, list[str]]) -> None:
    """Check ``SERVICE.KEY=VALUE`` items (``--set`` of ``mjnav up`` and ``mjnav demo``) and append them to
    ``overrides[SERVICE]`` as ``KEY=VALUE``.

    Raises:
        ConfigError: malformed item or unknown service.
    """
    for item in items:
        target, _, rest = item.partition(".")
        if not rest or "=" not in rest:
            raise ConfigError(f"--set {item!r} must look like SERVICE.KEY=VALUE")
        stack.get(target)
        parse_override(rest)
        overrides.setdefault(target, []).append(rest)

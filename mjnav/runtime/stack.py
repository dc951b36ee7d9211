"""The stack definition: which services exist, where their code and config live, how they are run.

``services/stack.toml`` (one file, read by ``mjnav up``, ``mjnav run`` and checked against docker compose)::

    namespace = "robot0"

    [[service]]
    name = "sim"                                  # service name: status key, liveliness token
    class = "mjnav.services.sim:SimService"       # module:Class of the Service subclass
    config = "sim.toml"                           # relative to the stack file
    restarts = 3                                  # how often the launcher restarts it after a crash
"""

from __future__ import annotations

import dataclasses
import importlib
import os
from dataclasses import dataclass
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
class Stack:
    """The services to run, in start order (the launcher stops them in reverse)."""

    path: Path
    namespace: str
    services: tuple[ServiceSpec, ...]

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


def load_stack(path: str | Path | None = None) -> Stack:
    """Read a stack file (default ``services/stack.toml``)."""
    p = Path(path) if path else default_stack_file()
    data = read_toml(p)
    unknown = sorted(set(data) - {"namespace", "service"})
    if unknown:
        raise ConfigError(f"{p}: unknown key(s) {unknown}; expected 'namespace' and [[service]] tables")
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
        restarts = entry.get("restarts", 3)
        if isinstance(restarts, bool) or not isinstance(restarts, int) or restarts < 0:
            raise ConfigError(f"{where}: 'restarts' must be a non-negative integer")
        config = entry.get("config")
        specs.append(ServiceSpec(name, class_path, (p.parent / config) if config else None, restarts))
        seen.add(name)
    if not specs:
        raise ConfigError(f"{p}: defines no [[service]]")
    return Stack(p, namespace, tuple(specs))


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

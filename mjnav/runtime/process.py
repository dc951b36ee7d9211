"""What one process runs: services of a stack file, by name or as a container, with their ``--set`` overrides.

``mjnav run`` builds its :class:`~mjnav.runtime.runner.ServiceRunner` here, and so does a process the launcher forks
(without going back through the command line: the runtime never imports the commands).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from mjnav.bus import BusConfig
from mjnav.runtime.config import ConfigError, parse_override
from mjnav.runtime.runner import ServiceRunner, Unit
from mjnav.runtime.stack import ServiceSpec, Stack


def resolve_services(stack: Stack, names: Sequence[str]) -> list[ServiceSpec]:
    """The services ``names`` stands for: one container's name (all its services) or service names.

    Raises:
        ConfigError: an unknown name, or a service named twice.
    """
    container = stack.container(names[0]) if len(names) == 1 else None
    specs = list(container.services) if container else [stack.get(name) for name in names]
    if len({s.name for s in specs}) != len(specs):
        raise ConfigError(f"a service is named twice: {' '.join(names)}")
    return specs


def split_overrides(items: Sequence[str], services: Sequence[str]) -> dict[str, dict[str, Any]]:
    """``--set`` items per service: ``KEY=VALUE`` for the only service, ``SERVICE.KEY=VALUE`` for one of several
    (or the only one).

    Raises:
        ConfigError: a malformed item, an unprefixed one with several services, or a service not run here.
    """
    out: dict[str, dict[str, Any]] = {}
    for item in items:
        head, eq, _ = item.partition("=")
        target, dot, _ = head.partition(".")
        if eq and dot:
            if target not in services:
                raise ConfigError(f"--set {item!r}: {target} is not run here ({', '.join(services)})")
            rest = item[len(target) + 1 :]
        elif len(services) == 1:
            target, rest = services[0], item
        else:
            raise ConfigError(f"--set {item!r}: with several services say whose: SERVICE.KEY=VALUE")
        key, value = parse_override(rest)
        out.setdefault(target, {})[key] = value
    return out


def build_runner(
    stack: Stack, specs: Sequence[ServiceSpec], items: Sequence[str], bus_config: BusConfig, namespace: str | None
) -> ServiceRunner:
    """The runner of ``specs`` (one process) with the ``--set`` ``items``.

    Raises:
        ConfigError: a bad override or config; ValueError: services that cannot share a process.
    """
    overrides = split_overrides(items, [s.name for s in specs])
    units = [Unit(s.load_class(), s.load_config(overrides.get(s.name)), s.name) for s in specs]
    return ServiceRunner(units, bus_config=bus_config, namespace=namespace or stack.namespace)

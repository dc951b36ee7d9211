"""Service runtime: config loading, the service lifecycle, the rate loop, time (:mod:`mjnav.runtime.simtime`), the
stack and its launcher.

No algorithms live here; services (``mjnav.services``) wire the bus to the algorithm library. The names below load
on first use, so the transport-free parts (the schedule and the pacer that :mod:`mjnav.sim` steps with) import
without Zenoh.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from mjnav.runtime.config import ConfigError, build_config, config_to_dict, parse_override, read_toml
    from mjnav.runtime.service import Service
    from mjnav.runtime.stack import ServiceSpec, Stack, load_stack

_EXPORTS = {
    "ConfigError": "config",
    "build_config": "config",
    "config_to_dict": "config",
    "parse_override": "config",
    "read_toml": "config",
    "Service": "service",
    "ServiceSpec": "stack",
    "Stack": "stack",
    "load_stack": "stack",
}

__all__ = [
    "ConfigError",
    "Service",
    "ServiceSpec",
    "Stack",
    "build_config",
    "config_to_dict",
    "load_stack",
    "parse_override",
    "read_toml",
]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'mjnav.runtime' has no attribute {name!r}")
    return getattr(importlib.import_module(f"mjnav.runtime.{module}"), name)

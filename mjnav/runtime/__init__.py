"""Service runtime: config loading, the service lifecycle, the rate loop, the stack and its launcher.

No algorithms live here; services (``mjnav.services``) wire the bus to the algorithm library.
"""

from mjnav.runtime.config import ConfigError, build_config, config_to_dict, parse_override, read_toml
from mjnav.runtime.service import Service
from mjnav.runtime.stack import ServiceSpec, Stack, load_stack

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

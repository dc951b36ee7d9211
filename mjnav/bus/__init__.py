"""The Zenoh bus: layered session configuration and typed publish/subscribe/request over the topic table."""

from mjnav.bus.bus import (
    Bus,
    BusStats,
    BusUnavailable,
    NoReply,
    NotDelivered,
    Publisher,
    RemoteError,
    Subscription,
    cdr_encoding,
    wait_until,
)
from mjnav.bus.config import (
    DEFAULT_PORT,
    DEFAULT_ROUTER,
    BusConfig,
    BusConfigError,
    add_bus_arguments,
    bus_config_from_args,
    load_bus_config,
)
from mjnav.bus.raw import BYTES_ENCODING, RawPublisher, RawSample, check_key_expr, key_matcher

__all__ = [
    "BYTES_ENCODING",
    "DEFAULT_PORT",
    "DEFAULT_ROUTER",
    "Bus",
    "BusConfig",
    "BusConfigError",
    "BusStats",
    "BusUnavailable",
    "NoReply",
    "NotDelivered",
    "Publisher",
    "RawPublisher",
    "RawSample",
    "RemoteError",
    "Subscription",
    "add_bus_arguments",
    "bus_config_from_args",
    "cdr_encoding",
    "check_key_expr",
    "key_matcher",
    "load_bus_config",
    "wait_until",
]

"""How mjnav keys become MCAP channels and back, and how command-line key arguments are read.

A Zenoh key ``robot0/scan`` is recorded as the ROS 2 topic ``/robot0/scan`` (the zenoh-bridge-ros2dds mapping), with
the key itself in the channel metadata (``zenoh_key``), so ROS 2 tools and Foxglove see ordinary topic names and
``mjnav bag play`` finds the key again.
"""

from __future__ import annotations

from mjnav.bag.errors import BagError
from mjnav.msgs import TOPICS, topic
from mjnav.msgs.topics import check_namespace


def topic_for_key(key: str) -> str:
    """ROS 2 topic name of a Zenoh key: ``robot0/scan`` → ``/robot0/scan``."""
    return "/" + key.strip("/")


def key_for_topic(topic_name: str) -> str:
    """Zenoh key of a ROS 2 topic name: ``/robot0/scan`` → ``robot0/scan``."""
    return topic_name.strip("/")


def key_expressions(args: list[str] | None, namespace: str) -> list[str]:
    """Zenoh key expressions for command-line ``--keys`` values.

    A value with a ``/`` is used as given (``robot0/scan``, ``robot0/status/*``, ``robot1/**``); a bare topic
    name means that topic in ``namespace`` (``scan`` → ``robot0/scan``, ``status`` → ``robot0/status/*``).
    No values: every key of ``namespace`` (``robot0/**``).

    Raises:
        BagError: an unknown bare topic name or an invalid key expression.
    """
    from mjnav.bus.raw import check_key_expr

    try:
        check_namespace(namespace)
    except ValueError as exc:
        raise BagError(str(exc)) from exc
    if not args:
        return [f"{namespace}/**"]
    out: list[str] = []
    for arg in args:
        if "/" not in arg:
            try:
                row = topic(arg)
            except KeyError:
                raise BagError(f"unknown topic {arg!r}; topics: {', '.join(TOPICS)} (or give a key)") from None
            expr = row.key(namespace, "*" if row.per_service else None)
        else:
            expr = arg
        try:
            check_key_expr(expr)
        except ValueError as exc:
            raise BagError(f"invalid key expression {expr!r}: use e.g. robot0/scan or robot0/status/*") from exc
        out.append(expr)
    return out

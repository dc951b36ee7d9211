"""Plumbing shared by the commands that run a stack beside their own client (private: not a command).

``mjnav demo`` and ``mjnav fly`` use it.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from mjnav import jsonsafe

T = TypeVar("T")


def run_beside_launcher(
    launcher: Any, bus_config: Any, namespace: str, client: Callable[[Any], T], command: str
) -> T | None:
    """Run ``launcher`` (router and services) in a daemon thread and ``client(bus)`` on a bus connected to it.

    The services are forked from this process first (:meth:`~mjnav.runtime.launcher.Launcher.spawn`), before its
    client's bus opens.

    The launcher is stopped (and its thread joined, up to 60 s) whatever happens. Ctrl-C, ``RuntimeError`` and
    ``TimeoutError`` from the client are reported on stderr as ``mjnav <command>: …`` and give ``None``.

    Args:
        launcher: a :class:`~mjnav.runtime.launcher.Launcher`.
        bus_config: the client's :class:`~mjnav.bus.BusConfig` (connected to ``launcher.endpoint``).
        namespace: the stack's namespace.
        client: what to do on the bus; its result is returned.
        command: the command's name, for messages.
    """
    from mjnav.bus import Bus

    # The services' first processes are forked from this one while it has no thread and no Zenoh session yet.
    launcher.fork_services = True
    launcher.spawn()
    thread = threading.Thread(target=lambda: launcher.run(install_signals=False), daemon=True)
    thread.start()
    launcher.router_ready.wait(60.0)  # connecting before it listens would wait out Zenoh's retry period (1 s)
    try:
        with Bus.open(bus_config, namespace) as bus:
            return client(bus)
    except KeyboardInterrupt:
        print(f"mjnav {command}: interrupted", file=sys.stderr)
    except (RuntimeError, TimeoutError) as exc:
        print(f"mjnav {command}: {exc}", file=sys.stderr)
    finally:
        launcher.stop_event.set()
        thread.join(60.0)
    return None


def write_summary(data: dict[str, Any], out: Path | None) -> None:
    """Write ``data`` as ``out/summary.json`` (indented JSON, non-finite numbers as null) when ``out`` is given."""
    if out is not None:
        (out / "summary.json").write_text(jsonsafe.dumps(data, indent=2) + "\n", encoding="utf-8")

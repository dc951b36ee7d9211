"""Which world the sim runs, as a viewer learns it over the bus: the world's name in the sim's ``sim_status`` (so a
replayed bag names its world too), else the ``world`` of the sim's config (a scene file elsewhere: ``sim_status``
carries only its name). Nothing tells a viewer its world on the command line: started alone (``mjnav run``, a
container) it draws what it would draw under ``mjnav up``.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from typing import Any

from mjnav.bus import Bus, NoReply, RemoteError
from mjnav.msgs import endpoint


class SimWorld:
    """Finds the world of the sim service ``sim`` (``sim_status`` on this bus's namespace, else its config).

    Args:
        bus: the viewer's bus.
        sim: the sim service's name (``sim``, ``uav_sim``).
        resolve: the world's path from a name or path (:func:`mjnav.sim.resolve_world`,
            :func:`mjnav.sim.uav.resolve_uav_world`); :class:`mjnav.sim.UnknownWorldError` for a name this viewer
            cannot load (a scene file elsewhere: only its name is in ``sim_status``).
        timeout_s: wall seconds to keep asking before :meth:`find` gives up.
    """

    def __init__(self, bus: Bus, sim: str, resolve: Callable[[str], object], timeout_s: float) -> None:
        self.bus = bus
        self.sim = sim
        self.resolve = resolve
        self.timeout_s = timeout_s
        self.sim_status = bus.subscribe("sim_status", lossy=True)
        self.started = time.monotonic()

    @property
    def where(self) -> str:
        """Where the world is looked for, for the log."""
        return f"{self.bus.key('sim_status')} or {endpoint('config').key(self.bus.namespace, self.sim)}"

    def find(self) -> str | None:
        """The sim's world (a name or path), ``""`` once ``timeout_s`` passed without one, or None meanwhile."""
        world = self._from_status() or self._from_config()
        if world:
            return world
        return "" if time.monotonic() - self.started >= self.timeout_s else None

    def _from_status(self) -> str | None:
        from mjnav.sim import UnknownWorldError

        msg: Any = self.sim_status.latest()
        if msg is None or not msg.world:
            return None
        try:
            self.resolve(str(msg.world))
        except UnknownWorldError:
            return None
        return str(msg.world)

    def _from_config(self) -> str | None:
        try:
            reply = self.bus.call("config", service=self.sim, timeout_s=0.5)
            world = json.loads(reply.data).get("world")
        except (NoReply, RemoteError, ValueError):
            return None
        return world if isinstance(world, str) and world else None

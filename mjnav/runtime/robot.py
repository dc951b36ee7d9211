"""The robot's description as the services receive it: the sim latches its MJCF on ``robot_description``, and
every service that needs a robot fact (footprint, radius, sensor frames, the lidar) reads it here, parsed by
:func:`mjnav.robot.parse_robot_description`. Nothing else tells a service what robot it drives: started alone
(``mjnav run``, a container) it learns the same facts as under ``mjnav up``.
"""

from __future__ import annotations

import logging
import threading
from typing import Any

from mjnav.bus import Bus
from mjnav.robot import DescriptionError, RobotDescription, parse_robot_description

log = logging.getLogger("mjnav.robot")


class RobotModel:
    """The newest robot description on the bus, parsed (in Zenoh's thread, once per new text).

    A service asks :meth:`waiting` in :meth:`~mjnav.runtime.Service.starting`, so it steps only once the facts are
    there; :attr:`version` counts the descriptions taken, so a service can rebuild what it derived when the sim
    restarts with another robot. A description that does not parse is logged with the reason and ignored.
    """

    def __init__(self, bus: Bus) -> None:
        self.key = bus.key("robot_description")
        self._lock = threading.Lock()
        self._current: RobotDescription | None = None
        self.version = 0
        self.rejected = 0
        bus.subscribe("robot_description", callback=self._on_description, immediate=True)

    def _on_description(self, msg: Any) -> None:
        text = str(msg.data)
        current = self._current
        if current is not None and current.mjcf == text:
            return
        try:
            description = parse_robot_description(text)
        except DescriptionError as exc:
            self.rejected += 1
            log.warning("robot description on %s ignored: %s", self.key, exc)
            return
        with self._lock:
            self._current = description
            self.version += 1
        log.info(
            "robot %r: footprint radius %.3f m, frames %s",
            description.name,
            description.radius_m,
            ", ".join(f.name for f in description.frames),
        )

    @property
    def current(self) -> RobotDescription | None:
        """The newest description (None before the first)."""
        with self._lock:
            return self._current

    def waiting(self) -> str:
        """What is missing ("" once a description arrived): for :meth:`~mjnav.runtime.Service.starting`."""
        return "" if self.current is not None else f"the robot description on {self.key} (the sim latches it)"

"""The service shape every mjnav service follows: configure → activate → step(now) → deactivate.

A service is a thin adapter between the bus and the algorithm library. It gets a validated config dataclass
(units in field names, a ``rate_hz`` field for its loop), a :class:`~mjnav.bus.Bus` for topics, and a logger. It
owns no threads, signals, sessions or timers: the runtime (:mod:`mjnav.runtime.runner`) calls ``step(now)`` at
``config.rate_hz`` on sim time (the ``clock`` topic) or wall time, and publishes its status.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Any, ClassVar, Generic, TypeVar

from mjnav.bus import Bus

ConfigT = TypeVar("ConfigT")

#: Environment variable naming the run's state directory (set by ``mjnav up`` for its services).
STATE_DIR_ENV = "MJNAV_STATE_DIR"


class Service(Generic[ConfigT]):
    """Base class of a service.

    Subclasses set ``name`` and ``config_class`` and override the lifecycle methods they need; ``step`` is
    mandatory. Exceptions from ``configure``/``activate`` end the process (the launcher restarts it);
    an exception from ``step`` is logged and counted, and the loop goes on.

    Attributes:
        name: the service name (key of its status topic and liveliness token).
        config_class: the frozen dataclass its TOML config is validated into; must have ``rate_hz``.
        uses_sim_time: step on the ``clock`` topic (True) or on wall time (False, e.g. the simulator itself).
        runs_alone: never shares a process (a relay that ignores what its own Zenoh session publishes would miss
            what its siblings publish).
        port_settings: config keys holding the TCP ports the service listens on (0 = any free port), which
            ``--port BASE`` numbers after the router's (:func:`mjnav.runtime.stack.port_overrides`).
        state_dir: a directory that outlives the process for the whole run (``$MJNAV_STATE_DIR``; ``mjnav up``
            makes one per run and removes it at the end): checkpoints a restarted service resumes from (the
            mapper's map, the planner's goal). None when the service runs on its own.
        runtime_settable: config keys that ``mjnav param set`` may change while the service runs (endpoint
            ``<ns>/set_param/<service>``): only keys the service reads from ``self.config`` whenever it uses them.
            The runner validates the new config like the TOML file and swaps ``self.config`` between two steps.
    """

    name: ClassVar[str] = ""
    config_class: ClassVar[type[Any]]
    uses_sim_time: ClassVar[bool] = True
    runs_alone: ClassVar[bool] = False
    port_settings: ClassVar[tuple[str, ...]] = ()
    runtime_settable: ClassVar[frozenset[str]] = frozenset()

    def __init__(self, config: ConfigT, bus: Bus, log: logging.Logger) -> None:
        self.config = config
        self.bus = bus
        bus.owner = self.name  # signs the delivery receipts of the event topics it subscribes to
        self.log = log
        state = os.environ.get(STATE_DIR_ENV, "")
        self.state_dir = Path(state) if state else None

    def configure(self) -> None:
        """Declare publishers/subscriptions and load resources (maps, models)."""

    def activate(self) -> None:
        """Start acting: called once before the first ``step``."""

    def step(self, now: float) -> None:
        """One loop iteration at time ``now`` (seconds of sim time, or wall time since start)."""
        raise NotImplementedError

    def starting(self) -> str:
        """Before the first step: what the service still waits for, by name and key ("" = ready), e.g. the robot
        description the sim latches. The runner steps the service (and, on sim time, joins lockstep) only once this
        is empty — in a container, once it is empty for every service of the process —, so every step of every run
        sees the same facts; meanwhile it says what is missing in the status and the log."""
        return ""

    def starved(self) -> str:
        """After each step: the input the service lacks to do its work, by name and key ("" = none), e.g.
        ``"initialpose on robot0/initialpose"``. The runner reports it in the status (``mjnav health --status``
        fails on it) and logs when it starts and when it ends. Keep it cheap: it is asked after every step."""
        return ""

    def deactivate(self) -> None:
        """Stop acting and release what ``activate``/``configure`` took (save files, stop actuators)."""

"""Service logic without processes: one service on a real in-process Zenoh bus, stepped by the test at chosen sim
times, its inputs published and its outputs recorded by a second peer (which also latches the robot description,
as the sim does)."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from mjnav.bus import Bus, Publisher, Subscription, wait_until
from mjnav.msgs import msg_class
from mjnav.runtime import Service, build_config
from tests.conftest import REPO

#: The bundled robot's MJCF: what the harness latches on ``robot_description`` unless told otherwise.
DIFFBOT = (REPO / "mjcf" / "diffbot.xml").read_text(encoding="utf-8")


class Harness:
    """A service instance plus a peer that feeds it and listens to it.

    Args:
        service_cls: the service class.
        peer: the ``peer`` fixture (opens buses on the test router).
        outputs: topics whose messages are recorded, in arrival order, in :attr:`received`.
        robot: the robot description (MJCF) latched on ``robot_description`` before the service starts (None:
            none); the service is ready (:meth:`Service.starting` empty) when the harness returns.
        config: config values over the class defaults.
    """

    def __init__(
        self,
        service_cls: type[Service[Any]],
        peer: Callable[..., Bus],
        outputs: tuple[str, ...],
        robot: str | None = DIFFBOT,
        **config: Any,
    ) -> None:
        self.world = peer()
        self.received: dict[str, list[Any]] = {name: [] for name in outputs}
        for name in outputs:
            self.world.subscribe(name, callback=self.received[name].append)
        self._pubs: dict[str, Publisher] = {}
        if robot is not None:
            self._pubs[self.world.key("robot_description")] = pub = self.world.publisher("robot_description")
            pub.put(msg_class("std_msgs/msg/String")(data=robot))
        cfg = build_config(service_cls.config_class, config, f"{service_cls.name} test config")
        self.service = service_cls(cfg, peer(), logging.getLogger(f"test.{service_cls.name}"))
        self.service.configure()
        self.service.activate()
        if robot is not None:
            assert wait_until(lambda: not self.service.starting(), 10.0), self.service.starting()

    def _subscription(self, name: str, service: str | None = None) -> Subscription:
        """The service's subscription to ``name`` (of ``service``, for a per-service topic), found among its bus's
        declarations."""
        key = self.service.bus.key(name, service)
        subs = [d for d in self.service.bus._declared if isinstance(d, Subscription) and d.key == key]
        assert subs, f"the service does not subscribe to {name}"
        return subs[0]

    def send(self, name: str, msg: Any, service: str | None = None) -> None:
        """Publish ``msg`` on ``name`` (as ``service``'s, for a per-service topic) and wait until the service's
        subscription has it."""
        pub = self._pubs.get(self.world.key(name, service))
        if pub is None:
            pub = self._pubs[self.world.key(name, service)] = self.world.publisher(name, service)
        sub = self._subscription(name, service)
        assert pub.wait_for_subscribers(10.0)
        before = sub.count
        # The publisher matches as soon as *a* subscriber is known — for a topic that is also an output, the
        # harness's own — which may be before the service's subscription reached this session. So: publish, and
        # publish again if the service did not get it, dropping the harness's own copy of the undelivered one.
        for _ in range(10):
            echoed = len(self.received[name]) if name in self.received else 0
            pub.put(msg)
            if wait_until(lambda: sub.count > before, 2.0):
                return
            if name in self.received:
                wait_until(lambda n=echoed: len(self.received[name]) > n, 2.0)
                del self.received[name][echoed:]
        raise AssertionError(f"{name} did not arrive")

    def close(self) -> None:
        """Close both buses (what the harness latched is gone with them)."""
        self.service.bus.close()
        self.world.close()

    def step(self, t: float, expect: dict[str, int] | None = None) -> None:
        """Step the service at sim time ``t``; with ``expect``, wait until each named output has that many
        messages in total."""
        self.service.step(t)
        for name, count in (expect or {}).items():
            assert wait_until(lambda n=name, c=count: len(self.received[n]) >= c, 10.0), (
                f"{name}: {len(self.received[name])} message(s), expected {count}"
            )

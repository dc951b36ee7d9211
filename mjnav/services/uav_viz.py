"""The UAV viz service: a headless meshcat viewer of the flight (the scene, the quadrotor, the reference, the trail).

Runs on wall time (not a lockstep participant, so it never holds sim time back): at ``rate_hz`` it moves the
vehicle along every ``ground_truth`` received since (extending the flown trail) and adds every received
``trajectory`` to the drawn reference. The scene is the world the UAV sim runs, learnt from the bus (its
``sim_status``, else its config; :class:`~mjnav.viz.simworld.SimWorld`) unless ``world`` names one. The meshcat
server binds to ``host`` (loopback by default); with ``static_html`` set, the scene is written there as a
self-contained HTML snapshot when the service stops.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mjnav.runtime import Service
from mjnav.viz.simworld import SimWorld


@dataclass(frozen=True)
class UavVizConfig:
    """UAV viz settings (``services/uav_viz.toml``).

    Attributes:
        rate_hz: drawing rate (wall time).
        world: the UAV scene drawn; "" = the sim's (from the bus).
        world_timeout_s: how long to keep asking the sim before drawing the default scene (``field``).
        serve: run the meshcat server (False: build the scene only, for ``static_html``).
        host, web_port, zmq_port, port_search: where the meshcat server listens (0: a free port; a taken port is
            searched upwards ``port_search`` times).
        static_html: write a self-contained HTML snapshot here when stopping ("" = none).
        trail_spacing_m: spacing of the drawn trail's points, m.
    """

    rate_hz: float = 10.0
    world: str = ""
    world_timeout_s: float = 10.0
    serve: bool = True
    host: str = "127.0.0.1"
    web_port: int = 7010
    zmq_port: int = 6010
    port_search: int = 20
    static_html: str = ""
    trail_spacing_m: float = 0.02

    def __post_init__(self) -> None:
        if not self.rate_hz > 0.0 or not self.trail_spacing_m > 0.0:
            raise ValueError("rate_hz and trail_spacing_m must be > 0")
        for name in ("web_port", "zmq_port"):
            if not 0 <= getattr(self, name) <= 65535:
                raise ValueError(f"{name} must be 0..65535, got {getattr(self, name)}")


class UavVizService(Service[UavVizConfig]):
    """meshcat viewer of the UAV flight."""

    name = "uav_viz"
    config_class = UavVizConfig
    uses_sim_time = False
    port_settings = ("web_port", "zmq_port")

    def configure(self) -> None:
        from mjnav.viz import MeshcatClient, MeshcatServer, Scene
        from mjnav.viz.uav import UavView

        cfg = self.config
        self.server: Any = None
        self.client: Any = None
        if cfg.serve:
            self.server = MeshcatServer(cfg.host, cfg.web_port, cfg.zmq_port, cfg.port_search).start()
            self.client = MeshcatClient(self.server.zmq_url)
            self.log.info("meshcat viewer at %s", self.server.web_url)
        self.scene = Scene(self.client.send if self.client is not None else None)
        self.view = UavView(self.scene, cfg.trail_spacing_m)
        from mjnav.sim.uav import resolve_uav_world

        self.sim_world = SimWorld(self.bus, "uav_sim", resolve_uav_world, cfg.world_timeout_s)
        self.drawn_world: str | None = None
        if cfg.world:
            self._setup(cfg.world)
        else:
            self.log.info("waiting for the UAV sim's world (%s)", self.sim_world.where)
        self._lock = threading.Lock()
        self._trajectories: list[Any] = []
        self._poses: list[Any] = []
        self.bus.subscribe("ground_truth", callback=self._on_pose)
        self.bus.subscribe("trajectory", callback=self._on_trajectory)

    def _on_pose(self, msg: Any) -> None:
        with self._lock:
            self._poses.append(msg)

    def _on_trajectory(self, msg: Any) -> None:
        with self._lock:
            self._trajectories.append(msg)

    def _setup(self, world: str) -> None:
        from mjnav.viz.uav import load_uav_visual

        self.view.setup(load_uav_visual(world or "field"))
        self.drawn_world = world or "field"
        self.log.info("drawing the UAV scene %s", self.drawn_world)

    def step(self, now: float) -> None:
        if self.drawn_world is None:
            world = self.sim_world.find()
            if world is None:
                return  # the poses and trajectories wait in their queues
            if not world:
                self.log.warning("no world from the UAV sim (%s): drawing field", self.sim_world.where)
            self._setup(world)
        with self._lock:
            trajectories, self._trajectories = self._trajectories, []
            poses, self._poses = self._poses, []
        for msg in trajectories:
            self.view.add_trajectory(msg)
        for i, msg in enumerate(poses):  # every true pose extends the trail; the last one places the vehicle
            last = i == len(poses) - 1
            self.view.set_pose(msg, redraw_trail=last, place=last)

    def deactivate(self) -> None:
        if self.config.static_html:
            path = self.scene.write_static_html(Path(self.config.static_html), title="mjnav uav0")
            self.log.info("wrote the scene snapshot %s", path)
        if self.client is not None:
            self.client.close()
        if self.server is not None:
            self.server.stop()
        self.log.info("drew %s", ", ".join(f"{k} {v}" for k, v in sorted(self.view.drawn.items())) or "nothing")

"""The viz service: a headless meshcat viewer of the stack, kept current from the bus.

Starts meshcat's web + ZMQ server in-process (bound to ``host``, loopback by default; never opens a browser unless
``open_browser`` is set *and* a display exists *and* the stack is not ``--headless``), builds the scene from the
MJCF world the sim runs (named in ``<ns>/sim_status`` — so a replayed bag shows its world too — or asked on
``<ns>/config/sim``, unless ``world`` is set) and, at ``rate_hz`` on wall time, draws the newest robot pose
(``ground_truth`` or ``odom``), scan, map, costmap, plan, path, the poses of the world's moving bodies
(``obstacles``), and every goal and goal status. A message that
cannot be drawn is logged with its topic and skipped. With ``static_html`` set, the scene is written there as a
self-contained HTML snapshot when the service stops (and every ``static_html_period_s``).
"""

from __future__ import annotations

import os
import time
import webbrowser
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mjnav.runtime import Service
from mjnav.viz.simworld import SimWorld
from mjnav.viz.view import POSE_TOPICS

#: Per-topic draw failures logged in full before they are only counted.
_LOG_FIRST = 5
#: Layers drawn as PNG textures, at ``grid_rate_hz``.
_GRIDS = ("map", "costmap")


@dataclass(frozen=True)
class VizConfig:
    """Viz service settings (``services/viz.toml``).

    Attributes:
        rate_hz: drawing rate (wall time).
        world: bundled world name or MJCF path to draw; "" = the sim's world (``<ns>/sim_status``, ``<ns>/config/sim``).
        world_timeout_s: how long to keep asking the sim before drawing without a world (robot model only).
        serve: run the meshcat server (False: build the scene only, e.g. for ``static_html``).
        host: interface the meshcat web and ZMQ sockets bind to; ``0.0.0.0`` serves the network.
        web_port: viewer port (HTTP + WebSocket); 0 picks a free one.
        zmq_port: meshcat drawing-command port (ZMQ); 0 picks a free one.
        port_search: when a port is taken, try this many following ports before failing.
        open_browser: open the viewer in a browser when a display exists and the stack is not headless.
        static_html: write a self-contained HTML snapshot here when stopping ("" = none).
        static_html_period_s: also rewrite the snapshot this often, wall seconds (0 = only when stopping).
        pose_topic: ``truth`` (true pose, the evaluation channel), ``pose`` (SLAM's estimate), ``ground_truth``
            (true pose, when the sim publishes it) or ``odom`` (wheel odometry, drifts).
        scan_point_size_m: drawn size of one scan return, metres.
        draw_costmap: draw the ``costmap`` topic over the map.
        grid_rate_hz: the map and costmap (a PNG texture each, the costly layers) are redrawn at most this often,
            wall time; the robot, scan and paths follow ``rate_hz``.
    """

    rate_hz: float = 10.0
    world: str = ""
    world_timeout_s: float = 10.0
    serve: bool = True
    host: str = "127.0.0.1"
    web_port: int = 7000
    zmq_port: int = 6000
    port_search: int = 10
    open_browser: bool = True
    static_html: str = ""
    static_html_period_s: float = 0.0
    pose_topic: str = "truth"
    scan_point_size_m: float = 0.06
    draw_costmap: bool = True
    grid_rate_hz: float = 2.0

    def __post_init__(self) -> None:
        for name in ("rate_hz", "grid_rate_hz"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("web_port", "zmq_port"):
            if not 0 <= getattr(self, name) <= 65535:
                raise ValueError(f"{name} must be 0..65535, got {getattr(self, name)}")
        if self.port_search < 0:
            raise ValueError(f"port_search must be >= 0, got {self.port_search}")
        for name in ("world_timeout_s", "static_html_period_s"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.pose_topic not in POSE_TOPICS:
            raise ValueError(f"pose_topic must be one of {list(POSE_TOPICS)}, got {self.pose_topic!r}")
        if not self.scan_point_size_m > 0.0:
            raise ValueError(f"scan_point_size_m must be > 0, got {self.scan_point_size_m}")
        if not self.host:
            raise ValueError("host must not be empty (127.0.0.1 = this machine only, 0.0.0.0 = every interface)")


class VizService(Service[VizConfig]):
    """meshcat viewer of the stack."""

    name = "viz"
    config_class = VizConfig
    uses_sim_time = False
    port_settings = ("web_port", "zmq_port")

    def configure(self) -> None:
        from mjnav.viz import MeshcatClient, MeshcatServer, NavView, Scene

        cfg = self.config
        self.server: Any = None
        self.client: Any = None
        if cfg.serve:
            self.server = MeshcatServer(cfg.host, cfg.web_port, cfg.zmq_port, cfg.port_search).start()
            self.client = MeshcatClient(self.server.zmq_url)
            self.log.info("meshcat viewer at %s (drawing commands on %s)", self.server.web_url, self.server.zmq_url)
        self.scene = Scene(self.client.send if self.client is not None else None)
        self.view = NavView(self.scene, scan_point_size_m=cfg.scan_point_size_m, pose_topic=cfg.pose_topic)
        snapshots = [cfg.pose_topic, "scan", "map", "plan", "path", "obstacles"]
        snapshots += ["costmap"] if cfg.draw_costmap else []
        # Lossy: the viewer is outside the lockstep loop and must never hold a publisher back when it falls
        # behind (a blocked router link stalls every service); it decodes only the newest message of each topic,
        # when it draws.
        self.snapshot_subs = {name: self.bus.subscribe(name, lossy=True) for name in snapshots}
        self.event_subs = {name: self.bus.subscribe(name, lossy=True) for name in ("goal", "goal_status")}
        from mjnav.sim import resolve_world

        self.sim_world = SimWorld(self.bus, "sim", resolve_world, cfg.world_timeout_s)
        self.world_name = ""
        self._failures: dict[str, int] = {}

    def activate(self) -> None:
        cfg = self.config
        self._started = time.monotonic()
        self._next_grid = self._started
        self._next_snapshot = self._started + cfg.static_html_period_s if cfg.static_html_period_s else None
        self.view.setup_viewer()
        if cfg.world:
            self._load_world(cfg.world)
        else:
            self.log.info("waiting for the sim's world (%s)", self.sim_world.where)
        if cfg.open_browser and self.server is not None and _can_open_browser():
            webbrowser.open(self.server.web_url, new=2)

    # --------------------------------------------------------------------------------------------------- loop

    def step(self, now: float) -> None:
        if self.view.model is None and not self._resolve_world():
            return
        wall = time.monotonic()
        grids_due = wall >= self._next_grid
        if grids_due:
            self._next_grid = wall + 1.0 / self.config.grid_rate_hz
        for name, sub in self.snapshot_subs.items():
            if name in _GRIDS and not grids_due:
                continue  # the newest grid stays in the subscription until the next grid tick
            msg = sub.take()
            if msg is not None:
                self._draw(name, msg)
        for name, sub in self.event_subs.items():
            for msg in sub.drain():
                self._draw(name, msg)
        if self._next_snapshot is not None and time.monotonic() >= self._next_snapshot:
            self._next_snapshot += self.config.static_html_period_s
            self._write_snapshot()

    def _draw(self, name: str, msg: Any) -> None:
        try:
            self.view.handle(name, msg)
        except Exception as exc:  # one bad message must not stop the drawing of the others
            n = self._failures.get(name, 0) + 1
            self._failures[name] = n
            if n <= _LOG_FIRST:
                self.log.warning("cannot draw %s from %s: %s: %s", name, self.bus.key(name), type(exc).__name__, exc)

    # --------------------------------------------------------------------------------------------------- world

    def _resolve_world(self) -> bool:
        """Find the sim's world; after ``world_timeout_s`` settle for the robot alone."""
        world = self.sim_world.find()
        if world is None:
            return False
        if not world:
            self.log.warning(
                "no world from the sim within %.1f s (%s); drawing the robot without a world",
                self.config.world_timeout_s,
                self.sim_world.where,
            )
        self._load_world(world)
        return True

    def _load_world(self, world: str) -> None:
        from mjnav.sim import SimError
        from mjnav.sim.worlds import MJCF_DIR
        from mjnav.viz import load_visual_model

        try:
            model = load_visual_model(world if world else MJCF_DIR / "diffbot.xml")
        except (SimError, OSError) as exc:
            self.log.error("cannot load world %r: %s; drawing the robot without a world", world, exc)
            model = load_visual_model(MJCF_DIR / "diffbot.xml")
            world = ""
        self.world_name = world
        if world:
            self.view.frame_camera(model.view_bounds())
        self.view.draw_model(model)
        self.log.info(
            "drawing world %s: %d static geoms, %d moving bodies, robot of %d geoms",
            world or "(none)",
            len(model.world_geoms) if world else 0,
            len(model.moving_bodies),
            len(model.robot_geoms),
        )

    # --------------------------------------------------------------------------------------------------- stop

    def _write_snapshot(self) -> None:
        path = Path(self.config.static_html)
        try:
            self.scene.write_static_html(path, title=f"mjnav {self.bus.namespace} {self.world_name}".strip())
        except OSError as exc:
            self.log.error("cannot write the snapshot %s: %s", path, exc)
            return
        self.log.info("wrote the scene snapshot %s", path)

    def deactivate(self) -> None:
        if self.config.static_html:
            self._write_snapshot()
        if self.client is not None:
            self.client.close()
        if self.server is not None:
            self.server.stop()
        self.log.info("drew %s", ", ".join(f"{k} {v}" for k, v in sorted(self.view.drawn.items())) or "nothing")


def _can_open_browser() -> bool:
    """A browser may open: the stack is not headless and there is a display."""
    if os.environ.get("MJNAV_HEADLESS", "") not in ("", "0"):
        return False
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))

"""The mapper service: the navigation ``costmap`` (Nav2's layered style).

With ``map_source = "scan"`` (the default) each new scan is fused into a persistent log-odds
:class:`~mjnav.mapping.OccupancyGrid` (marking and clearing, like Nav2's obstacle layer) at the pose the robot had
when the scan was taken, from ``pose_source`` (by default SLAM's ``map → odom`` ∘ the odometry at the scan's stamp),
and inflated into ``costmap`` (0–100, −1 unknown) at ``publish_rate_hz`` of sim time, the first one as soon as a
cell is known (never an all-unknown costmap). Every scan counts (SLAM's own map holds only its keyframes), which
keeps thin walls solid in the costmap. The grid is published on ``map`` only when the mapper is the map's source
(``pose_source`` ``ground_truth`` or ``odom``; on SLAM's pose, SLAM owns ``map``); it is checkpointed in the run's
state directory, saved as PGM + YAML on request (endpoint ``save_map``) and on exit (``save_path``); ``prior_map``
starts from a saved map. Returns of a moving obstacle (their motion between two scans, as the controller's
collision check tracks it) clear the cells before them and mark nothing: the costmap holds what stays, and the
controller waits for what passes.

With ``map_source = "slam"`` the static layer is SLAM's ``map`` (resampled onto the mapper's fixed grid) and an
obstacle layer marks the newest ``scan``'s returns within ``obstacle_range_m`` at SLAM's pose; ``save_map`` then
saves the newest SLAM map.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from mjnav.control.collision import TrackedScan, TrackingParams, track_scan
from mjnav.geometry import Pose2D
from mjnav.mapping import CellState, OccupancyGrid, inflation_costmap, read_ros_map, write_ros_map
from mjnav.mapping.frame import GridFrame
from mjnav.msgs import msg_class, ros
from mjnav.runtime import Service
from mjnav.runtime.pose import PoseInput


@dataclass(frozen=True)
class MapperConfig:
    """Mapper settings (``services/mapper.toml``).

    Attributes:
        rate_hz: loop rate (sim time); every new scan is integrated at the next step.
        publish_rate_hz: ``map`` and ``costmap`` publications per sim second.
        map_source: ``slam`` (static layer from SLAM's ``map``) or ``scan`` (a log-odds map of its own).
        pose_source: ``slam`` (SLAM's ``map → odom`` ∘ odometry, :mod:`mjnav.runtime.pose`), ``ground_truth``
            (true pose) or ``odom`` (drifting).
        obstacle_range_m: the obstacle layer marks the newest scan's returns up to this range (slam mode).
        moving_speed_mps: returns moving faster than this between two scans are a moving obstacle's
            (:func:`mjnav.control.collision.track_scan`, as the controller's collision check sees them): they clear
            the cells before them and mark nothing. The planner then plans through a cart crossing its way, which
            the controller waits for, rather than around each place the cart was.
        width_m, height_m, resolution_m, origin_m: the grid (origin = map-frame corner of cell (0, 0)); ``mjnav
            up`` sizes it to the sim's world (:meth:`mjnav.runtime.launcher.Launcher._settings_from_world`).
        laser_offset_m: lidar position in base_link (x, y), metres (``mjnav up``: the robot model's lidar site).
        max_range_m: readings at or beyond this are "no return" (free up to it).
        robot_radius_m: inscribed radius for the costmap's lethal inflation (``mjnav up``: the robot model's
            footprint radius).
        inflation_radius_m: cost decays to 0 at this distance from obstacles (0.7 left a 1.4 m corridor one
            zero-cost line, its centre: paths 20 % longer than the shortest in the maze; 0.5, near Nav2's 0.55,
            leaves a band to round corners in).
        cost_scaling_factor: exponential decay rate of the cost, 1/m.
        prior_map: ROS map YAML to start from ("" = unknown everywhere; its grid replaces width/height/origin).
        save_path: ROS map YAML written on exit ("" = don't).
        maps_dir: the only directory the ``save_map`` request may write to; its path is taken relative to it.
        checkpoint_period_s: how often (sim s) the map is checkpointed to the run's state directory, from which a
            restarted mapper resumes (``mjnav up`` gives one per run; 0 = never).
    """

    rate_hz: float = 10.0
    publish_rate_hz: float = 2.0
    map_source: Literal["slam", "scan"] = "scan"
    pose_source: Literal["slam", "ground_truth", "odom"] = "slam"
    obstacle_range_m: float = 3.0
    moving_speed_mps: float = 0.25
    width_m: float = 20.0
    height_m: float = 20.0
    resolution_m: float = 0.05
    origin_m: tuple[float, float] = (-10.0, -10.0)
    laser_offset_m: tuple[float, float] = (0.0, 0.0)
    max_range_m: float = 12.0
    robot_radius_m: float = 0.19
    inflation_radius_m: float = 0.5
    cost_scaling_factor: float = 5.0
    prior_map: str = ""
    save_path: str = ""
    maps_dir: str = "maps"
    checkpoint_period_s: float = 2.0

    def __post_init__(self) -> None:
        for name in ("publish_rate_hz", "width_m", "height_m", "resolution_m", "max_range_m", "moving_speed_mps"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not 0 <= self.robot_radius_m <= self.inflation_radius_m:
            raise ValueError("need 0 <= robot_radius_m <= inflation_radius_m")
        if not self.checkpoint_period_s >= 0:
            raise ValueError(f"checkpoint_period_s must be >= 0, got {self.checkpoint_period_s}")
        if not self.maps_dir:
            raise ValueError("maps_dir must not be empty")


class MapperService(Service[MapperConfig]):
    """Builds the occupancy map and the costmap from scans."""

    name = "mapper"
    config_class = MapperConfig
    #: Read from ``self.config`` at every use: ``mjnav param set mapper KEY VALUE`` changes them while running.
    runtime_settable = frozenset({"inflation_radius_m", "cost_scaling_factor", "publish_rate_hz", "obstacle_range_m"})

    def configure(self) -> None:
        cfg = self.config
        if cfg.prior_map:
            prior = read_ros_map(cfg.prior_map)
            self.grid = OccupancyGrid.from_ros_map(prior)
            self.log.info(
                "prior map %s: %dx%d cells at %.3f m", cfg.prior_map, *prior.occupancy.shape[::-1], prior.resolution_m
            )
        else:
            self.grid = OccupancyGrid(
                round(cfg.width_m / cfg.resolution_m),
                round(cfg.height_m / cfg.resolution_m),
                cfg.resolution_m,
                origin_m=cfg.origin_m,
            )
        self.frame = GridFrame(self.grid.resolution_m, self.grid.origin_m, self.grid.shape)
        self.seeded = bool(cfg.prior_map)  # something is known: a prior or resumed map, or enough scans
        self.slam_mode = cfg.map_source == "slam"
        if not self.slam_mode:
            self._restore_checkpoint()
        self.scan = self.bus.subscribe("scan")
        self.pose_in = PoseInput(self.bus, cfg.pose_source)
        self.static = self.bus.subscribe("map") if self.slam_mode else None
        # On SLAM's pose, SLAM owns the ``map`` topic; the mapper's own grid is then only the costmap's layer.
        self.map_pub = None if self.slam_mode or cfg.pose_source == "slam" else self.bus.publisher("map")
        self.costmap_pub = self.bus.publisher("costmap")
        self.obstacles: Any = np.zeros((0, 2))  # the obstacle layer: newest scan's static returns in map, (M, 2)
        self.tracked: TrackedScan | None = None  # the previous scan, for its returns' motion
        self.tracking = TrackingParams(moving_speed_mps=cfg.moving_speed_mps)
        self._centres: Any = None  # (H·W, 2) map-frame cell centres of the grid (slam mode, computed once)
        self.bus.serve("save_map", self._on_save)
        self.laser = Pose2D(cfg.laser_offset_m[0], cfg.laser_offset_m[1], 0.0)
        self.scans = 0
        self.skipped = 0
        self.checkpointed_scans = 0
        self.next_checkpoint = 0.0
        # Load the compiled scan integration now, on a scratch grid.
        OccupancyGrid(8, 8, 0.1).integrate_scan((0.4, 0.4, 0.0), np.zeros(1), np.ones(1), 1.0)

    def activate(self) -> None:
        self.pose_in.reset()
        self.next_publish = 0.0

    def step(self, now: float) -> None:
        self.pose_in.update()
        scan = self.scan.take()
        if scan is not None:
            self._integrate(scan)
        if now >= self.next_publish and self._has_data():
            # On the publication grid (k / rate), so the first costmap, which goes out as soon as there is data,
            # does not shift the later ones against the planner's steps.
            rate = self.config.publish_rate_hz
            self.next_publish = (math.floor(now * rate + 1e-9) + 1.0) / rate
            self._publish(now)
        if not self.slam_mode and self.config.checkpoint_period_s > 0 and now >= self.next_checkpoint:
            self.next_checkpoint = now + self.config.checkpoint_period_s
            if self.scans != self.checkpointed_scans:
                self._checkpoint()

    def _has_data(self) -> bool:
        """Whether any cell is known: the grid's (a prior or resumed map, or scans enough for a cell to cross a
        threshold), or SLAM's map and scans in slam mode. Before that no costmap goes out: an all-unknown one would
        have the planner route straight through unknown space, and the robot set off on that route."""
        if not self.seeded:
            if self.slam_mode:
                self.seeded = self.scans > 0 or (self.static is not None and self.static.latest() is not None)
            elif self.scans:
                self.seeded = bool((self.grid.states() != CellState.UNKNOWN).any())
        return self.seeded

    # ------------------------------------------------------------------------------------------- checkpoints

    def _checkpoint_file(self) -> Path | None:
        return None if self.state_dir is None else self.state_dir / "mapper-map.npz"

    def _checkpoint(self) -> None:
        """Write the log-odds grid to the state directory (atomically: a crash mid-write keeps the last one)."""
        path = self._checkpoint_file()
        if path is None:
            return
        tmp = path.with_suffix(".tmp.npz")
        g = self.grid
        np.savez(tmp, log_odds=g.log_odds, resolution_m=g.resolution_m, origin_m=np.asarray(g.origin_m))
        os.replace(tmp, path)
        self.checkpointed_scans = self.scans

    def _restore_checkpoint(self) -> None:
        """Resume from the run's checkpoint, if a previous mapper process of this run left one for this grid."""
        path = self._checkpoint_file()
        if path is None or not path.exists():
            return
        g = self.grid
        try:
            with np.load(path) as data:
                log_odds = np.asarray(data["log_odds"], dtype=np.float64)
                same = (
                    log_odds.shape == g.log_odds.shape
                    and float(data["resolution_m"]) == g.resolution_m
                    and tuple(np.asarray(data["origin_m"]).tolist()) == tuple(g.origin_m)
                )
        except (OSError, ValueError, KeyError) as exc:
            self.log.warning("map checkpoint %s unreadable (%s): starting from scratch", path, exc)
            return
        if not same:
            self.log.warning("map checkpoint %s is for another grid: starting from scratch", path)
            return
        g.log_odds[...] = log_odds
        self.seeded = True
        known = int(np.count_nonzero(log_odds))
        self.log.info("resumed the map from checkpoint %s (%d known cells)", path, known)

    def _integrate(self, scan: Any) -> None:
        stamp = ros.seconds(scan.header.stamp)
        pose = self.pose_in.at(stamp)
        if pose is None:
            self.skipped += 1
            if self.skipped in (1, 10, 100) or self.skipped % 1000 == 0:
                self.log.warning(
                    "no %s pose at scan time %.3f s: %d scan(s) skipped", self.config.pose_source, stamp, self.skipped
                )
            return
        sensor = pose * self.laser
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        max_range = min(float(scan.range_max), self.config.max_range_m)
        tracked = track_scan(
            stamp,
            (sensor.x, sensor.y, sensor.theta),
            float(scan.angle_min),
            float(scan.angle_increment),
            ranges,
            float(scan.range_min),
            max_range,
            self.tracked,
            self.tracking,
            static=None if self.slam_mode else self._on_walls,
        )
        self.tracked = tracked
        moving = tracked.moving()
        self.scans += 1
        if self.slam_mode:
            near = ~moving & (ranges[tracked.beams] < self.config.obstacle_range_m)
            self.obstacles = tracked.points[near]
            return
        marks = np.ones(len(ranges), dtype=bool)
        marks[tracked.beams[moving]] = False
        angles = scan.angle_min + scan.angle_increment * np.arange(len(ranges))
        self.grid.integrate_scan(sensor, angles, ranges, max_range, min_range_m=float(scan.range_min), marks=marks)

    def _on_walls(self, points: Any) -> Any:
        """(M,) True for points on or next to a cell the grid has as occupied: static, whatever two scans say."""
        log_odds, threshold = self.grid.log_odds, self.grid.model.occupied_threshold
        cells = self.frame.world_to_cells(points)
        h, w = log_odds.shape
        out = np.zeros(len(points), dtype=bool)
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                r, c = cells[:, 0] + dr, cells[:, 1] + dc
                inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
                out[inside] |= log_odds[r[inside], c[inside]] > threshold
        return out

    def occupancy(self) -> Any:
        """(H, W) int8 occupancy the costmap inflates (0..100, −1 unknown): the own map's states (scan mode), or
        SLAM's map resampled onto the grid with the obstacle layer's returns marked occupied (slam mode)."""
        if not self.slam_mode:
            return self.grid.states()
        assert self.static is not None
        occ = np.full(self.grid.shape, -1, dtype=np.int8)
        msg = self.static.latest()
        if msg is not None:
            cells, frame = ros.grid_frame(msg)
            if self._centres is None:
                rows, cols = np.indices(self.grid.shape)
                self._centres = self.frame.cells_to_world(np.column_stack((rows.ravel(), cols.ravel())))
            occ = frame.values_at(cells, self._centres, outside=-1).astype(np.int8).reshape(self.grid.shape)
        if len(self.obstacles):
            idx = self.frame.world_to_cells(self.obstacles)
            inside = (idx[:, 0] >= 0) & (idx[:, 0] < occ.shape[0]) & (idx[:, 1] >= 0) & (idx[:, 1] < occ.shape[1])
            occ[idx[inside, 0], idx[inside, 1]] = 100
        return occ

    def costmap(self) -> Any:
        """The current inflated costmap, (H, W) int8 (0..100, −1 unknown)."""
        cfg = self.config
        return inflation_costmap(
            self.occupancy(),
            self.grid.resolution_m,
            cfg.robot_radius_m,
            cfg.inflation_radius_m,
            cfg.cost_scaling_factor,
        )

    def _publish(self, now: float) -> None:
        origin = (self.grid.origin_m[0], self.grid.origin_m[1])
        res = self.grid.resolution_m
        if self.map_pub is not None:
            self.map_pub.put(ros.occupancy_grid(now, "map", self.grid.to_ros(), res, origin))
        self.costmap_pub.put(ros.occupancy_grid(now, "map", self.costmap(), res, origin))

    def save(self, yaml_path: str | Path) -> Path:
        """Write the map (in slam mode: SLAM's newest) as trinary PGM + YAML; returns the YAML path."""
        grid = self.grid
        if self.static is not None:
            msg = self.static.latest()
            if msg is None:
                raise ValueError("no map from SLAM yet")
            info = msg.info
            origin_xy = (info.origin.position.x, info.origin.position.y)
            grid = OccupancyGrid.from_ros(msg.data, info.width, info.height, info.resolution, origin_xy)
        origin = (grid.origin_m[0], grid.origin_m[1], 0.0)
        return write_ros_map(yaml_path, grid.states(), grid.resolution_m, origin)

    def _on_save(self, request: Any) -> Any:
        """``save_map``: write the map to a path inside ``maps_dir`` (given relative to it; default: the
        configured ``save_path``). Anything that would land outside ``maps_dir`` is refused."""
        if request.data:
            root = Path(self.config.maps_dir).resolve()
            target = (root / request.data).resolve()
            if Path(request.data).is_absolute() or not target.is_relative_to(root):
                raise ValueError(f"save_map writes only inside maps_dir {root}: {request.data!r} is outside it")
            target.parent.mkdir(parents=True, exist_ok=True)
        elif self.config.save_path:
            target = Path(self.config.save_path)
        else:
            raise ValueError("no path given and no save_path configured")
        written = self.save(target)
        self.log.info("map saved to %s", written)
        return msg_class("std_msgs/msg/String")(data=json.dumps({"yaml": str(written)}))

    def deactivate(self) -> None:
        if self.config.save_path:
            try:
                written = self.save(self.config.save_path)
            except ValueError as exc:
                self.log.warning("map not saved to %s: %s", self.config.save_path, exc)
                return
            self.log.info("map saved to %s (%d scans used)", written, self.scans)

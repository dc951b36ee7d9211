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

With ``map_source = "slam"`` the static layer is SLAM's ``map`` (resampled onto the mapper's grid) and an
obstacle layer marks the newest ``scan``'s returns within ``obstacle_range_m`` at SLAM's pose; ``save_map`` then
saves the newest SLAM map.

The grid grows with what the robot explores (Nav2's static layer resizes to the map it receives): it starts around
the first scan and is extended, on the same cells, whenever a scan touches cells beyond it (its returns, and its
free beams up to ``max_range_m``; ``grow_margin_m`` more, so that it grows seldom), and to cover SLAM's map in slam
mode. A goal beyond it is the planner's business (it plans through unknown space up to a margin). The robot's
footprint radius (the costmap's inscribed band) and where the lidar sits come from the robot description the sim
latches (:mod:`mjnav.runtime.robot`); nothing about the robot or the world is configured here.
"""

from __future__ import annotations

import io
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from mjnav.control.collision import TrackedScan, TrackingParams, track_scan
from mjnav.geometry import Pose2D
from mjnav.mapping import CellState, OccupancyGrid, inflation_costmap, read_ros_map, write_ros_map
from mjnav.mapping.frame import GridFrame
from mjnav.msgs import msg_class, ros
from mjnav.robot import DescriptionError
from mjnav.runtime import Service
from mjnav.runtime.checkpoint import Checkpoint
from mjnav.runtime.pose import PoseInput
from mjnav.runtime.robot import RobotModel

#: Sim seconds without a scan used after which the status says the mapper lacks scans.
STARVED_AFTER_S = 5.0


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
        resolution_m: cell size of the grid, metres.
        grow_margin_m: when a scan touches cells beyond the grid, the grid grows to hold them plus this much
            (metres), so that it grows every few metres of driving, not at every scan.
        max_range_m: readings at or beyond this are "no return" (free up to it).
        grazing_margin_m: a return frees no cell where its beam runs within this distance of the surface it ends
            on (:meth:`~mjnav.mapping.OccupancyGrid.integrate_scan`): beams that graze a long wall otherwise
            clear holes in its face, which the planner took for ways through the wall (issue 30: 258 m driven
            along a 30 m wall). About two cells; 0 = the textbook update.
        inflation_radius_m: cost decays to 0 at this distance from obstacles (0.7 left a 1.4 m corridor one
            zero-cost line, its centre: paths 20 % longer than the shortest in the maze; 0.5, near Nav2's 0.55,
            leaves a band to round corners in). Cells within the robot's footprint radius (from its description)
            of an obstacle are inscribed (99); a robot wider than this radius inflates to its own radius.
        cost_scaling_factor: exponential decay rate of the cost, 1/m.
        prior_map: ROS map YAML to start from ("" = unknown everywhere; the grid starts as its extent).
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
    resolution_m: float = 0.05
    grow_margin_m: float = 2.0
    max_range_m: float = 12.0
    grazing_margin_m: float = 0.1
    inflation_radius_m: float = 0.5
    cost_scaling_factor: float = 5.0
    prior_map: str = ""
    save_path: str = ""
    maps_dir: str = "maps"
    checkpoint_period_s: float = 2.0

    def __post_init__(self) -> None:
        for name in ("publish_rate_hz", "resolution_m", "max_range_m", "moving_speed_mps", "inflation_radius_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("grow_margin_m", "grazing_margin_m"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
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
        self.grid: OccupancyGrid | None = None  # none until the first scan (or a prior or resumed map)
        if cfg.prior_map:
            prior = read_ros_map(cfg.prior_map)
            self._set_grid(OccupancyGrid.from_ros_map(prior))
            self.log.info(
                "prior map %s: %dx%d cells at %.3f m", cfg.prior_map, *prior.occupancy.shape[::-1], prior.resolution_m
            )
        self.seeded = bool(cfg.prior_map)  # something is known: a prior or resumed map, or enough scans
        self.slam_mode = cfg.map_source == "slam"
        if not self.slam_mode:
            self._restore_checkpoint()
        self.scan = self.bus.subscribe("scan")
        self.robot = RobotModel(self.bus)
        self.pose_in = PoseInput(self.bus, cfg.pose_source)
        self.static = self.bus.subscribe("map") if self.slam_mode else None
        # On SLAM's pose, SLAM owns the ``map`` topic; the mapper's own grid is then only the costmap's layer.
        self.map_pub = None if self.slam_mode or cfg.pose_source == "slam" else self.bus.publisher("map")
        self.costmap_pub = self.bus.publisher("costmap")
        self.obstacles: Any = np.zeros((0, 2))  # the obstacle layer: newest scan's static returns in map, (M, 2)
        self.tracked: TrackedScan | None = None  # the previous scan, for its returns' motion
        self.tracking = TrackingParams(moving_speed_mps=cfg.moving_speed_mps)
        self.bus.serve("save_map", self._on_save)
        self.scans = 0
        self.skipped = 0
        self.checkpointed_scans = 0
        self.next_checkpoint = 0.0
        self._inflation_warned = False
        # Load the compiled scan integration now, on a scratch grid.
        OccupancyGrid(8, 8, 0.1).integrate_scan((0.4, 0.4, 0.0), np.zeros(1), np.ones(1), 1.0)

    def starting(self) -> str:
        return self.robot.waiting()

    def starved(self) -> str:
        if self.skipped_since_use:
            return f"the robot's pose at the scans' times ({self.pose_in.describe()})"
        if self.now - self.last_scan_used > STARVED_AFTER_S:
            return f"scans on {self.scan.key} (none used for {STARVED_AFTER_S:g} s)"
        return ""

    def activate(self) -> None:
        self.pose_in.reset()
        self.next_publish = 0.0
        self.now = 0.0
        self.last_scan_used = -math.inf  # sim time of the newest scan integrated (set at the first step)
        self.skipped_since_use = 0  # scans skipped for want of a pose since one was used

    def step(self, now: float) -> None:
        self.now = now
        if self.last_scan_used == -math.inf:
            self.last_scan_used = now  # starvation counts from the first step
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
            elif self.scans and self.grid is not None:
                self.seeded = bool((self.grid.states() != CellState.UNKNOWN).any())
        return self.seeded and self.grid is not None

    # ------------------------------------------------------------------------------------------------- grid

    def _set_grid(self, grid: OccupancyGrid) -> None:
        self.grid = grid
        self.frame = GridFrame(grid.resolution_m, grid.origin_m, grid.shape)
        self._centres: Any = None  # (H·W, 2) map-frame cell centres of the grid (slam mode, computed on use)

    def _cover(self, x_min: float, y_min: float, x_max: float, y_max: float) -> OccupancyGrid:
        """The grid, grown (or made) to hold the rectangle, ``grow_margin_m`` beyond it when it must grow."""
        grid = self.grid
        if grid is not None:
            x0, x1, y0, y1 = grid.extent_m
            if x0 <= x_min and y0 <= y_min and x_max <= x1 and y_max <= y1:
                return grid
        m = self.config.grow_margin_m
        if grid is None:
            res = self.config.resolution_m
            x0, y0 = math.floor((x_min - m) / res) * res, math.floor((y_min - m) / res) * res
            grid = OccupancyGrid(1, 1, res, (x0, y0))
        grown = grid.grown_to(x_min - m, y_min - m, x_max + m, y_max + m)
        self.log.debug("grid grown to %dx%d cells from %s", grown.width_cells, grown.height_cells, grown.origin_m)
        self._set_grid(grown)
        return grown

    # ------------------------------------------------------------------------------------------- checkpoints

    def _checkpoint_store(self) -> Checkpoint | None:
        """The map's checkpoint in the run's state directory (None without one)."""
        return None if self.state_dir is None else Checkpoint(self.state_dir / "mapper-map.npz", 1, self.log)

    def _checkpoint(self) -> None:
        """Write the log-odds grid to the state directory (:class:`Checkpoint`: atomic, checksummed, the previous
        one kept)."""
        store = self._checkpoint_store()
        if store is None or self.grid is None:
            return
        g = self.grid
        buffer = io.BytesIO()
        np.savez(buffer, log_odds=g.log_odds, resolution_m=g.resolution_m, origin_m=np.asarray(g.origin_m))
        store.save(buffer.getvalue())
        self.checkpointed_scans = self.scans

    def _restore_checkpoint(self) -> None:
        """Resume from the run's checkpoint, if a previous mapper process of this run left one at this resolution
        (a prior map's grid, if any, grows to hold it). A bad checkpoint is logged, set aside and the previous one
        used, or none (:meth:`Checkpoint.load`)."""
        store = self._checkpoint_store()
        if store is None:
            return
        saved = store.load(self._decode_grid)
        if saved is None:
            return
        if saved.resolution_m != self.config.resolution_m and self.grid is None:
            self.log.warning(
                "map checkpoint %s has %g m cells, the mapper %g m: starting from scratch",
                store.path, saved.resolution_m, self.config.resolution_m,
            )  # fmt: skip
            return
        self._set_grid(saved)
        self.seeded = True
        known = int(np.count_nonzero(saved.log_odds))
        self.log.info("resumed the map from checkpoint %s (%d known cells)", store.path, known)

    @staticmethod
    def _decode_grid(payload: bytes) -> OccupancyGrid:
        """The grid a checkpoint's payload holds (an ``.npz`` of ``log_odds``, ``resolution_m``, ``origin_m``).

        Raises:
            ValueError, KeyError, OSError: not such an ``.npz``.
        """
        with np.load(io.BytesIO(payload), allow_pickle=False) as data:
            log_odds = np.asarray(data["log_odds"], dtype=np.float64)
            resolution = float(data["resolution_m"])
            origin = tuple(float(v) for v in np.asarray(data["origin_m"]).tolist())
        if log_odds.ndim != 2 or 0 in log_odds.shape or len(origin) != 2 or not resolution > 0:
            raise ValueError(f"log_odds of shape {log_odds.shape}, origin {origin}, {resolution} m cells")
        if not np.isfinite(log_odds).all():
            raise ValueError("log_odds not finite")
        h, w = log_odds.shape
        grid = OccupancyGrid(w, h, resolution, (origin[0], origin[1]))
        grid.log_odds[...] = log_odds
        return grid

    # ------------------------------------------------------------------------------------------------ scans

    def _integrate(self, scan: Any) -> None:
        stamp = ros.seconds(scan.header.stamp)
        pose = self.pose_in.at(stamp)
        if pose is None:
            self.skipped += 1
            self.skipped_since_use += 1
            if self.skipped in (1, 10, 100) or self.skipped % 1000 == 0:
                self.log.warning(
                    "no %s pose at scan time %.3f s: %d scan(s) skipped", self.config.pose_source, stamp, self.skipped
                )
            return
        robot = self.robot.current
        assert robot is not None  # starting() waited for it
        try:
            laser = Pose2D(*robot.frame(scan.header.frame_id).planar)
        except DescriptionError as exc:
            self.skipped += 1
            if self.skipped in (1, 10, 100) or self.skipped % 1000 == 0:
                self.log.warning("scan at %.3f s not used: %s", stamp, exc)
            return
        self.skipped_since_use = 0
        self.last_scan_used = self.now
        sensor = pose * laser
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        max_range = min(float(scan.range_max), self.config.max_range_m)
        angles = scan.angle_min + scan.angle_increment * np.arange(len(ranges))
        grid = self._cover(*_scan_extent(sensor, angles, ranges, float(scan.range_min), max_range))
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
        grid.integrate_scan(
            sensor,
            angles,
            ranges,
            max_range,
            min_range_m=float(scan.range_min),
            marks=marks,
            grazing_margin_m=self.config.grazing_margin_m,
        )

    def _on_walls(self, points: Any) -> Any:
        """(M,) True for points on or next to a cell the grid has as occupied: static, whatever two scans say."""
        assert self.grid is not None
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
        assert self.grid is not None
        if not self.slam_mode:
            return self.grid.states()
        assert self.static is not None
        msg = self.static.latest()
        if msg is not None:
            cells, frame = ros.grid_frame(msg)
            (x0, y0), (x1, y1) = frame.cells_to_world([[0, 0], [frame.shape[0] - 1, frame.shape[1] - 1]])
            half = frame.resolution_m / 2
            self._cover(x0 - half, y0 - half, x1 + half, y1 + half)  # the grid holds SLAM's whole map
        occ = np.full(self.grid.shape, -1, dtype=np.int8)
        if msg is not None:
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
        """The current inflated costmap, (H, W) int8 (0..100, −1 unknown): cells within the robot's footprint
        radius of an obstacle are inscribed (99), the cost decays to 0 at ``inflation_radius_m`` (or at the
        robot's radius, when it is the larger)."""
        cfg = self.config
        robot = self.robot.current
        assert robot is not None and self.grid is not None
        occupancy = self.occupancy()  # may grow the grid (slam mode)
        inflation = cfg.inflation_radius_m
        if robot.radius_m > inflation:
            if not self._inflation_warned:
                self.log.warning(
                    "inflation_radius_m %.2f m is less than the robot's radius %.3f m: inflating to the radius",
                    inflation, robot.radius_m,
                )  # fmt: skip
                self._inflation_warned = True
            inflation = robot.radius_m
        return inflation_costmap(occupancy, self.grid.resolution_m, robot.radius_m, inflation, cfg.cost_scaling_factor)

    def _publish(self, now: float) -> None:
        costmap = self.costmap()
        assert self.grid is not None
        origin = (self.grid.origin_m[0], self.grid.origin_m[1])
        res = self.grid.resolution_m
        if self.map_pub is not None:
            self.map_pub.put(ros.occupancy_grid(now, "map", self.grid.to_ros(), res, origin))
        self.costmap_pub.put(ros.occupancy_grid(now, "map", costmap, res, origin))

    def save(self, yaml_path: str | Path) -> Path:
        """Write the map (in slam mode: SLAM's newest) as trinary PGM + YAML; returns the YAML path.

        Raises:
            ValueError: there is no map yet.
        """
        grid = self.grid
        if self.static is not None:
            msg = self.static.latest()
            if msg is None:
                raise ValueError("no map from SLAM yet")
            info = msg.info
            origin_xy = (info.origin.position.x, info.origin.position.y)
            grid = OccupancyGrid.from_ros(msg.data, info.width, info.height, info.resolution, origin_xy)
        if grid is None:
            raise ValueError("no map yet: no scan was used")
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


def _scan_extent(
    sensor: Pose2D, angles: Any, ranges: Any, range_min_m: float, max_range_m: float
) -> tuple[float, float, float, float]:
    """(x_min, y_min, x_max, y_max) of what a scan touches in the map frame: the sensor and each beam's end — its
    return, or ``max_range_m`` along it for a beam without one (it clears the cells up to there) — metres. Beams too
    close to measure touch nothing (:meth:`OccupancyGrid.integrate_scan`)."""
    r = np.asarray(ranges, dtype=np.float64)
    used = ~(np.isneginf(r) | (r < range_min_m) | (r <= 0.0))
    reach = np.where(np.isfinite(r) & (r < max_range_m), r, max_range_m)[used]
    heading = sensor.theta + np.asarray(angles, dtype=np.float64)[used]
    xs = np.append(sensor.x + reach * np.cos(heading), sensor.x)
    ys = np.append(sensor.y + reach * np.sin(heading), sensor.y)
    return float(xs.min()), float(ys.min()), float(xs.max()), float(ys.max())

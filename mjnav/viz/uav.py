"""meshcat drawing of the UAV stack: the scene's geoms, the quadrotor at its true pose, the reference and the trail.

:func:`load_uav_visual` collects the visible geoms of a UAV scene (``mjcf/uav/``), split into the world and the
quadrotor (relative to its ``base_link``); :class:`UavView` draws them into a :class:`~mjnav.viz.Scene` and keeps
the vehicle, the reference (every trajectory pose received, a line) and the flown trail (a line through the true
positions) current.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import meshcat.geometry as mg
import mujoco
import numpy as np

from mjnav.viz.layers import pose_msg_matrix
from mjnav.viz.model import _SHAPES, VisualGeom, _rgba, homogeneous
from mjnav.viz.scene import Scene
from mjnav.viz.view import geom_objects

ROOT = "/mjnav_uav"
#: Trail points per drawn line object: finished chunks stay, only the newest is redrawn (cost independent of length).
TRAIL_CHUNK = 200
REFERENCE_COLOUR = 0x1F77B4
TRAIL_COLOUR = 0xD62728


@dataclass(frozen=True)
class UavVisual:
    """What the viewer draws of a UAV scene: world geoms (world frame), quadrotor geoms (``base_link`` frame)."""

    name: str
    world_geoms: tuple[VisualGeom, ...]
    uav_geoms: tuple[VisualGeom, ...]
    start: np.ndarray


def load_uav_visual(world: str | Path = "field") -> UavVisual:
    """Compile a UAV scene and collect its visible geoms (groups 0–2; planes as 24 m squares).

    Raises:
        mjnav.sim.UnknownWorldError, mjnav.sim.ModelLoadError: as :class:`~mjnav.sim.uav.UavSimulator`.
    """
    from mjnav.sim.uav import UavSimulator

    sim = UavSimulator(world)
    model, data = sim.model, sim.data
    mujoco.mj_kinematics(model, data)
    body = sim.body_id
    base_inv = np.linalg.inv(homogeneous(data.xmat[body].reshape(3, 3), data.xpos[body]))
    world_geoms, uav_geoms = [], []
    for g in range(model.ngeom):
        shape = _SHAPES.get(int(model.geom_type[g]))
        rgba = _rgba(model, g)
        if int(model.geom_group[g]) > 2 or shape is None or shape == "mesh" or rgba[3] <= 0.0:
            continue
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom_{g}"
        sx, sy, sz = (float(v) for v in model.geom_size[g])
        if shape == "plane":
            sx, sy = sx or 12.0, sy or 12.0
        pose = homogeneous(data.geom_xmat[g].reshape(3, 3), data.geom_xpos[g])
        if int(model.geom_bodyid[g]) == body:
            uav_geoms.append(VisualGeom(name.removeprefix("uav/"), shape, (sx, sy, sz), rgba, base_inv @ pose))
        else:
            world_geoms.append(VisualGeom(name, shape, (sx, sy, sz), rgba, pose))
    return UavVisual(sim.path.stem, tuple(world_geoms), tuple(uav_geoms), sim.truth().position_m)


class UavView:
    """Draws the UAV scene, moves the vehicle and extends the reference and the trail.

    Args:
        scene: where to draw.
        trail_spacing_m: a true position joins the trail when it is this far from the last one, metres.
    """

    def __init__(self, scene: Scene, trail_spacing_m: float = 0.02) -> None:
        self.scene = scene
        self.trail_spacing_m = trail_spacing_m
        self.trail: list[np.ndarray] = []  # the newest chunk of the trail
        self._trail_chunks = 0
        self.reference: dict[int, np.ndarray] = {}  # stamp (ns) -> position
        self.drawn: dict[str, int] = {}

    def setup(self, visual: UavVisual) -> None:
        """Background, camera (south-west of the pad, looking at it from above), world and vehicle."""
        s = self.scene
        s.set_property("/Background", "visible", False)
        s.set_property("/Grid", "visible", False)
        s.set_property("/Cameras/default/rotated/<object>", "position", [-4.0, 3.5, 4.0])
        s.delete(ROOT)
        for geom in visual.world_geoms:
            self._draw_geom(f"{ROOT}/world/{geom.name}", geom)
        for geom in visual.uav_geoms:
            self._draw_geom(f"{ROOT}/uav/{geom.name}", geom)
        start = np.eye(4)
        start[:3, 3] = visual.start
        s.set_transform(f"{ROOT}/uav", start)

    def _draw_geom(self, path: str, geom: VisualGeom) -> None:
        for sub, obj, transform in geom_objects(geom):
            node = f"{path}/{sub}" if sub else path
            self.scene.set_object(node, obj)
            self.scene.set_transform(node, transform)

    def set_pose(self, pose_msg: Any, *, redraw_trail: bool = True, place: bool = True) -> None:
        """Extend the trail with a geometry_msgs/PoseStamped (true pose, ENU) and, with ``place``, move the vehicle
        there (a batch of poses moves it once, to its last: every move is a message to the viewer)."""
        m = pose_msg_matrix(pose_msg.pose)
        if place:
            self.scene.set_transform(f"{ROOT}/uav", m)
            self._count("uav")
        p = m[:3, 3].copy()
        if not self.trail or np.linalg.norm(p - self.trail[-1]) >= self.trail_spacing_m:
            self.trail.append(p)
            if len(self.trail) > TRAIL_CHUNK:  # freeze the full chunk; the next one starts at its last point
                self._line(f"trail/{self._trail_chunks}", np.array(self.trail), TRAIL_COLOUR)
                self._trail_chunks += 1
                self.trail = self.trail[-1:]
            elif redraw_trail and len(self.trail) >= 2:
                self._line(f"trail/{self._trail_chunks}", np.array(self.trail), TRAIL_COLOUR)

    def add_trajectory(self, path_msg: Any) -> None:
        """Merge a trajectory's stamped poses into the reference and redraw it."""
        from mjnav.msgs import uav as uav_msgs

        ts, pts, _ = uav_msgs.trajectory_arrays(path_msg)
        for t, p in zip(ts, pts, strict=True):
            self.reference[round(t * 1e9)] = p
        if len(self.reference) >= 2:
            ordered = np.array([self.reference[k] for k in sorted(self.reference)])
            self._line("reference", ordered, REFERENCE_COLOUR)
        self._count("reference")

    def _line(self, name: str, points: np.ndarray, colour: int) -> None:
        geometry = mg.PointsGeometry(points.T.astype(np.float32))
        self.scene.set_object(f"{ROOT}/{name}", mg.Line(geometry, mg.LineBasicMaterial(color=colour, linewidth=2.0)))

    def _count(self, layer: str) -> None:
        self.drawn[layer] = self.drawn.get(layer, 0) + 1

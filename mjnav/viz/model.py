"""What the viewer draws of an MJCF world: its visible geoms, split into the static world and the robot.

The world is compiled with :func:`mjnav.sim.model.load_world` (the same loader as the simulator), and every visible
geom (alpha > 0, geom group 0–2 as in MuJoCo's viewer) is described by a :class:`VisualGeom`: its shape and MuJoCo
sizes, its colour as MuJoCo would render it (geom ``rgba`` when set explicitly, else the material colour times the
mean texture colour) and its pose. World-body geoms are posed in the ``map`` frame; robot geoms relative to
``base_link`` (so drawing the robot at a pose is one transform); geoms of other moving bodies (the warehouse's
carts) relative to their body, a :class:`MovingBody` that starts where the model puts it and follows the sim's
``obstacles`` topic (transforms ``map`` → body name).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjnav.geometry import Pose2D

#: MuJoCo's default geom rgba: a geom with this colour and a material takes the material's colour.
_DEFAULT_RGBA = (0.5, 0.5, 0.5, 1.0)
#: Half extent (m) used for an infinite plane (size 0) when the world has no other geoms to size it.
_DEFAULT_PLANE_HALF_M = 10.0


@dataclass(frozen=True)
class VisualGeom:
    """One visible MuJoCo geom.

    Attributes:
        name: geom name (``geom_<id>`` when unnamed), without the robot prefix.
        shape: ``box``, ``sphere``, ``cylinder``, ``capsule``, ``ellipsoid``, ``plane`` or ``mesh``.
        size: MuJoCo ``geom_size`` (half sizes / radius, half length), metres.
        rgba: colour and opacity, each in [0, 1].
        pose: (4, 4) homogeneous transform of the geom frame in its parent frame (``map`` or ``base_link``).
        vertices: (V, 3) float32 mesh vertices in the geom frame, metres (``mesh`` only).
        faces: (F, 3) uint32 vertex indices (``mesh`` only).
    """

    name: str
    shape: str
    size: tuple[float, float, float]
    rgba: tuple[float, float, float, float]
    pose: NDArray[np.float64]
    vertices: NDArray[np.float32] | None = None
    faces: NDArray[np.uint32] | None = None


@dataclass(frozen=True)
class MovingBody:
    """A body outside the robot that moves (e.g. a warehouse cart).

    Attributes:
        name: MJCF body name (``body_<id>`` when unnamed): the ``child_frame_id`` of its transform on ``obstacles``.
        pose: (4, 4) initial pose of the body in ``map``.
        geoms: its visible geoms, posed relative to the body.
    """

    name: str
    pose: NDArray[np.float64]
    geoms: tuple[VisualGeom, ...]


@dataclass(frozen=True)
class VisualModel:
    """The drawable content of a world.

    Attributes:
        name: world name (file stem).
        path: MJCF file.
        world_geoms: static geoms in the ``map`` frame (floor, walls, furniture).
        moving_bodies: bodies outside the robot that move, with their geoms.
        robot_geoms: robot geoms relative to ``base_link``.
        laser_pose: (4, 4) pose of the lidar (frame ``laser``) relative to ``base_link``.
        start: robot start pose in ``map``.
        goal: the world's default goal in ``map``, or None.
        bounds_m: (x_min, y_min, x_max, y_max) of the non-plane static geoms, or None when there are none.
    """

    name: str
    path: Path
    world_geoms: tuple[VisualGeom, ...]
    moving_bodies: tuple[MovingBody, ...]
    robot_geoms: tuple[VisualGeom, ...]
    laser_pose: NDArray[np.float64]
    start: Pose2D
    goal: Pose2D | None
    bounds_m: tuple[float, float, float, float] | None

    def view_bounds(self, margin_m: float = 0.5) -> tuple[float, float, float, float]:
        """Region worth framing: the static bounds (or ±2 m around the start) grown by ``margin_m``."""
        if self.bounds_m is not None:
            x0, y0, x1, y1 = self.bounds_m
        else:
            s = self.start
            x0, y0, x1, y1 = s.x - 2.0, s.y - 2.0, s.x + 2.0, s.y + 2.0
        return x0 - margin_m, y0 - margin_m, x1 + margin_m, y1 + margin_m


def homogeneous(rotation: NDArray[np.float64], translation: NDArray[np.float64]) -> NDArray[np.float64]:
    """(4, 4) transform from a (3, 3) rotation and a (3,) translation."""
    out = np.eye(4)
    out[:3, :3] = rotation
    out[:3, 3] = translation
    return out


def load_visual_model(world: str | Path) -> VisualModel:
    """Compile ``world`` (bundled name or MJCF path) and collect what the viewer draws.

    Raises:
        mjnav.sim.UnknownWorldError, mjnav.sim.ModelLoadError, mjnav.sim.RobotNotFoundError: as
            :func:`mjnav.sim.model.load_world`.
    """
    from mjnav.sim.model import body_name, is_static_body, load_world, moving_bodies

    loaded = load_world(world)
    model, robot = loaded.model, loaded.robot
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)

    base = homogeneous(data.xmat[robot.root_body].reshape(3, 3), data.xpos[robot.root_body])
    base_inv = np.linalg.inv(base)
    robot_geoms = {int(g) for g in robot.robot_geoms}
    plane_half = _plane_extent(loaded.info.bounds_m)

    world_geoms: list[VisualGeom] = []
    body_pose = {b: homogeneous(data.xmat[b].reshape(3, 3), data.xpos[b]) for b in moving_bodies(model, robot)}
    moving: dict[int, list[VisualGeom]] = {b: [] for b in body_pose}
    robot_list: list[VisualGeom] = []
    colours: dict[tuple[tuple[float, ...], int], tuple[float, float, float, float]] = {}
    for g in range(model.ngeom):
        if int(model.geom_group[g]) > 2:
            continue
        key = (tuple(model.geom_rgba[g].tolist()), int(model.geom_matid[g]))
        rgba = colours.get(key)
        if rgba is None:  # a map world has thousands of boxes and one colour
            rgba = colours[key] = _rgba(model, g)
        if rgba[3] <= 0.0:
            continue
        shape = _SHAPES.get(int(model.geom_type[g]))
        if shape is None:  # height fields, SDFs: not drawn
            continue
        pose = homogeneous(data.geom_xmat[g].reshape(3, 3), data.geom_xpos[g])
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom_{g}"
        sx, sy, sz = (float(v) for v in model.geom_size[g])
        if shape == "plane":
            sx, sy = sx or plane_half[0], sy or plane_half[1]
        size3 = (sx, sy, sz)
        vertices = faces = None
        if shape == "mesh":
            mesh = int(model.geom_dataid[g])
            v0, nv = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
            f0, nf = int(model.mesh_faceadr[mesh]), int(model.mesh_facenum[mesh])
            vertices = np.asarray(model.mesh_vert[v0 : v0 + nv], dtype=np.float32)
            faces = np.asarray(model.mesh_face[f0 : f0 + nf], dtype=np.uint32)
        if g in robot_geoms:
            name = name.removeprefix(robot.prefix)
            robot_list.append(VisualGeom(name, shape, size3, rgba, base_inv @ pose, vertices, faces))
        elif is_static_body(model, int(model.geom_bodyid[g])):
            world_geoms.append(VisualGeom(name, shape, size3, rgba, pose, vertices, faces))
        else:
            body = int(model.geom_bodyid[g])
            rel = np.linalg.inv(body_pose[body]) @ pose
            moving[body].append(VisualGeom(name, shape, size3, rgba, rel, vertices, faces))

    lidar = homogeneous(data.site_xmat[robot.lidar_site].reshape(3, 3), data.site_xpos[robot.lidar_site])
    info = loaded.info
    return VisualModel(
        name=info.name,
        path=info.path,
        world_geoms=tuple(world_geoms),
        moving_bodies=tuple(
            MovingBody(body_name(model, b), body_pose[b], tuple(geoms)) for b, geoms in moving.items() if geoms
        ),
        robot_geoms=tuple(robot_list),
        laser_pose=base_inv @ lidar,
        start=info.start,
        goal=info.goal,
        bounds_m=info.bounds_m,
    )


def _plane_extent(bounds: tuple[float, float, float, float] | None) -> tuple[float, float]:
    if bounds is None:
        return _DEFAULT_PLANE_HALF_M, _DEFAULT_PLANE_HALF_M
    x0, y0, x1, y1 = bounds
    half = max(abs(x0), abs(x1), abs(y0), abs(y1)) + 1.0
    return half, half


def _rgba(model: mujoco.MjModel, g: int) -> tuple[float, float, float, float]:
    """The colour MuJoCo renders geom ``g`` with: explicit rgba wins, else material colour × mean texture colour."""
    r, gr, b, a = (float(v) for v in model.geom_rgba[g])
    mat = int(model.geom_matid[g])
    if mat < 0 or not np.allclose((r, gr, b, a), _DEFAULT_RGBA):
        return r, gr, b, a
    colour = np.array(model.mat_rgba[mat], dtype=np.float64)
    texids = np.atleast_1d(model.mat_texid[mat])
    tex = int(texids[1]) if texids.size > 1 else int(texids[0])  # texture role 1 = RGB (MuJoCo >= 3.1)
    if tex >= 0:
        adr, channels = int(model.tex_adr[tex]), int(model.tex_nchannel[tex])
        count = int(model.tex_width[tex]) * int(model.tex_height[tex]) * channels
        pixels = np.asarray(model.tex_data[adr : adr + count], dtype=np.float64).reshape(-1, channels)
        if channels >= 3:
            colour[:3] *= pixels[:, :3].mean(axis=0) / 255.0
    return float(colour[0]), float(colour[1]), float(colour[2]), float(colour[3])


_SHAPES: dict[int, str] = {
    int(mujoco.mjtGeom.mjGEOM_PLANE): "plane",
    int(mujoco.mjtGeom.mjGEOM_SPHERE): "sphere",
    int(mujoco.mjtGeom.mjGEOM_CAPSULE): "capsule",
    int(mujoco.mjtGeom.mjGEOM_ELLIPSOID): "ellipsoid",
    int(mujoco.mjtGeom.mjGEOM_CYLINDER): "cylinder",
    int(mujoco.mjtGeom.mjGEOM_BOX): "box",
    int(mujoco.mjtGeom.mjGEOM_MESH): "mesh",
}

"""Load a world: parse the MJCF, find the robot, add the collision sensors, compile, resolve names to ids.

The robot is found by name, not by position in the file: the one body whose name ends in ``base_link`` and
that has a free joint. Whatever precedes ``base_link`` is the attach prefix (``robot/`` in the bundled scenes,
empty for ``mjcf/diffbot.xml`` itself); every other robot element is looked up as prefix + its name in
``diffbot.xml``.

Two ``contact`` sensors are added to every loaded model (``data="found"``): contacts of the robot subtree with
anything, and contacts of the robot subtree with each floor geom. Their difference is the number of contacts
between the robot and anything but the floor, computed by MuJoCo inside ``mj_step`` — the stepping loop then
only compares two numbers. The *floor* is every plane geom of the world body.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjnav.geometry import Pose2D, quaternion_to_yaw
from mjnav.robot import LIDAR_SITE, DescriptionError, RobotDescription, parse_robot_description
from mjnav.sim.errors import ModelLoadError, RobotNotFoundError
from mjnav.sim.worlds import GOAL_NUMERIC, WorldInfo, goal_from_numeric, resolve_world

#: Geom group of every robot geom; the lidar's geomgroup mask leaves this group out.
ROBOT_GEOM_GROUP = 2

_BASE = "base_link"
_CONTACT_ALL = "mjnav_contact_robot_all"
_CONTACT_FLOOR = "mjnav_contact_robot_floor"
# contact sensor intprm: (data fields bitmask: 1 = "found", reduce: 0 = none, num slots)
_CONTACT_FOUND = (1, 0, 1)


@dataclass(frozen=True, slots=True)
class RobotBinding:
    """Ids and addresses of the robot's elements in a compiled model (resolved once at load).

    Attributes:
        prefix: name prefix of the robot's elements (``"robot/"`` in the bundled scenes).
        root_body: body id of ``base_link``.
        root_qpos: qpos address of the free joint (x, y, z, qw, qx, qy, qz).
        root_qvel: qvel address of the free joint (vx, vy, vz world frame; wx, wy, wz body frame).
        wheel_qpos: (2,) qpos addresses of the (left, right) wheel hinges.
        wheel_qvel: (2,) qvel addresses of the (left, right) wheel hinges.
        wheel_actuators: (2,) actuator ids of the (left, right) wheel velocity servos.
        max_wheel_speed_radps: smallest |ctrlrange| bound of the two servos, rad/s.
        wheel_diameter_m: drive wheel diameter W, metres.
        wheel_separation_m: distance between the wheel centres L, metres.
        wheel_vel_noise_radps: encoder velocity noise std (from the jointvel sensors' ``noise``), rad/s.
        gyro_adr: sensordata address of the 3-axis gyro.
        accel_adr: sensordata address of the 3-axis accelerometer.
        gyro_noise: gyro noise std, rad/s.
        accel_noise: accelerometer noise std, m/s².
        imu_site: site id of the IMU.
        lidar_site: site id of the lidar.
        contact_all_adr: sensordata address of "robot contacts with anything" (count).
        contact_floor_adrs: sensordata addresses of "robot contacts with floor geom i" (counts).
        robot_geoms: (G,) ids of every geom in the robot subtree.
        floor_geoms: (F,) ids of the floor plane geoms.
        wheel_joint_names: joint names without prefix, for ``sensor_msgs/JointState``.
    """

    prefix: str
    root_body: int
    root_qpos: int
    root_qvel: int
    wheel_qpos: tuple[int, int]
    wheel_qvel: tuple[int, int]
    wheel_actuators: tuple[int, int]
    max_wheel_speed_radps: float
    wheel_diameter_m: float
    wheel_separation_m: float
    wheel_vel_noise_radps: float
    gyro_adr: int
    accel_adr: int
    gyro_noise: float
    accel_noise: float
    imu_site: int
    lidar_site: int
    contact_all_adr: int
    contact_floor_adrs: tuple[int, ...]
    robot_geoms: NDArray[np.int32]
    floor_geoms: NDArray[np.int32]
    wheel_joint_names: tuple[str, str] = ("left_wheel_joint", "right_wheel_joint")


@dataclass(frozen=True, slots=True)
class LoadedWorld:
    """A compiled world: the MuJoCo model, what the demo needs to know, the robot's ids and its description (the
    MJCF the sim publishes on ``robot_description``, parsed)."""

    model: mujoco.MjModel
    info: WorldInfo
    robot: RobotBinding
    description: RobotDescription


def _find_robot_root(spec: mujoco.MjSpec, path: Path) -> mujoco.MjsBody:
    candidates = [
        b for b in spec.bodies if b.name.endswith(_BASE) and any(j.type == mujoco.mjtJoint.mjJNT_FREE for j in b.joints)
    ]
    if not candidates:
        raise RobotNotFoundError(
            f"{path}: no robot found (need a body named '*{_BASE}' with a free joint, e.g. "
            '<attach model="diffbot" body="base_link" prefix="robot/"/>)'
        )
    if len(candidates) > 1:
        names = ", ".join(b.name for b in candidates)
        raise RobotNotFoundError(f"{path}: several robots ({names}); one robot per world is supported")
    return candidates[0]


def _floor_names(spec: mujoco.MjSpec) -> list[str]:
    """Names of the world-body plane geoms, naming unnamed ones so sensors can refer to them.

    The planes are found in a first compilation (0.15 s on a map world of 33,000 boxes): going through the spec's
    geoms costs more than linear time (``spec.geoms`` 1.8 s there). Only an unnamed plane is looked up in the spec,
    by its place among the world body's geoms.
    """
    model = spec.compile()
    first = int(model.body_geomadr[0])
    planes = np.flatnonzero((model.geom_bodyid == 0) & (model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE))
    names: list[str] = []
    for g in planes.tolist():
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        if not name:
            geom = spec.worldbody.first_geom()
            for _ in range(g - first):
                geom = spec.worldbody.next_geom(geom)
            name = geom.name = f"mjnav_floor_{g}"
        names.append(name)
    return names


def _id(model: mujoco.MjModel, objtype: mujoco.mjtObj, name: str, path: Path) -> int:
    idx = int(mujoco.mj_name2id(model, objtype, name))
    if idx < 0:
        kind = objtype.name.removeprefix("mjOBJ_").lower()
        raise RobotNotFoundError(f"{path}: the robot has no {kind} named {name!r}")
    return idx


def _sensor(model: mujoco.MjModel, name: str, path: Path) -> tuple[int, float]:
    sid = _id(model, mujoco.mjtObj.mjOBJ_SENSOR, name, path)
    return int(model.sensor_adr[sid]), float(model.sensor_noise[sid])


def subtree_bodies(model: mujoco.MjModel, root: int) -> list[int]:
    bodies = []
    for b in range(model.nbody):
        a = b
        while a > 0 and a != root:
            a = int(model.body_parentid[a])
        if a == root:
            bodies.append(b)
    return bodies


def is_static_body(model: mujoco.MjModel, body: int) -> bool:
    """Whether ``body`` and all its ancestors are welded to the world (no joints)."""
    while body > 0:
        if int(model.body_jntnum[body]) > 0:
            return False
        body = int(model.body_parentid[body])
    return True


def moving_bodies(model: mujoco.MjModel, robot: RobotBinding) -> tuple[int, ...]:
    """Ids of the bodies outside the robot that can move (they or an ancestor have a joint), e.g. the
    warehouse's carts."""
    robot_bodies = set(subtree_bodies(model, robot.root_body))
    return tuple(b for b in range(1, model.nbody) if b not in robot_bodies and not is_static_body(model, b))


def body_name(model: mujoco.MjModel, body: int) -> str:
    """The body's MJCF name, or ``body_<id>`` for an unnamed body."""
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f"body_{body}"


def _bind_robot(model: mujoco.MjModel, prefix: str, floors: list[str], path: Path) -> RobotBinding:
    obj = mujoco.mjtObj
    root = _id(model, obj.mjOBJ_BODY, prefix + _BASE, path)
    free = int(model.body_jntadr[root])
    if free < 0 or model.jnt_type[free] != mujoco.mjtJoint.mjJNT_FREE:
        raise RobotNotFoundError(f"{path}: {prefix + _BASE} has no free joint")
    joints = [_id(model, obj.mjOBJ_JOINT, f"{prefix}{side}_wheel_joint", path) for side in ("left", "right")]
    acts = [_id(model, obj.mjOBJ_ACTUATOR, f"{prefix}{side}_motor", path) for side in ("left", "right")]
    wheel_geoms = [_id(model, obj.mjOBJ_GEOM, f"{prefix}{side}_wheel", path) for side in ("left", "right")]
    wheel_bodies = [int(model.jnt_bodyid[j]) for j in joints]
    ctrl_max = float(np.min(np.abs(model.actuator_ctrlrange[acts])))
    if ctrl_max <= 0.0:
        raise RobotNotFoundError(f"{path}: the wheel motors need a non-zero ctrlrange")
    radius = float(model.geom_size[wheel_geoms[0], 0])
    separation = float(np.linalg.norm(model.body_pos[wheel_bodies[0]] - model.body_pos[wheel_bodies[1]]))
    lvel_adr, vel_noise = _sensor(model, f"{prefix}left_wheel_vel", path)
    gyro_adr, gyro_noise = _sensor(model, f"{prefix}imu_gyro", path)
    accel_adr, accel_noise = _sensor(model, f"{prefix}imu_accel", path)
    contact_all, _ = _sensor(model, _CONTACT_ALL, path)
    contact_floor = tuple(_sensor(model, f"{_CONTACT_FLOOR}_{i}", path)[0] for i in range(len(floors)))
    bodies = set(subtree_bodies(model, root))
    robot_geoms = np.array([g for g in range(model.ngeom) if int(model.geom_bodyid[g]) in bodies], np.int32)
    floor_geoms = np.array([_id(model, obj.mjOBJ_GEOM, n, path) for n in floors], np.int32)
    return RobotBinding(
        prefix=prefix,
        root_body=root,
        root_qpos=int(model.jnt_qposadr[free]),
        root_qvel=int(model.jnt_dofadr[free]),
        wheel_qpos=(int(model.jnt_qposadr[joints[0]]), int(model.jnt_qposadr[joints[1]])),
        wheel_qvel=(int(model.jnt_dofadr[joints[0]]), int(model.jnt_dofadr[joints[1]])),
        wheel_actuators=(acts[0], acts[1]),
        max_wheel_speed_radps=ctrl_max,
        wheel_diameter_m=2.0 * radius,
        wheel_separation_m=separation,
        wheel_vel_noise_radps=vel_noise if lvel_adr >= 0 else 0.0,
        gyro_adr=gyro_adr,
        accel_adr=accel_adr,
        gyro_noise=gyro_noise,
        accel_noise=accel_noise,
        imu_site=_id(model, obj.mjOBJ_SITE, f"{prefix}imu", path),
        lidar_site=_id(model, obj.mjOBJ_SITE, f"{prefix}{LIDAR_SITE}", path),
        contact_all_adr=contact_all,
        contact_floor_adrs=contact_floor,
        robot_geoms=robot_geoms,
        floor_geoms=floor_geoms,
    )


def static_bounds(model: mujoco.MjModel, data: mujoco.MjData) -> tuple[float, float, float, float] | None:
    """(x_min, y_min, x_max, y_max) of the world-body geoms that are not planes, metres; None if none.

    ``data`` must hold the kinematics (after ``mj_forward`` or ``mj_kinematics``).
    """
    g = np.flatnonzero((model.geom_bodyid == 0) & (model.geom_type != mujoco.mjtGeom.mjGEOM_PLANE))
    if g.size == 0:
        return None
    rot = data.geom_xmat[g].reshape(-1, 3, 3)
    centre = data.geom_xpos[g] + np.einsum("gij,gj->gi", rot, model.geom_aabb[g, :3])
    half = np.einsum("gij,gj->gi", np.abs(rot), model.geom_aabb[g, 3:])
    lo = (centre[:, :2] - half[:, :2]).min(axis=0)
    hi = (centre[:, :2] + half[:, :2]).max(axis=0)
    if not np.all(np.isfinite(lo)):
        return None
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def root_pose(model: mujoco.MjModel, qpos: NDArray[np.float64], robot: RobotBinding) -> Pose2D:
    """Planar pose (x, y, yaw) of the robot's free joint in ``qpos`` (map frame)."""
    a = robot.root_qpos
    w, x, y, z = (float(v) for v in qpos[a + 3 : a + 7])
    return Pose2D(float(qpos[a]), float(qpos[a + 1]), quaternion_to_yaw(x, y, z, w))


def load_world(world: str | Path, *, timestep_s: float | None = None) -> LoadedWorld:
    """Parse and compile a world, add the collision sensors and resolve the robot's names to ids.

    Args:
        world: bundled world name or path to an MJCF file containing the robot.
        timestep_s: physics step, seconds; ``None`` keeps the model's ``<option timestep>``.

    Returns:
        The compiled model, its :class:`WorldInfo` and the robot's :class:`RobotBinding`.

    Raises:
        UnknownWorldError: the world is neither a bundled name nor a file.
        ModelLoadError: MuJoCo cannot parse or compile the file (its message is included).
        RobotNotFoundError: no robot, several robots, or a robot element is missing.
    """
    path = resolve_world(world)
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except Exception as exc:  # MuJoCo raises ValueError with the parser's message
        raise ModelLoadError(f"{path}: {exc}") from exc
    root = _find_robot_root(spec, path)
    prefix = root.name[: -len(_BASE)]
    try:
        floors = _floor_names(spec)
    except Exception as exc:  # the first compilation: MuJoCo's ValueError with its message
        raise ModelLoadError(f"{path}: {exc}") from exc
    sens, obj = mujoco.mjtSensor.mjSENS_CONTACT, mujoco.mjtObj
    spec.add_sensor(
        name=_CONTACT_ALL, type=sens, objtype=obj.mjOBJ_XBODY, objname=root.name, intprm=list(_CONTACT_FOUND)
    )
    for i, floor in enumerate(floors):
        spec.add_sensor(
            name=f"{_CONTACT_FLOOR}_{i}",
            type=sens,
            objtype=obj.mjOBJ_XBODY,
            objname=root.name,
            reftype=obj.mjOBJ_GEOM,
            refname=floor,
            intprm=list(_CONTACT_FOUND),
        )
    try:
        model = spec.compile()
    except Exception as exc:
        raise ModelLoadError(f"{path}: {exc}") from exc
    if timestep_s is not None:
        if not (math.isfinite(timestep_s) and timestep_s > 0.0):
            raise ModelLoadError(f"timestep_s must be a positive number of seconds, got {timestep_s}")
        model.opt.timestep = timestep_s
    robot = _bind_robot(model, prefix, floors, path)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    goal = None
    gid = int(mujoco.mj_name2id(model, obj.mjOBJ_NUMERIC, GOAL_NUMERIC))
    if gid >= 0:
        adr, size = int(model.numeric_adr[gid]), int(model.numeric_size[gid])
        try:
            goal = goal_from_numeric(model.numeric_data[adr : adr + size].tolist())
        except ValueError as exc:
            raise ModelLoadError(f"{path}: {exc}") from exc
    from mjnav.sim.description import robot_description

    try:
        description = parse_robot_description(robot_description(model, robot, prefix.rstrip("/") or spec.modelname))
    except DescriptionError as exc:
        raise ModelLoadError(f"{path}: robot description: {exc}") from exc
    info = WorldInfo(
        name=path.stem,
        path=path,
        start=root_pose(model, model.qpos0, robot),
        goal=goal,
        bounds_m=static_bounds(model, data),
        robot_radius_m=description.radius_m,
        lidar_offset_m=description.frame(LIDAR_SITE).xyz_m,
    )
    return LoadedWorld(model=model, info=info, robot=robot, description=description)

"""The robot's description as the sim publishes it: a self-contained MJCF of the robot, written from the compiled
world (as ROS's robot_state_publisher publishes the expanded URDF).

The scene may attach the robot from a file, with default classes and a name prefix (``robot/``); what goes on the
wire is flattened: the robot's bodies (``base_link`` at the origin), joints, inertias, geoms, sites, actuators,
sensors and ``lidar_*`` numerics with every attribute explicit and the prefix removed. MuJoCo compiles it into the
same robot, and :func:`mjnav.robot.parse_robot_description` reads it without knowing the scene.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable

import mujoco

from mjnav.sim.errors import ModelLoadError
from mjnav.sim.model import RobotBinding, subtree_bodies
from mjnav.sim.worlds import GOAL_NUMERIC

_GEOM_SIZES = {"sphere": 1, "capsule": 2, "cylinder": 2, "box": 3, "ellipsoid": 3}
_JOINTS = {
    mujoco.mjtJoint.mjJNT_HINGE: "hinge",
    mujoco.mjtJoint.mjJNT_SLIDE: "slide",
    mujoco.mjtJoint.mjJNT_BALL: "ball",
}


def _num(values: Iterable[float]) -> str:
    return " ".join(repr(float(v)) for v in values)


def robot_description(model: mujoco.MjModel, robot: RobotBinding, name: str = "robot") -> str:
    """The MJCF text of the robot in a compiled world.

    Args:
        model: the compiled world.
        robot: the robot's ids in it.
        name: the ``<mujoco model>`` name.

    Raises:
        ModelLoadError: the robot has a geom the description cannot carry (a mesh, a height field).
    """
    prefix = robot.prefix
    obj = mujoco.mjtObj

    def bare(objtype: mujoco.mjtObj, i: int) -> str:
        full = mujoco.mj_id2name(model, objtype, i) or ""
        return full[len(prefix) :] if full.startswith(prefix) else full

    bodies = subtree_bodies(model, robot.root_body)
    in_robot = set(bodies)
    root = ET.Element("mujoco", model=name)
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    world = ET.SubElement(root, "worldbody")
    elements: dict[int, ET.Element] = {}
    for b in bodies:
        parent = world if b == robot.root_body else elements[int(model.body_parentid[b])]
        attrs = {"name": bare(obj.mjOBJ_BODY, b)}
        if b != robot.root_body:  # the root is the base frame: at the origin
            attrs |= {"pos": _num(model.body_pos[b]), "quat": _num(model.body_quat[b])}
        body = elements[b] = ET.SubElement(parent, "body", attrs)
        if model.body_mass[b] > 0:
            ET.SubElement(
                body,
                "inertial",
                pos=_num(model.body_ipos[b]),
                quat=_num(model.body_iquat[b]),
                mass=repr(float(model.body_mass[b])),
                diaginertia=_num(model.body_inertia[b]),
            )
        for j in range(int(model.body_jntadr[b]), int(model.body_jntadr[b] + model.body_jntnum[b])):
            jname = bare(obj.mjOBJ_JOINT, j)
            kind = model.jnt_type[j]
            if kind == mujoco.mjtJoint.mjJNT_FREE:
                ET.SubElement(body, "freejoint", name=jname)
                continue
            dof = int(model.jnt_dofadr[j])
            attrs = {
                "name": jname,
                "type": _JOINTS[mujoco.mjtJoint(kind)],
                "pos": _num(model.jnt_pos[j]),
                "axis": _num(model.jnt_axis[j]),
                "damping": repr(float(model.dof_damping[dof])),
                "armature": repr(float(model.dof_armature[dof])),
                "frictionloss": repr(float(model.dof_frictionloss[dof])),
            }
            if model.jnt_limited[j]:
                attrs["range"] = _num(model.jnt_range[j])
            ET.SubElement(body, "joint", attrs)
        for g in range(int(model.body_geomadr[b]), int(model.body_geomadr[b] + model.body_geomnum[b])):
            kind = mujoco.mjtGeom(model.geom_type[g]).name.removeprefix("mjGEOM_").lower()
            if kind not in _GEOM_SIZES:
                raise ModelLoadError(
                    f"robot geom {bare(obj.mjOBJ_GEOM, g)!r} is a {kind}: the robot description carries primitive "
                    f"geoms only ({', '.join(_GEOM_SIZES)})"
                )
            ET.SubElement(
                body,
                "geom",
                name=bare(obj.mjOBJ_GEOM, g),
                type=kind,
                size=_num(model.geom_size[g, : _GEOM_SIZES[kind]]),
                pos=_num(model.geom_pos[g]),
                quat=_num(model.geom_quat[g]),
                contype=str(int(model.geom_contype[g])),
                conaffinity=str(int(model.geom_conaffinity[g])),
                condim=str(int(model.geom_condim[g])),
                priority=str(int(model.geom_priority[g])),
                friction=_num(model.geom_friction[g]),
                group=str(int(model.geom_group[g])),
                rgba=" ".join(f"{float(v):.6g}" for v in model.geom_rgba[g]),  # float32 in MuJoCo
            )
        for s in range(model.nsite):
            if int(model.site_bodyid[s]) == b:
                ET.SubElement(
                    body,
                    "site",
                    name=bare(obj.mjOBJ_SITE, s),
                    pos=_num(model.site_pos[s]),
                    quat=_num(model.site_quat[s]),
                    size=_num(model.site_size[s, :1]),
                )
    joints = {j for j in range(model.njnt) if int(model.jnt_bodyid[j]) in in_robot}
    actuators = [
        a
        for a in range(model.nu)
        if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT and int(model.actuator_trnid[a, 0]) in joints
    ]
    if actuators:
        section = ET.SubElement(root, "actuator")
        for a in actuators:
            attrs = {
                "name": bare(obj.mjOBJ_ACTUATOR, a),
                "joint": bare(obj.mjOBJ_JOINT, int(model.actuator_trnid[a, 0])),
                "gaintype": mujoco.mjtGain(model.actuator_gaintype[a]).name.removeprefix("mjGAIN_").lower(),
                "biastype": mujoco.mjtBias(model.actuator_biastype[a]).name.removeprefix("mjBIAS_").lower(),
                "gainprm": _num(model.actuator_gainprm[a, :3]),
                "biasprm": _num(model.actuator_biasprm[a, :3]),
            }
            if model.actuator_ctrllimited[a]:
                attrs["ctrlrange"] = _num(model.actuator_ctrlrange[a])
            if model.actuator_forcelimited[a]:
                attrs["forcerange"] = _num(model.actuator_forcerange[a])
            ET.SubElement(section, "general", attrs)
    sensors = []
    for s in range(model.nsensor):
        kind = mujoco.mjtSensor(model.sensor_type[s]).name.removeprefix("mjSENS_").lower()
        objtype, objid = model.sensor_objtype[s], int(model.sensor_objid[s])
        if objtype == obj.mjOBJ_SITE and int(model.site_bodyid[objid]) in in_robot:
            sensors.append((kind, "site", bare(obj.mjOBJ_SITE, objid), s))
        elif objtype == obj.mjOBJ_JOINT and objid in joints:
            sensors.append((kind, "joint", bare(obj.mjOBJ_JOINT, objid), s))
    if sensors:
        section = ET.SubElement(root, "sensor")
        for kind, target, target_name, s in sensors:
            attrs = {"name": bare(obj.mjOBJ_SENSOR, s), target: target_name}
            if model.sensor_noise[s] > 0:
                attrs["noise"] = repr(float(model.sensor_noise[s]))
            ET.SubElement(section, kind, attrs)
    numerics = []
    for n in range(model.nnumeric):
        full = mujoco.mj_id2name(model, obj.mjOBJ_NUMERIC, n) or ""
        if full.startswith(prefix) and full != GOAL_NUMERIC:
            adr, size = int(model.numeric_adr[n]), int(model.numeric_size[n])
            numerics.append((full[len(prefix) :], model.numeric_data[adr : adr + size]))
    if numerics:
        custom = ET.SubElement(root, "custom")
        for numeric, data in numerics:
            ET.SubElement(custom, "numeric", name=numeric, data=_num(data))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"

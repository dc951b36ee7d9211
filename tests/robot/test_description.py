"""The robot description parser against MuJoCo's own compiler: the same frames, the same geoms, a footprint that
holds the robot, and clear errors for what it cannot read."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from mjnav.robot import CIRCLE_SIDES, DescriptionError, convex_hull, parse_robot_description
from mjnav.sim import Simulator
from tests.conftest import REPO

DIFFBOT = REPO / "mjcf" / "diffbot.xml"

# A robot written with every placement MJCF offers: degrees (the default), default classes with inheritance and
# childclass, euler/axisangle/xyaxes/zaxis/quat, fromto, a <frame>, nested bodies, an ellipsoid, a rotated lidar.
ODD_ROBOT = """
<mujoco model="odd">
  <compiler eulerseq="zyx"/>
  <default>
    <geom contype="1" conaffinity="1"/>
    <default class="body">
      <geom type="box" size="0.2 0.1 0.05"/>
      <default class="nose">
        <geom type="capsule" size="0.04 0.08" euler="0 90 0"/>
      </default>
    </default>
    <default class="ghost">
      <geom contype="0" conaffinity="0" type="sphere" size="0.9"/>
    </default>
  </default>
  <worldbody>
    <body name="base" pos="5 6 7" euler="0 0 30" childclass="body">
      <freejoint/>
      <geom name="hull" pos="0.05 0 0.1" euler="0 0 20"/>
      <geom name="nose" class="nose" pos="0.3 0 0.1"/>
      <geom name="ghost" class="ghost"/>
      <geom name="mast" type="cylinder" fromto="-0.1 0.1 0.1 -0.1 0.1 0.5" size="0.03"/>
      <geom name="skid" type="cylinder" size="0.02 0.1" pos="-0.2 -0.15 0.02" zaxis="1 0 0"/>
      <geom name="pod" type="ellipsoid" size="0.05 0.1 0.03" pos="0 -0.25 0.1" axisangle="0 0 1 45"/>
      <site name="laser" pos="0.2 0 0.3" euler="-90 0 0"/>
      <frame pos="0 0.1 0" xyaxes="0 1 0 -1 0 0">
        <site name="imu" pos="0.05 0 0.08"/>
        <body name="arm" pos="0.1 0 0.2" quat="0.9238795 0 0 0.3826834">
          <joint name="arm_joint" type="hinge" axis="0 0 1"/>
          <geom name="arm_box" size="0.15 0.02 0.02" pos="0.15 0 0"/>
          <site name="tool" pos="0.3 0 0" euler="10 20 30"/>
        </body>
      </frame>
    </body>
  </worldbody>
  <sensor>
    <gyro name="gyro" site="imu"/>
  </sensor>
  <custom>
    <numeric name="lidar_beams" data="270"/>
    <numeric name="lidar_fov_rad" data="4.71238898"/>
    <numeric name="lidar_range_max_m" data="10"/>
  </custom>
</mujoco>
"""


def _compiled_relative(text: str, base: str) -> tuple[mujoco.MjModel, mujoco.MjData, np.ndarray, np.ndarray]:
    """A MuJoCo model of ``text`` at its initial pose, and the base body's rotation and position (to express
    world-frame results in the base frame)."""
    model = mujoco.MjModel.from_xml_string(text)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, base)
    return model, data, data.xmat[b].reshape(3, 3).copy(), data.xpos[b].copy()


def _site_in_base(model: mujoco.MjModel, data: mujoco.MjData, rot: np.ndarray, pos: np.ndarray, name: str):
    s = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    return rot.T @ (data.site_xpos[s] - pos), rot.T @ data.site_xmat[s].reshape(3, 3)


def _quat_matrix(xyzw: tuple[float, float, float, float]) -> np.ndarray:
    x, y, z, w = xyzw
    m = np.empty(9)
    mujoco.mju_quat2Mat(m, np.array([w, x, y, z]))
    return m.reshape(3, 3)


def _inside(hull: np.ndarray, points: np.ndarray, tol: float = 1e-9) -> bool:
    """Whether every point lies in the counter-clockwise convex polygon ``hull``."""
    a, b = hull, np.roll(hull, -1, axis=0)
    for p in points:
        cross = (b[:, 0] - a[:, 0]) * (p[1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (p[0] - a[:, 0])
        if np.any(cross < -tol):
            return False
    return True


def _surface(kind: int, size: np.ndarray) -> np.ndarray:
    """(K, 3) points on a geom's surface in its own frame (MuJoCo's sizes)."""
    t = np.linspace(0.0, 2.0 * math.pi, 72, endpoint=False)
    ring = np.column_stack((np.cos(t), np.sin(t), np.zeros_like(t)))
    u = np.linspace(-1.0, 1.0, 9)
    g = mujoco.mjtGeom
    if kind == g.mjGEOM_BOX:
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * size
    if kind in (g.mjGEOM_SPHERE, g.mjGEOM_ELLIPSOID):
        dirs = np.vstack([np.cos(a) * ring + [0.0, 0.0, np.sin(a)] for a in np.linspace(-1.5, 1.5, 11)])
        return dirs * (size if kind == g.mjGEOM_ELLIPSOID else size[0])
    side = np.vstack([size[0] * ring + [0.0, 0.0, z * size[1]] for z in u])
    if kind == g.mjGEOM_CYLINDER:
        return side
    caps = np.vstack(
        [size[0] * _surface(g.mjGEOM_SPHERE, np.array([1.0])) + [0.0, 0.0, z] for z in (-size[1], size[1])]
    )
    return np.vstack((side, caps))


def _colliding_surfaces(model: mujoco.MjModel, data: mujoco.MjData, rot: np.ndarray, pos: np.ndarray):
    """Per colliding geom (name, (K, 2) base-frame ground projections of points on its surface), from MuJoCo's
    kinematics."""
    out = []
    for g in range(model.ngeom):
        if (model.geom_contype[g] | model.geom_conaffinity[g]) == 0:
            continue
        r = rot.T @ data.geom_xmat[g].reshape(3, 3)
        c = rot.T @ (data.geom_xpos[g] - pos)
        pts = c + _surface(model.geom_type[g], model.geom_size[g]) @ r.T
        out.append((mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g), pts[:, :2]))
    return out


def test_frames_and_geoms_of_every_placement_form_match_mujoco() -> None:
    d = parse_robot_description(ODD_ROBOT)
    model, data, rot, pos = _compiled_relative(ODD_ROBOT, "base")
    assert (d.name, d.base_frame, d.lidar_frame, d.imu_frame) == ("odd", "base", "laser", "imu")
    for name in ("laser", "imu", "tool"):
        xyz, mat = _site_in_base(model, data, rot, pos, name)
        frame = d.frame(name)
        np.testing.assert_allclose(frame.xyz_m, xyz, atol=1e-6, err_msg=name)
        np.testing.assert_allclose(_quat_matrix(frame.quat_xyzw), mat, atol=1e-6, err_msg=name)
    assert d.frame("laser").yaw_rad == pytest.approx(-math.pi / 2)
    # Every colliding geom, placed by MuJoCo, lies inside the footprint and within the radius, and the radius is
    # tight; the ghost (0.9 m, not colliding) is left out.
    surfaces = _colliding_surfaces(model, data, rot, pos)
    assert sorted(name for name, _ in surfaces) == ["arm_box", "hull", "mast", "nose", "pod", "skid"]
    reach = 0.0
    for name, pts in surfaces:
        assert _inside(d.footprint_m, pts), name
        reach = max(reach, float(np.max(np.hypot(pts[:, 0], pts[:, 1]))))
    assert reach - 1e-9 <= d.radius_m <= reach * 1.01
    assert d.lidar is not None and (d.lidar.num_beams, d.lidar.range_max_m) == (270, 10.0)
    assert d.lidar.fov_rad == pytest.approx(1.5 * math.pi)


@pytest.mark.parametrize("world", ["empty", "rooms", "maze", "warehouse"])
def test_the_sims_description_is_the_robot_of_its_world(world: str) -> None:
    sim = Simulator(world, lidar=None)
    d = sim.description
    model, data = sim.model, sim.data
    root = sim.robot.root_body
    rot, pos = data.xmat[root].reshape(3, 3), data.xpos[root]
    mujoco.mj_kinematics(model, data)
    for name in ("laser", "imu"):
        s = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, sim.robot.prefix + name)
        np.testing.assert_allclose(d.frame(name).xyz_m, rot.T @ (data.site_xpos[s] - pos), atol=1e-9)
    # The footprint radius: every colliding robot geom (spheres, vertical cylinders) reaches exactly this far.
    reach = 0.0
    for g in sim.robot.robot_geoms:
        if model.geom_contype[g] | model.geom_conaffinity[g]:
            c = rot.T @ (data.geom_xpos[g] - pos)
            reach = max(reach, math.hypot(c[0], c[1]) + model.geom_size[g, 0])
    assert d.radius_m == pytest.approx(reach, abs=1e-12)
    assert d.lidar is not None and d.lidar.num_beams == 360


def test_the_flattened_description_compiles_into_the_same_robot() -> None:
    sim = Simulator("rooms", lidar=None)
    flat = mujoco.MjModel.from_xml_string(sim.description.mjcf)
    model, prefix = sim.model, sim.robot.prefix
    obj = mujoco.mjtObj
    robot_geoms = [mujoco.mj_id2name(model, obj.mjOBJ_GEOM, g) for g in sim.robot.robot_geoms]
    assert flat.ngeom == len(robot_geoms)
    for full in robot_geoms:
        g, f = (
            mujoco.mj_name2id(model, obj.mjOBJ_GEOM, full),
            mujoco.mj_name2id(flat, obj.mjOBJ_GEOM, full[len(prefix) :]),
        )
        for attr in ("geom_type", "geom_size", "geom_pos", "geom_quat", "geom_contype", "geom_conaffinity"):
            np.testing.assert_allclose(getattr(flat, attr)[f], getattr(model, attr)[g], atol=1e-12, err_msg=attr)
    for name in ("base_link", "left_wheel", "right_wheel"):
        b, f = mujoco.mj_name2id(model, obj.mjOBJ_BODY, prefix + name), mujoco.mj_name2id(flat, obj.mjOBJ_BODY, name)
        assert flat.body_mass[f] == pytest.approx(model.body_mass[b])
        np.testing.assert_allclose(flat.body_inertia[f], model.body_inertia[b], rtol=1e-9)
    for name in ("left_motor", "right_motor"):
        a, f = (
            mujoco.mj_name2id(model, obj.mjOBJ_ACTUATOR, prefix + name),
            mujoco.mj_name2id(flat, obj.mjOBJ_ACTUATOR, name),
        )
        for attr in ("actuator_ctrlrange", "actuator_forcerange", "actuator_gainprm", "actuator_biasprm"):
            np.testing.assert_allclose(getattr(flat, attr)[f], getattr(model, attr)[a], err_msg=attr)
    for name in ("left_wheel_vel", "imu_gyro", "imu_accel"):
        s, f = (
            mujoco.mj_name2id(model, obj.mjOBJ_SENSOR, prefix + name),
            mujoco.mj_name2id(flat, obj.mjOBJ_SENSOR, name),
        )
        assert (flat.sensor_type[f], flat.sensor_noise[f]) == (model.sensor_type[s], model.sensor_noise[s])


def test_the_robot_file_and_the_flattened_description_say_the_same() -> None:
    raw = parse_robot_description(DIFFBOT.read_text(encoding="utf-8"))
    flat = Simulator("rooms", lidar=None).description
    assert raw.radius_m == pytest.approx(flat.radius_m, abs=1e-12)
    assert raw.inscribed_radius_m == pytest.approx(flat.inscribed_radius_m, abs=1e-12)
    assert raw.lidar == flat.lidar and raw.imu_frame == flat.imu_frame == "imu"
    assert [f.name for f in raw.frames] == [f.name for f in flat.frames] == ["imu", "laser"]
    for a, b in zip(raw.frames, flat.frames, strict=True):
        assert a.xyz_m == pytest.approx(b.xyz_m) and a.quat_xyzw == pytest.approx(b.quat_xyzw)
    np.testing.assert_allclose(np.sort(raw.footprint_m, axis=0), np.sort(flat.footprint_m, axis=0), atol=1e-12)
    # The disc robot: the chassis (0.18 m) inside, the wheels reaching 0.14 + 0.05 m.
    assert flat.radius_m == pytest.approx(0.19) and flat.inscribed_radius_m == pytest.approx(0.18)


def test_round_outlines_are_circumscribed() -> None:
    text = '<mujoco><worldbody><body name="b"><freejoint/><geom size="0.5"/></body></worldbody></mujoco>'
    d = parse_robot_description(text)
    assert len(d.footprint_m) == CIRCLE_SIDES
    assert d.radius_m == pytest.approx(0.5)  # the disc itself
    assert d.inscribed_radius_m == pytest.approx(0.5)  # the polygon's edges touch the circle
    assert np.max(np.hypot(*d.footprint_m.T)) == pytest.approx(0.5 / math.cos(math.pi / CIRCLE_SIDES))


def test_convex_hull() -> None:
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5], [0.5, 0.0], [1, 1]], dtype=float)
    np.testing.assert_array_equal(convex_hull(pts), [[0, 0], [1, 0], [1, 1], [0, 1]])


def _robot(body: str, extra: str = "") -> str:
    return f'<mujoco><worldbody><body name="b">{body}</body></worldbody>{extra}</mujoco>'


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("not xml <", "not XML"),
        ("<robot/>", "must be MJCF"),
        ('<mujoco><include file="x.xml"/></mujoco>', "self-contained"),
        ("<mujoco/>", "no <worldbody>"),
        ("<mujoco><worldbody><body/><body/></worldbody></mujoco>", "no robot body"),
        ('<mujoco><worldbody><body><freejoint/><geom size="1"/></body></worldbody></mujoco>', "has no name"),
        (_robot('<geom class="nope"/>'), "unknown class 'nope'"),
        (_robot('<geom type="mesh" mesh="m"/>'), "colliding mesh"),
        (_robot('<geom size="x"/>'), "expected numbers"),
        (_robot('<geom size="1" pos="0 0"/>'), "expected 3"),
        (_robot('<geom size="1" quat="1 0 0 0" euler="0 0 1"/>'), "several orientations"),
        (_robot('<geom contype="0" conaffinity="0" size="1"/>'), "no colliding geom"),
        ('<mujoco><compiler angle="grad"/><worldbody><body name="b"/></worldbody></mujoco>', "degree or radian"),
        (_robot('<geom size="1"/><site name="laser"/>', '<custom><numeric name="lidar_beams" data="10.5"/></custom>'),
         "whole number"),
        (_robot('<geom size="1"/>', '<sensor><gyro site="nowhere"/></sensor>'), "not a named site"),
    ],
)  # fmt: skip
def test_what_cannot_be_read_is_a_typed_error_naming_it(text: str, message: str) -> None:
    with pytest.raises(DescriptionError, match=message):
        parse_robot_description(text)


def test_an_unknown_frame_is_named() -> None:
    d = parse_robot_description(DIFFBOT.read_text(encoding="utf-8"))
    with pytest.raises(DescriptionError, match="no frame 'lidar'; frames: imu, laser"):
        d.frame("lidar")


def test_a_robot_without_lidar_site_has_no_lidar(tmp_path: Path) -> None:
    text = DIFFBOT.read_text(encoding="utf-8").replace('<site name="laser"', '<site name="camera"')
    d = parse_robot_description(text)
    assert d.lidar is None and d.lidar_frame is None and "camera" in {f.name for f in d.frames}

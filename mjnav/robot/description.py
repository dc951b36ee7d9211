"""The robot description: what the services know about the robot, parsed from its MJCF.

The sim publishes the robot's MJCF on ``robot_description`` (latched, as ROS's robot_state_publisher publishes the
URDF) and every service that needs a robot fact — the footprint, its radius, the lidar and where it sits, the IMU's
frame — derives it here, from that text, with the same function. No service keeps a robot number of its own.

What is read (the MJCF subset a robot model uses; the sim's description is flattened, but a hand-written robot
file parses the same way):

* ``<compiler angle eulerseq>`` (MuJoCo's defaults: degrees, ``xyz``), ``<default>`` classes with their
  inheritance, ``class`` and ``childclass``;
* the robot's root body (the one body with a free joint, else the only top-level body): its name is the base
  frame (``base_link``), and everything below is placed relative to it — nested bodies and ``<frame>`` elements
  with ``pos`` and any orientation (``quat``, ``axisangle``, ``euler``, ``xyaxes``, ``zaxis``), geoms with
  ``fromto``;
* every named site is a sensor frame; the lidar is the site named :data:`LIDAR_SITE` with the ``lidar_*`` custom
  numerics (:mod:`mjnav.robot.lidar`), the IMU is the site of the first ``gyro`` sensor;
* the footprint is the convex hull of the horizontal outline of every colliding geom (``contype`` or
  ``conaffinity`` not 0) at the model's initial pose: spheres, capsules, cylinders, boxes and ellipsoids (an
  ellipsoid by its bounding box; round outlines by a circumscribed 32-gon, so the polygon holds the robot).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjnav.robot.lidar import LidarConfig, lidar_config_from_numerics

#: Name of the site the lidar's beams start from (also the frame of its scans).
LIDAR_SITE = "laser"
#: Sides of the polygons that stand for round outlines (circumscribed: the polygon contains the circle).
CIRCLE_SIDES = 32

_ORIENTATIONS = ("quat", "axisangle", "euler", "xyaxes", "zaxis")
_PRIMITIVES = ("sphere", "capsule", "cylinder", "box", "ellipsoid")


class DescriptionError(ValueError):
    """A robot description that cannot be read: not MJCF, no robot body, an unknown class, a collision geom
    without a primitive shape, bad numbers."""


@dataclass(frozen=True, slots=True)
class Frame:
    """A named frame of the robot (a site), relative to the base frame.

    Attributes:
        name: the frame id (the site's name), e.g. ``laser``.
        xyz_m: (x, y, z) position in the base frame, metres.
        quat_xyzw: orientation in the base frame, unit quaternion (x, y, z, w) as in ``geometry_msgs``.
    """

    name: str
    xyz_m: tuple[float, float, float]
    quat_xyzw: tuple[float, float, float, float]

    @property
    def yaw_rad(self) -> float:
        """Heading of the frame's x axis in the base frame's x-y plane, radians."""
        x, y, z, w = self.quat_xyzw
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))

    @property
    def planar(self) -> tuple[float, float, float]:
        """(x, y, yaw) of the frame in the base frame: metres, radians."""
        return self.xyz_m[0], self.xyz_m[1], self.yaw_rad


@dataclass(frozen=True, eq=False)
class RobotDescription:
    """The robot facts the services use.

    Attributes:
        name: the model's name (``<mujoco model>``).
        base_frame: the root body's name, the frame everything here is given in (``base_link``).
        footprint_m: (N, 2) convex polygon in the base frame, counter-clockwise, metres: every colliding part of
            the robot projected on the ground plane lies inside it.
        radius_m: the smallest disc about the base frame's origin holding every colliding part (the circumscribed
            radius), metres.
        inscribed_radius_m: the largest disc about the origin inside the footprint (0 when the origin lies outside
            it), metres.
        frames: every named site, as a frame in the base frame.
        lidar: the lidar's beams, rate, limits and noise (None: the robot has no :data:`LIDAR_SITE` site).
        lidar_frame: the lidar's frame (:data:`LIDAR_SITE`), or None.
        imu_frame: the frame of the first gyro, or None.
        mjcf: the text this was parsed from.
    """

    name: str
    base_frame: str
    footprint_m: NDArray[np.float64]
    radius_m: float
    inscribed_radius_m: float
    frames: tuple[Frame, ...]
    lidar: LidarConfig | None
    lidar_frame: str | None
    imu_frame: str | None
    mjcf: str

    def frame(self, name: str) -> Frame:
        """The frame called ``name``.

        Raises:
            DescriptionError: the robot has no such frame (the message lists those it has).
        """
        for f in self.frames:
            if f.name == name:
                return f
        raise DescriptionError(f"the robot has no frame {name!r}; frames: {', '.join(f.name for f in self.frames)}")


def parse_robot_description(text: str) -> RobotDescription:
    """Read a robot's MJCF (see the module docstring for what is read).

    Args:
        text: the MJCF document, self-contained (no ``<include>``).

    Raises:
        DescriptionError: what is wrong, naming the element.
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise DescriptionError(f"robot description is not XML: {exc}") from None
    if root.tag != "mujoco":
        raise DescriptionError(f"robot description must be MJCF (<mujoco>), got <{root.tag}>")
    if root.find(".//include") is not None:
        raise DescriptionError("robot description must be self-contained: it has an <include>")
    reader = _Reader(root)
    base = reader.robot_root()
    base_name = base.get("name", "")
    if not base_name:
        raise DescriptionError("the robot's root body has no name (the base frame, e.g. base_link)")
    reader.walk(base, np.eye(3), np.zeros(3), base.get("childclass"))
    if not reader.points:
        raise DescriptionError(f"body {base_name!r} has no colliding geom: the footprint would be empty")
    hull = convex_hull(np.vstack(reader.points))
    numerics = reader.numerics()
    frames = tuple(reader.frames)
    names = {f.name for f in frames}
    lidar = None
    if LIDAR_SITE in names:
        try:
            lidar = lidar_config_from_numerics(numerics)
        except ValueError as exc:
            raise DescriptionError(f"lidar: {exc}") from None
    imu = reader.gyro_site()
    if imu is not None and imu not in names:
        raise DescriptionError(f"the gyro's site {imu!r} is not a named site of the robot")
    return RobotDescription(
        name=root.get("model", ""),
        base_frame=base_name,
        footprint_m=hull,
        radius_m=max(reader.radii),
        inscribed_radius_m=_inscribed_radius(hull),
        frames=frames,
        lidar=lidar,
        lidar_frame=LIDAR_SITE if lidar is not None else None,
        imu_frame=imu,
        mjcf=text,
    )


class _Reader:
    """Walks one MJCF tree: classes, transforms, geoms, sites."""

    def __init__(self, root: ET.Element) -> None:
        self.root = root
        compiler: dict[str, str] = {}
        for el in root.iter("compiler"):
            compiler.update(el.attrib)
        angle = compiler.get("angle", "degree")
        if angle not in ("degree", "radian"):
            raise DescriptionError(f"<compiler angle={angle!r}>: expected degree or radian")
        self.angle_scale = math.pi / 180.0 if angle == "degree" else 1.0
        self.eulerseq = compiler.get("eulerseq", "xyz")
        if len(self.eulerseq) != 3 or any(c not in "xyzXYZ" for c in self.eulerseq):
            raise DescriptionError(f"<compiler eulerseq={self.eulerseq!r}>: expected 3 of x, y, z, X, Y, Z")
        self.classes: dict[str, tuple[str | None, dict[str, dict[str, str]]]] = {"main": (None, {})}
        for default in root.findall("default"):
            self._read_defaults(default, None)
        self.points: list[NDArray[np.float64]] = []
        self.radii: list[float] = []
        self.frames: list[Frame] = []

    def _read_defaults(self, el: ET.Element, parent: str | None) -> None:
        name = el.get("class", "main")
        if name in self.classes and name != "main":
            raise DescriptionError(f"default class {name!r} is defined twice")
        own = self.classes["main"][1] if name == "main" else {}
        for child in el:
            if child.tag != "default":
                own.setdefault(child.tag, {}).update(child.attrib)
        self.classes[name] = (parent if name != "main" else None, own)
        for child in el.findall("default"):
            self._read_defaults(child, name)

    def attrs(self, el: ET.Element, childclass: str | None) -> dict[str, str]:
        """The element's attributes over its class's defaults (own class, else the enclosing childclass)."""
        cls = el.get("class") or childclass or "main"
        if cls not in self.classes:
            raise DescriptionError(f"<{el.tag} name={el.get('name', '')!r}>: unknown class {cls!r}")
        chain = []
        c: str | None = cls
        while c is not None:
            chain.append(c)
            c = self.classes[c][0]
        out: dict[str, str] = {}
        for c in reversed(chain):
            out.update(self.classes[c][1].get(el.tag, {}))
        own = dict(el.attrib)
        if any(k in own for k in (*_ORIENTATIONS, "fromto")):  # an element's own orientation replaces its class's
            for k in (*_ORIENTATIONS, "fromto"):
                out.pop(k, None)
        out.update(own)
        out.pop("class", None)
        return out

    def robot_root(self) -> ET.Element:
        worldbody = self.root.find("worldbody")
        if worldbody is None:
            raise DescriptionError("robot description has no <worldbody>")
        free = [
            b
            for b in worldbody.iter("body")
            if b.find("freejoint") is not None or any(j.get("type") == "free" for j in b.findall("joint"))
        ]
        if len(free) > 1:
            raise DescriptionError(f"several bodies with a free joint: {[b.get('name') for b in free]}; one robot")
        if free:
            return free[0]
        top = [el for el in worldbody if el.tag == "body"]
        if len(top) != 1:
            raise DescriptionError("no robot body: need one body with a free joint, or a single top-level body")
        return top[0]

    def walk(self, el: ET.Element, rot: NDArray[np.float64], pos: NDArray[np.float64], childclass: str | None) -> None:
        """Visit ``el``'s geoms, sites, bodies and frames, ``el`` being placed at (rot, pos) in the base frame."""
        for child in el:
            tag = child.tag
            if tag in ("body", "frame"):
                r, p = self._placement(child, dict(child.attrib))
                self.walk(child, rot @ r, pos + rot @ p, child.get("childclass") or childclass)
            elif tag == "geom":
                self._geom(child, self.attrs(child, childclass), rot, pos)
            elif tag == "site":
                attrs = self.attrs(child, childclass)
                name = attrs.get("name", "")
                if name:
                    r, p = self._placement(child, attrs)
                    q = _matrix_to_quat(rot @ r)
                    xyz = pos + rot @ p
                    self.frames.append(
                        Frame(name, (float(xyz[0]), float(xyz[1]), float(xyz[2])), (q[1], q[2], q[3], q[0]))
                    )

    def _placement(self, el: ET.Element, attrs: dict[str, str]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        where = f"<{el.tag} name={attrs.get('name', '')!r}>"
        pos = _floats(attrs.get("pos", "0 0 0"), 3, f"{where} pos")
        present = [k for k in _ORIENTATIONS if k in attrs]
        if len(present) > 1:
            raise DescriptionError(f"{where}: several orientations ({', '.join(present)}); give one")
        if not present:
            return np.eye(3), pos
        key = present[0]
        value = attrs[key]
        if key == "quat":
            q = _floats(value, 4, f"{where} quat")
            n = float(np.linalg.norm(q))
            if n == 0.0:
                raise DescriptionError(f"{where} quat is zero")
            return _quat_to_matrix(q / n), pos
        if key == "axisangle":
            v = _floats(value, 4, f"{where} axisangle")
            return _axis_angle(v[:3], v[3] * self.angle_scale, where), pos
        if key == "euler":
            v = _floats(value, 3, f"{where} euler") * self.angle_scale
            rot = np.eye(3)
            for axis, angle in zip(self.eulerseq, v, strict=True):
                step = _axis_angle(np.eye(3)["xyz".index(axis.lower())], float(angle), where)
                rot = rot @ step if axis.islower() else step @ rot  # lower case: about the rotated (moving) axes
            return rot, pos
        if key == "xyaxes":
            v = _floats(value, 6, f"{where} xyaxes")
            x = _unit(v[:3], where)
            y = _unit(v[3:] - (x @ v[3:]) * x, where)
            return np.column_stack((x, y, np.cross(x, y))), pos
        return _z_to(_unit(_floats(value, 3, f"{where} zaxis"), where)), pos

    def _geom(self, el: ET.Element, attrs: dict[str, str], rot: NDArray[np.float64], pos: NDArray[np.float64]) -> None:
        contype = int(float(attrs.get("contype", "1")))
        conaffinity = int(float(attrs.get("conaffinity", "1")))
        if contype == 0 and conaffinity == 0:
            return
        kind = attrs.get("type", "sphere")
        where = f"<geom name={attrs.get('name', '')!r}>"
        if kind not in _PRIMITIVES:
            shapes = ", ".join(_PRIMITIVES)
            raise DescriptionError(
                f"{where} is a colliding {kind}: the footprint needs primitive collision geoms ({shapes})"
            )
        size = np.zeros(3)
        given = _floats(attrs.get("size", ""), None, f"{where} size")
        size[: min(3, len(given))] = given[:3]
        if "fromto" in attrs:
            if kind == "sphere":
                raise DescriptionError(f"{where}: a sphere takes no fromto")
            ends = _floats(attrs["fromto"], 6, f"{where} fromto")
            axis = ends[3:] - ends[:3]
            half = float(np.linalg.norm(axis)) / 2.0
            r, p = _z_to(_unit(axis, where)), (ends[:3] + ends[3:]) / 2.0
            size[1 if kind in ("capsule", "cylinder") else 2] = half
        else:
            r, p = self._placement(el, attrs)
        g_rot, g_pos = rot @ r, pos + rot @ p
        points, radius = _outline(kind, size, g_rot, g_pos)
        self.points.append(points)
        self.radii.append(radius)

    def numerics(self) -> dict[str, list[float]]:
        out: dict[str, list[float]] = {}
        for custom in self.root.findall("custom"):
            for num in custom.findall("numeric"):
                name = num.get("name", "")
                out[name] = [float(v) for v in _floats(num.get("data", ""), None, f"numeric {name}")]
        return out

    def gyro_site(self) -> str | None:
        for sensor in self.root.findall("sensor"):
            for gyro in sensor.findall("gyro"):
                return gyro.get("site")
        return None


def _floats(text: str, n: int | None, where: str) -> NDArray[np.float64]:
    try:
        values = np.array([float(v) for v in text.split()], dtype=np.float64)
    except ValueError:
        raise DescriptionError(f"{where}: expected numbers, got {text!r}") from None
    if n is not None and len(values) != n:
        raise DescriptionError(f"{where}: expected {n} numbers, got {len(values)}")
    if not np.all(np.isfinite(values)):
        raise DescriptionError(f"{where}: numbers must be finite, got {text!r}")
    return values


def _unit(v: NDArray[np.float64], where: str) -> NDArray[np.float64]:
    n = float(np.linalg.norm(v))
    if n < 1e-12:
        raise DescriptionError(f"{where}: zero-length axis")
    return np.asarray(v, dtype=np.float64) / n


def _axis_angle(axis: NDArray[np.float64], angle: float, where: str) -> NDArray[np.float64]:
    """Rotation matrix of ``angle`` (rad) about ``axis`` (Rodrigues)."""
    k = _unit(axis, where)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * (kx @ kx)


def _z_to(z: NDArray[np.float64]) -> NDArray[np.float64]:
    """The smallest rotation taking +z to the unit vector ``z`` (MuJoCo's ``zaxis``)."""
    c = float(z[2])
    axis = np.array([-z[1], z[0], 0.0])  # (0, 0, 1) × z
    s = float(np.linalg.norm(axis))
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])  # half a turn about x
    return _axis_angle(axis, math.atan2(s, c), "zaxis")


def _quat_to_matrix(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation matrix of a unit quaternion (w, x, y, z)."""
    w, x, y, z = (float(v) for v in q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _matrix_to_quat(m: NDArray[np.float64]) -> tuple[float, float, float, float]:
    """Unit quaternion (w, x, y, z), w >= 0, of a rotation matrix (Shepperd's method)."""
    t = float(np.trace(m))
    if t > 0:
        s = 2.0 * math.sqrt(t + 1.0)
        q = (0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s)
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        v = [0.0, 0.0, 0.0]
        v[i] = 0.25 * s
        v[j] = (m[j, i] + m[i, j]) / s
        v[k] = (m[k, i] + m[i, k]) / s
        q = ((m[k, j] - m[j, k]) / s, v[0], v[1], v[2])
    w, x, y, z = (float(c) for c in q)
    sign = -1.0 if w < 0 else 1.0
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return sign * w / n, sign * x / n, sign * y / n, sign * z / n


def _circle(centre: NDArray[np.float64], u: NDArray[np.float64], v: NDArray[np.float64], r: float) -> Any:
    """(CIRCLE_SIDES, 3) vertices of the polygon circumscribing the circle of radius ``r`` about ``centre`` in the
    plane spanned by the unit vectors ``u``, ``v``."""
    a = (np.arange(CIRCLE_SIDES) + 0.5) * (2.0 * math.pi / CIRCLE_SIDES)
    rr = r / math.cos(math.pi / CIRCLE_SIDES)
    return centre + rr * (np.outer(np.cos(a), u) + np.outer(np.sin(a), v))


def _outline(
    kind: str, size: NDArray[np.float64], rot: NDArray[np.float64], pos: NDArray[np.float64]
) -> tuple[NDArray[np.float64], float]:
    """(K, 2) points whose hull holds the geom's ground-plane projection, and the distance of its farthest point
    from the base frame's z axis (exact for spheres, capsules, boxes and vertical cylinders; from the polygon
    otherwise)."""
    ex, ey = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    if kind == "sphere":
        pts = _circle(pos, ex, ey, size[0])
        return pts[:, :2], float(np.hypot(pos[0], pos[1])) + size[0]
    if kind in ("capsule", "cylinder"):
        ends = (pos - rot[:, 2] * size[1], pos + rot[:, 2] * size[1])
        centre_reach = max(float(np.hypot(e[0], e[1])) for e in ends)
        if kind == "capsule":
            pts = np.vstack([_circle(e, ex, ey, size[0]) for e in ends])
            return pts[:, :2], centre_reach + size[0]
        pts = np.vstack([_circle(e, rot[:, 0], rot[:, 1], size[0]) for e in ends])
        if abs(rot[2, 2]) > 1.0 - 1e-12:  # vertical: each end disc projects to a circle
            return pts[:, :2], centre_reach + size[0]
        return pts[:, :2], float(np.max(np.hypot(pts[:, 0], pts[:, 1])))
    # box, and an ellipsoid by its bounding box
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
    corners = pos + (signs * size) @ rot.T
    return corners[:, :2], float(np.max(np.hypot(corners[:, 0], corners[:, 1])))


def convex_hull(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Convex hull of planar points, counter-clockwise from the lowest-leftmost, without collinear vertices
    (Andrew's monotone chain).

    Args:
        points: (N, 2) array.

    Returns:
        (H, 2) hull vertices.
    """
    pts = sorted({(float(x), float(y)) for x, y in np.asarray(points, dtype=np.float64)})
    if len(pts) <= 2:
        return np.array(pts, dtype=np.float64).reshape(-1, 2)

    def cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, float]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1], dtype=np.float64)


def _inscribed_radius(hull: NDArray[np.float64]) -> float:
    """Distance from the origin to the nearest edge of a counter-clockwise convex polygon (0 when outside)."""
    if len(hull) < 3:
        return 0.0
    a, b = hull, np.roll(hull, -1, axis=0)
    edge = b - a
    length = np.hypot(edge[:, 0], edge[:, 1])
    signed = (edge[:, 0] * (-a[:, 1]) - edge[:, 1] * (-a[:, 0])) / length  # > 0: origin left of (inside) the edge
    return max(0.0, float(signed.min()))

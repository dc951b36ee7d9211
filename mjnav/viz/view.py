"""The mjnav scene: which meshcat path shows what, and how each message is drawn.

Layout (all under ``/meshcat/mjnav``, frame ``map`` = the MuJoCo world frame)::

    world/<geom>            static MJCF geoms (floor, walls, furniture); in a world of more than
                            MERGE_ABOVE_GEOMS of them, the boxes as world/boxes_<k>: one mesh per colour
    moving/<geom>           other bodies at their initial pose, translucent (their motion is not on the bus)
    robot                   transform = robot pose; robot/body/<geom> the robot's MJCF geoms
    robot/laser             transform = lidar pose in base_link; robot/laser/scan the latest scan points
    map, costmap            textured planes (nav_msgs/OccupancyGrid)
    plan, path              raw plan (orange) and smoothed path (green) as lines with vertices
    goal                    goal marker: disk + heading arrow, coloured by the latest goal status

:class:`NavView` draws into a :class:`~mjnav.viz.scene.Scene`; :meth:`NavView.handle` takes a topic name and a
decoded message, so the viz service, a bag replay or a test can feed it alike.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import meshcat.geometry as mg
import numpy as np
from numpy.typing import NDArray

from mjnav.viz.layers import (
    grid_plane_transform,
    occupancy_rgba,
    path_points,
    png_bytes,
    pose_matrix,
    pose_msg_matrix,
    rgb_hex,
    scan_points,
    transform_msg_matrix,
)
from mjnav.viz.model import VisualGeom, VisualModel
from mjnav.viz.scene import Scene

ROOT = "/meshcat/mjnav"

#: Colours (0xRRGGBB) of the drawn layers.
SCAN_RGB = (1.0, 0.15, 0.1)
PLAN_COLOUR = 0xFF9900
PATH_COLOUR = 0x16C60C
#: Heights (m) that keep the flat layers apart and above the floor.
MAP_Z_M = 0.004
COSTMAP_Z_M = 0.008
PLAN_Z_M = 0.03
PATH_Z_M = 0.04
#: The driven trail: the robot's poses on the pose topic, a point every TRAIL_SPACING_M, drawn as a line.
TRAIL_COLOUR = 0x1F77B4
TRAIL_Z_M = 0.02
TRAIL_SPACING_M = 0.1
#: Goal marker colour per mjnav_msgs/GoalStatus state: amber accepted/planning (0 = no status yet), teal following,
#: green reached, red failed, grey canceled.
GOAL_COLOURS = {0: 0xF2C200, 1: 0xF2C200, 2: 0xF2C200, 3: 0x00C2C7, 4: 0x16C60C, 5: 0xE02020, 6: 0x8A8A8A}

#: A world with more static geoms than this draws its boxes merged, one triangle mesh per colour: a map turned into
#: a world has thousands (random512-40-5: 33,370), and one meshcat object each took 4.5 s to build and as long again
#: to send, while the viewer's tree of them is of no use to anyone.
MERGE_ABOVE_GEOMS = 256

_ROT_X_90 = np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])  # y axis → z axis


#: Topics that can move the drawn robot: the true pose (evaluation channel, or the sim's ``ground_truth``),
#: SLAM's estimate, wheel odometry.
POSE_TOPICS = ("truth", "pose", "ground_truth", "odom")


class _Plane(mg.Geometry):
    """three.js PlaneGeometry: a ``width × height`` rectangle in the xy plane facing +z, UVs along +x and +y."""

    def __init__(self, width: float, height: float) -> None:
        super().__init__()
        self.width = width
        self.height = height

    def lower(self, object_data: Any) -> dict[str, Any]:
        return {"uuid": self.uuid, "type": "PlaneGeometry", "width": self.width, "height": self.height}


def _box_faces() -> tuple[NDArray[np.float64], NDArray[np.uint32]]:
    """A unit box's corners as (24, 3) signs, four per face (so each face shades flat), and its (12, 3) triangles,
    counter-clockwise seen from outside."""
    corners: list[list[float]] = []
    triangles: list[tuple[int, int, int]] = []
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3  # e_u x e_v = e_axis
        for sign in (1.0, -1.0):
            if sign < 0:
                u, v = v, u  # reversed order: the face looks along -e_axis
            base = len(corners)
            for a, b in ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)):
                c = [0.0, 0.0, 0.0]
                c[axis], c[u], c[v] = sign, a, b
                corners.append(c)
            triangles += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return np.asarray(corners), np.asarray(triangles, dtype=np.uint32)


_BOX_CORNERS, _BOX_TRIANGLES = _box_faces()


def merged_boxes(geoms: list[VisualGeom]) -> tuple[NDArray[np.float32], NDArray[np.uint32]]:
    """One triangle mesh of many box geoms, in their common parent frame.

    Args:
        geoms: box geoms (``shape == "box"``), posed in one frame.

    Returns:
        vertices: (24 B, 3) float32, metres, four per face; faces: (12 B, 3) uint32, counter-clockwise seen from
        outside.
    """
    half = np.asarray([g.size for g in geoms], dtype=np.float64)  # (B, 3) half sizes
    poses = np.asarray([g.pose for g in geoms], dtype=np.float64)  # (B, 4, 4)
    local = _BOX_CORNERS[None, :, :] * half[:, None, :]  # (B, 24, 3)
    world = np.einsum("bij,bkj->bki", poses[:, :3, :3], local) + poses[:, None, :3, 3]
    faces = _BOX_TRIANGLES[None, :, :] + (24 * np.arange(len(geoms), dtype=np.uint32))[:, None, None]
    return world.reshape(-1, 3).astype(np.float32), faces.reshape(-1, 3)


def _safe(name: str) -> str:
    return name.replace("/", "_") or "unnamed"


def geom_objects(geom: VisualGeom, opacity_scale: float = 1.0) -> list[tuple[str, Any, NDArray[np.float64]]]:
    """Meshcat objects for one MJCF geom: ``(sub-path, object, transform in the geom's parent frame)``.

    Cylinders are turned from three.js's y axis to MuJoCo's z axis; a capsule becomes a cylinder and two spheres.
    """
    r, g, b, a = geom.rgba
    opacity = float(a) * opacity_scale
    material = mg.MeshLambertMaterial(color=rgb_hex((r, g, b)), opacity=opacity, transparent=opacity < 1.0)
    sx, sy, sz = geom.size
    pose = geom.pose
    shape = geom.shape
    if shape == "box":
        return [("", mg.Mesh(mg.Box([2 * sx, 2 * sy, 2 * sz]), material), pose)]
    if shape == "sphere":
        return [("", mg.Mesh(mg.Sphere(sx), material), pose)]
    if shape == "ellipsoid":
        return [("", mg.Mesh(mg.Ellipsoid([sx, sy, sz]), material), pose)]
    if shape == "cylinder":
        return [("", mg.Mesh(mg.Cylinder(2 * sy, sx), material), pose @ _ROT_X_90)]
    if shape == "capsule":
        up, down = np.eye(4), np.eye(4)
        up[2, 3], down[2, 3] = sy, -sy
        return [
            ("shaft", mg.Mesh(mg.Cylinder(2 * sy, sx), material), pose @ _ROT_X_90),
            ("cap_top", mg.Mesh(mg.Sphere(sx), material), pose @ up),
            ("cap_bottom", mg.Mesh(mg.Sphere(sx), material), pose @ down),
        ]
    if shape == "plane":
        return [("", mg.Mesh(_Plane(2 * sx, 2 * sy), material), pose)]
    if shape == "mesh" and geom.vertices is not None and geom.faces is not None:
        return [("", mg.Mesh(mg.TriangularMeshGeometry(geom.vertices, geom.faces), material), pose)]
    return []


class NavView:
    """Draws the navigation scene into a :class:`Scene`.

    Args:
        scene: where to draw (offline, or mirrored to a meshcat server).
        scan_point_size_m: rendered size of a scan point, metres.
        pose_topic: which topic moves the robot: one of :data:`POSE_TOPICS` (``truth`` by default).
    """

    #: Topics :meth:`handle` understands, besides the pose topic.
    TOPICS: ClassVar[tuple[str, ...]] = (
        "scan",
        "map",
        "costmap",
        "plan",
        "path",
        "goal",
        "goal_status",
        "obstacles",
    )

    def __init__(self, scene: Scene, *, scan_point_size_m: float = 0.06, pose_topic: str = "truth") -> None:
        if pose_topic not in POSE_TOPICS:
            raise ValueError(f"pose_topic must be one of {list(POSE_TOPICS)}, got {pose_topic!r}")
        self.scene = scene
        self.scan_point_size_m = scan_point_size_m
        self.pose_topic = pose_topic
        self.model: VisualModel | None = None
        self.goal_state = 0
        self._goal: Any = None
        self.trail: list[tuple[float, float]] = []  # driven trail, map frame, metres
        self.drawn: dict[str, int] = {}
        self._shown: dict[str, Any] = {}  # per grid or path layer: what it shows now (a redraw of it is skipped)

    # ------------------------------------------------------------------------------------------------ set-up

    def setup_viewer(self, bounds_m: tuple[float, float, float, float] | None = None) -> None:
        """Plain page background instead of meshcat's sky gradient, no default grid (the floor is drawn), camera
        framing ``bounds_m`` (or ±5 m)."""
        s = self.scene
        s.set_property("/Background", "visible", False)
        s.set_property("/Grid", "visible", False)
        self.frame_camera(bounds_m or (-5.0, -5.0, 5.0, 5.0))

    def frame_camera(self, bounds_m: tuple[float, float, float, float]) -> None:
        """Look down at the centre of ``bounds_m`` (x_min, y_min, x_max, y_max; metres) from the south, slightly
        tilted, far enough for the whole region to fit a 4:3 view (meshcat's camera: 75° vertical field of view)."""
        x0, y0, x1, y1 = bounds_m
        extent = max(x1 - x0, y1 - y0, 1.0)
        height = 0.72 * extent
        centre = np.eye(4)
        centre[:3, 3] = (0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.0)
        self.scene.set_transform("/Cameras/default", centre)
        # The camera lives in meshcat's y-up "rotated" frame: (x, y, z) there is (x, -z, y) in the world.
        self.scene.set_property("/Cameras/default/rotated/<object>", "position", [0.0, height, 0.25 * height])

    def draw_model(self, model: VisualModel) -> None:
        """Draw the world's static geoms, its moving bodies and the robot (at their start poses until poses
        arrive)."""
        self.model = model
        s = self.scene
        s.delete(f"{ROOT}/world")
        s.delete(f"{ROOT}/moving")
        s.delete(f"{ROOT}/robot/body")
        separate = model.world_geoms
        if len(separate) > MERGE_ABOVE_GEOMS:
            boxes: dict[tuple[float, float, float, float], list[VisualGeom]] = {}
            for geom in separate:
                if geom.shape == "box":
                    boxes.setdefault(geom.rgba, []).append(geom)
            for k, (rgba, group) in enumerate(sorted(boxes.items())):
                vertices, faces = merged_boxes(group)
                material = mg.MeshLambertMaterial(color=rgb_hex(rgba[:3]), opacity=rgba[3], transparent=rgba[3] < 1)
                s.set_object(f"{ROOT}/world/boxes_{k}", mg.Mesh(mg.TriangularMeshGeometry(vertices, faces), material))
            separate = tuple(g for g in separate if g.shape != "box")
        for geom in separate:
            self._draw_geom(f"{ROOT}/world/{_safe(geom.name)}", geom, 1.0)
        for body in model.moving_bodies:
            path = f"{ROOT}/moving/{_safe(body.name)}"
            for geom in body.geoms:
                self._draw_geom(f"{path}/{_safe(geom.name)}", geom, 0.6)
            s.set_transform(path, body.pose)
        for geom in model.robot_geoms:
            self._draw_geom(f"{ROOT}/robot/body/{_safe(geom.name)}", geom, 1.0)
        s.set_transform(f"{ROOT}/robot/laser", model.laser_pose)
        start = model.start
        self.set_robot_pose(pose_matrix(start.x, start.y, start.theta))

    def _draw_geom(self, path: str, geom: VisualGeom, opacity: float) -> None:
        for sub, obj, transform in geom_objects(geom, opacity):
            node = f"{path}/{sub}" if sub else path
            self.scene.set_object(node, obj)
            self.scene.set_transform(node, transform)

    # ------------------------------------------------------------------------------------------------ layers

    def set_robot_pose(self, transform: NDArray[np.float64]) -> None:
        """Move the robot: ``transform`` is the (4, 4) pose of ``base_link`` in ``map``."""
        self.scene.set_transform(f"{ROOT}/robot", transform)
        self._count("robot")

    def extend_trail(self, x: float, y: float) -> None:
        """Grow the driven trail by (x, y) (map frame, metres) when the robot moved :data:`TRAIL_SPACING_M` from
        the trail's last point; the trail is one line, replaced as it grows."""
        if self.trail and math.dist(self.trail[-1], (x, y)) < TRAIL_SPACING_M:
            return
        self.trail.append((x, y))
        if len(self.trail) < 2:
            return
        xy = np.asarray(self.trail, dtype=np.float32).T
        points = np.vstack((xy, np.full((1, xy.shape[1]), TRAIL_Z_M, dtype=np.float32)))
        material = mg.LineBasicMaterial(color=TRAIL_COLOUR, linewidth=3.0)
        self.scene.set_object(f"{ROOT}/trail", mg.Line(mg.PointsGeometry(points), material))
        self._count("trail")

    def move_bodies(self, tf: Any) -> None:
        """Move the moving bodies named in ``tf`` (tf2_msgs/TFMessage, transforms ``map`` → body name); transforms
        of bodies the model does not have are ignored."""
        known = {b.name for b in self.model.moving_bodies} if self.model is not None else set()
        for t in tf.transforms:
            if t.child_frame_id in known and t.header.frame_id == "map":
                self.scene.set_transform(f"{ROOT}/moving/{_safe(t.child_frame_id)}", transform_msg_matrix(t.transform))
                self._count("obstacles")

    def draw_scan(self, scan: Any) -> None:
        """Show a sensor_msgs/LaserScan's returns as points in the lidar frame (attached to the robot)."""
        points = scan_points(scan)
        colours = np.tile(np.asarray(SCAN_RGB, dtype=np.float32)[:, None], (1, points.shape[1]))
        self.scene.set_object(f"{ROOT}/robot/laser/scan", mg.PointCloud(points, colours, size=self.scan_point_size_m))
        self._count("scan")

    def draw_grid(self, grid: Any, kind: str = "map") -> None:
        """Show a nav_msgs/OccupancyGrid as a textured plane (``kind``: ``map`` or ``costmap``); the grid already
        shown is not drawn again."""
        info = grid.info
        shown = (info.width, info.height, info.resolution, pose_msg_matrix(info.origin).tobytes(), bytes(grid.data))
        if self._shown.get(kind) == shown:
            return  # the same grid again (an unchanged map re-published): no new texture
        self._shown[kind] = shown
        if info.width == 0 or info.height == 0:
            self.scene.delete(f"{ROOT}/{kind}")
            return
        image = png_bytes(occupancy_rgba(grid, kind))
        texture = mg.ImageTexture(mg.PngImage(image), wrap=[1001, 1001], magFilter=1003, minFilter=1003)
        material = mg.MeshBasicMaterial(map=texture, transparent=True, opacity=1.0)
        size = (info.width * info.resolution, info.height * info.resolution)
        z = MAP_Z_M if kind == "map" else COSTMAP_Z_M
        path = f"{ROOT}/{kind}"
        self.scene.set_object(path, mg.Mesh(_Plane(*size), material))
        self.scene.set_transform(path, grid_plane_transform(grid, z))
        self._count(kind)

    def draw_path(self, path_msg: Any, name: str = "path") -> None:
        """Show a nav_msgs/Path (``name``: ``plan`` or ``path``) as a line through its poses plus vertex dots; the
        path already shown is not drawn again."""
        z, colour = (PLAN_Z_M, PLAN_COLOUR) if name == "plan" else (PATH_Z_M, PATH_COLOUR)
        node = f"{ROOT}/{name}"
        points = path_points(path_msg, z)
        if name in self._shown and np.array_equal(self._shown[name], points):
            return  # the same path again (the planner re-sends its plan every second)
        self._shown[name] = points
        self.scene.delete(node)
        if points.shape[1] == 0:
            self._count(name)
            return
        if points.shape[1] >= 2:
            line = mg.Line(mg.PointsGeometry(points), mg.LineBasicMaterial(color=colour, linewidth=2.0))
            self.scene.set_object(f"{node}/line", line)
        rgb = np.array([(colour >> 16) & 255, (colour >> 8) & 255, colour & 255], dtype=np.float32) / 255.0
        colours = np.tile(rgb[:, None], (1, points.shape[1]))
        self.scene.set_object(f"{node}/vertices", mg.PointCloud(points, colours, size=0.05))
        self._count(name)

    def draw_goal(self, goal: Any) -> None:
        """Show a geometry_msgs/PoseStamped goal: a disk with an arrow along its heading."""
        self._goal = goal
        self._draw_goal_marker()
        self.scene.set_transform(f"{ROOT}/goal", pose_msg_matrix(goal.pose))
        self._count("goal")

    def set_goal_status(self, status: Any) -> None:
        """Colour the goal marker by an mjnav_msgs/GoalStatus (drawing the goal it names if none is shown yet)."""
        self.goal_state = int(status.state)
        if self._goal is None:
            self.draw_goal(status.goal)
        else:
            self._draw_goal_marker()
        self._count("goal_status")

    def _draw_goal_marker(self) -> None:
        colour = GOAL_COLOURS.get(self.goal_state, GOAL_COLOURS[0])
        s = self.scene
        disk = mg.MeshLambertMaterial(color=colour, opacity=0.55, transparent=True)
        s.set_object(f"{ROOT}/goal/disk", mg.Mesh(mg.Cylinder(0.02, 0.25), disk))
        s.set_transform(f"{ROOT}/goal/disk", _translation(0.0, 0.0, 0.01) @ _ROT_X_90)
        arrow = mg.MeshLambertMaterial(color=colour)
        s.set_object(f"{ROOT}/goal/arrow", mg.Mesh(mg.Cylinder(0.3, radiusTop=0.0, radiusBottom=0.08), arrow))
        # three.js cylinders point along +y; turn the cone's tip to +x and lift it off the floor.
        s.set_transform(f"{ROOT}/goal/arrow", _translation(0.15, 0.0, 0.08) @ _rot_z(-math.pi / 2))

    # ------------------------------------------------------------------------------------------------ dispatch

    def handle(self, topic_name: str, msg: Any) -> bool:
        """Draw ``msg`` received on topic ``topic_name``; returns False for topics the view does not draw."""
        if topic_name == self.pose_topic:
            pose = msg.pose.pose if hasattr(msg.pose, "pose") else msg.pose  # PoseStamped, or with covariance/Odometry
            self.set_robot_pose(pose_msg_matrix(pose))
            self.extend_trail(pose.position.x, pose.position.y)
        elif topic_name == "scan":
            self.draw_scan(msg)
        elif topic_name in ("map", "costmap"):
            self.draw_grid(msg, topic_name)
        elif topic_name in ("plan", "path"):
            self.draw_path(msg, topic_name)
        elif topic_name == "goal":
            self.goal_state = 0
            self.draw_goal(msg)
        elif topic_name == "goal_status":
            self.set_goal_status(msg)
        elif topic_name == "obstacles":
            self.move_bodies(msg)
        else:
            return False
        return True

    def _count(self, layer: str) -> None:
        self.drawn[layer] = self.drawn.get(layer, 0) + 1


def _translation(x: float, y: float, z: float) -> NDArray[np.float64]:
    out = np.eye(4)
    out[:3, 3] = (x, y, z)
    return out


def _rot_z(angle_rad: float) -> NDArray[np.float64]:
    return pose_matrix(0.0, 0.0, angle_rad)

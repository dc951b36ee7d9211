"""Scene building without a server or browser: MJCF geoms, message layers, the command tree, static HTML."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import umsgpack

from mjnav.geometry import Pose2D
from mjnav.msgs import from_dict, ros
from mjnav.viz import NavView, Scene, load_visual_model, write_static_html
from mjnav.viz.layers import grid_plane_transform, occupancy_rgba, path_points, scan_points
from mjnav.viz.view import ROOT
from tests.viz.helpers import goal_status, ring_scan, rooms_grid, snapshot_commands, straight_path


def _by_name(geoms: Any) -> dict[str, Any]:
    return {g.name: g for g in geoms}


def test_rooms_model_splits_world_and_robot_with_mujoco_colours() -> None:
    model = load_visual_model("rooms")
    world, robot = _by_name(model.world_geoms), _by_name(model.robot_geoms)
    assert {"floor", "wall_north", "sofa", "pillar"} <= set(world)
    assert not model.moving_bodies
    # Invisible collision spheres (alpha 0) are left out; visuals stay.
    assert "left_wheel" not in robot and "left_wheel_visual" in robot and "chassis" in robot
    # Robot geoms sit in base_link: the chassis centre is 0.1 m above the base, the lidar 0.2 m.
    assert np.allclose(robot["chassis"].pose[:3, 3], [0.0, 0.0, 0.1])
    assert np.allclose(model.laser_pose[:3, 3], [0.0, 0.0, 0.2])
    # Colours as MuJoCo renders them: explicit rgba wins, else the material (times the texture's mean colour).
    assert world["sofa"].rgba == pytest.approx((0.35, 0.45, 0.6, 1.0))
    assert world["wall_north"].rgba == pytest.approx((0.55, 0.5, 0.45, 1.0))
    assert 0.7 < world["floor"].rgba[0] < 0.85  # white material × grey checker texture
    assert model.start == Pose2D(-3.5, -3.5, 0.0)
    # World geoms are in the map frame: the north wall's centre is at y = 5.
    assert world["wall_north"].pose[1, 3] == pytest.approx(5.0)


def test_moving_bodies_are_kept_apart_and_follow_the_obstacles_topic() -> None:
    import mujoco

    from mjnav.sim.model import load_world

    model = load_visual_model("warehouse")
    bodies = {b.name: b for b in model.moving_bodies}
    assert set(bodies) == {"cart", "picker"}
    assert {g.name for b in bodies.values() for g in b.geoms} == {"cart", "picker"}
    assert not {"cart", "picker"} & {g.name for g in model.world_geoms}
    # Body pose ∘ geom pose relative to the body = the geom where MuJoCo puts it.
    loaded = load_world("warehouse")
    data = mujoco.MjData(loaded.model)
    mujoco.mj_kinematics(loaded.model, data)
    cart_geom = mujoco.mj_name2id(loaded.model, mujoco.mjtObj.mjOBJ_GEOM, "cart")
    np.testing.assert_allclose((bodies["cart"].pose @ bodies["cart"].geoms[0].pose)[:3, 3], data.geom_xpos[cart_geom])

    scene = Scene()
    view = NavView(scene)
    view.draw_model(model)
    assert scene.has_object(f"{ROOT}/moving/cart/cart")
    n = len(scene.commands())
    moved = ros.tf_message(
        ros.transform_stamped_3d(1.0, "map", "cart", (0.0, -1.0, 0.45), (0.0, 0.0, 0.0, 1.0)),
        ros.transform_stamped_3d(1.0, "map", "forklift", (9.0, 9.0, 0.0), (0.0, 0.0, 0.0, 1.0)),  # not in this world
    )
    assert view.handle("obstacles", moved)
    assert view.drawn["obstacles"] == 1  # the cart moved; the unknown body was ignored
    assert len(scene.commands()) == n  # the cart's transform was replaced, nothing added
    sent: list[bytes] = []
    scene.replay(lambda kind, path, packed: sent.append(packed) if path == f"{ROOT}/moving/cart" else None)
    (command,) = [umsgpack.unpackb(p) for p in sent if umsgpack.unpackb(p)["type"] == "set_transform"]
    matrix = np.array(command["matrix"], dtype=float).reshape(4, 4).T  # meshcat matrices are column-major
    np.testing.assert_allclose(matrix[:3, 3], [0.0, -1.0, 0.45])


def test_occupancy_image_rows_run_north_and_unknown_is_transparent() -> None:
    grid = from_dict(
        "nav_msgs/msg/OccupancyGrid",
        {
            "info": {"resolution": 0.5, "width": 3, "height": 2, "origin": {"orientation": {"w": 1.0}}},
            "data": [0, 50, 100, -1, 0, 0],
        },
    )
    image = occupancy_rgba(grid)
    assert image.shape == (2, 3, 4)
    # Grid row 0 (south) is the image's last row.
    assert image[1, 0].tolist() == [255, 255, 255, 255]
    assert image[1, 1, 0] == 128 and image[1, 2, :3].tolist() == [0, 0, 0]
    assert image[0, 0, 3] == 0  # unknown
    cost = occupancy_rgba(grid, "costmap")
    assert cost[1, 0, 3] == 0 and cost[1, 2, 3] > 0


def test_grid_plane_is_centred_on_the_rotated_origin() -> None:
    yaw = math.pi / 2
    grid = from_dict(
        "nav_msgs/msg/OccupancyGrid",
        {
            "info": {
                "resolution": 0.1,
                "width": 40,
                "height": 20,
                "origin": {
                    "position": {"x": 1.0, "y": 2.0},
                    "orientation": {"z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
                },
            }
        },
    )
    t = grid_plane_transform(grid, z_m=0.01)
    # 4 m along the origin's x (world +y), 2 m along its y (world -x): centre = origin + R (2, 1).
    assert t[:3, 3] == pytest.approx([1.0 - 1.0, 2.0 + 2.0, 0.01])
    assert t[:3, 0] == pytest.approx([0.0, 1.0, 0.0])


def test_scan_and_path_points() -> None:
    scan = ros.laser_scan(
        1.0,
        "laser",
        angle_min_rad=0.0,
        angle_increment_rad=math.pi / 2,
        scan_time_s=0.1,
        range_min_m=0.1,
        range_max_m=5.0,
        ranges_m=[1.0, math.inf, 2.0, 0.05],
    )
    pts = scan_points(scan)
    assert pts.shape == (3, 2)  # +inf (no return) and below range_min are dropped
    assert pts[:, 0] == pytest.approx([1.0, 0.0, 0.0]) and pts[:, 1] == pytest.approx([-2.0, 0.0, 0.0], abs=1e-6)
    path = path_points(straight_path(0.0, 0.0, 1.0, 0.0, 3), z_m=0.5)
    np.testing.assert_allclose(path.T, [[0, 0, 0.5], [0.5, 0, 0.5], [1, 0, 0.5]])


def test_scene_tree_mirrors_the_meshcat_server() -> None:
    sent: list[tuple[str, str]] = []
    scene = Scene(lambda kind, path, packed: sent.append((kind, path)))
    view = NavView(scene)
    view.draw_model(load_visual_model("rooms"))
    assert scene.has_object(f"{ROOT}/world/wall_north") and scene.has_object(f"{ROOT}/robot/body/chassis")
    assert ("set_transform", f"{ROOT}/robot") in sent
    n = len(scene.commands())
    assert len(sent) >= n  # every command went to the sink; the tree keeps only the latest per path
    view.handle("truth", ros.pose_stamped(1.0, "map", Pose2D(1.0, 2.0, 0.0)))
    assert len(scene.commands()) == n  # a new pose replaces the old transform
    view.handle("truth", ros.pose_stamped(2.0, "map", Pose2D(2.0, 2.0, 0.0)))
    assert len(scene.commands()) == n + 1  # the driven trail appears with its second point
    view.handle("truth", ros.pose_stamped(3.0, "map", Pose2D(3.0, 2.0, 0.0)))
    assert len(scene.commands()) == n + 1  # ... and is replaced as it grows
    scene.delete(f"{ROOT}/world")
    assert not any(p.startswith(f"{ROOT}/world") for p in scene.paths())
    assert sent[-1] == ("delete", f"{ROOT}/world")
    replayed: list[str] = []
    assert scene.replay(lambda kind, path, packed: replayed.append(kind)) == len(scene.commands())


def test_view_draws_every_topic_and_ignores_others() -> None:
    scene = Scene()
    view = NavView(scene)
    assert view.handle("map", rooms_grid())
    assert view.handle("costmap", rooms_grid("costmap"))
    assert view.handle("scan", ring_scan())
    assert view.handle("plan", straight_path(-3.5, -3.5, 3.0, 2.0))
    assert view.handle("path", straight_path(-3.5, -3.5, 3.0, 2.0))
    assert view.handle("goal", ros.pose_stamped(1.0, "map", Pose2D(3.8, 2.2, 1.57)))
    assert view.handle("goal_status", goal_status(4, Pose2D(3.8, 2.2, 1.57)))
    assert not view.handle("imu", object())
    for layer in ("map", "costmap", "robot/laser/scan", "plan/line", "path/vertices", "goal/arrow"):
        assert scene.has_object(f"{ROOT}/{layer}"), layer
    assert view.goal_state == 4
    odom_view = NavView(Scene(), pose_topic="odom")
    assert not odom_view.handle("ground_truth", ros.pose_stamped(1.0, "map", Pose2D(0, 0, 0)))
    assert odom_view.handle("odom", ros.odometry(1.0, Pose2D(1.0, 0.0, 0.0), 0.0, 0.0))


def test_static_html_is_self_contained_and_replays_the_scene(tmp_path: Path) -> None:
    out = write_static_html(
        tmp_path / "snap" / "scene.html",
        world="rooms",
        messages=[("map", rooms_grid()), ("truth", ros.pose_stamped(1.0, "map", Pose2D(-2.0, -3.0, 0.5)))],
        title="rooms <test>",
    )
    text = out.read_text(encoding="utf-8")
    assert "<title>rooms &lt;test&gt;</title>" in text
    assert "<script src" not in text and "MeshCat.Viewer" in text  # the viewer is inlined
    commands = snapshot_commands(out)
    paths = {(c["type"], c["path"]) for c in commands}
    assert ("set_object", f"{ROOT}/map") in paths and ("set_object", f"{ROOT}/robot/body/chassis") in paths
    robot = [c for c in commands if c["type"] == "set_transform" and c["path"] == f"{ROOT}/robot"]
    assert len(robot) == 1
    matrix = np.array(robot[0]["matrix"]).reshape(4, 4).T  # meshcat sends column-major
    assert matrix[:3, 3] == pytest.approx([-2.0, -3.0, 0.0]) and math.atan2(
        matrix[1, 0], matrix[0, 0]
    ) == pytest.approx(0.5)
    texture = next(c for c in commands if c["path"] == f"{ROOT}/map")["object"]["images"][0]["url"]
    assert texture.startswith("data:image/png;base64,")


def test_static_html_shows_the_driven_trail(tmp_path: Path) -> None:
    from mjnav.viz.view import TRAIL_SPACING_M

    drive = [Pose2D(-3.0 + 0.02 * i, -3.0 + 0.01 * i, 0.46) for i in range(101)]  # 2.24 m at 2 cm steps
    out = write_static_html(
        tmp_path / "scene.html",
        world="rooms",
        messages=[("truth", ros.pose_stamped(0.1 * i, "map", p)) for i, p in enumerate(drive)],
    )
    commands = snapshot_commands(out)
    trail = [c for c in commands if c["type"] == "set_object" and c["path"] == f"{ROOT}/trail"]
    assert len(trail) == 1  # the snapshot holds the newest trail
    geometry = trail[0]["object"]["geometries"][0]
    packed = geometry["data"]["attributes"]["position"]["array"]  # a msgpack typed-array extension
    xyz = np.frombuffer(packed.data, dtype=np.float32).reshape(-1, 3)
    assert xyz[0, :2] == pytest.approx([-3.0, -3.0])
    assert len(xyz) == pytest.approx(math.dist((-3.0, -3.0), (-1.0, -2.0)) / TRAIL_SPACING_M, abs=2)
    # Every trail point lies on the driven line, in order.
    assert np.allclose(xyz[:, 1] + 3.0, 0.5 * (xyz[:, 0] + 3.0), atol=1e-5) and np.all(np.diff(xyz[:, 0]) > 0)


def test_merged_boxes_have_the_boxes_corners_and_faces_that_look_outwards() -> None:
    from mjnav.viz.model import VisualGeom
    from mjnav.viz.view import merged_boxes

    yaw = 0.6
    pose = np.eye(4)
    pose[:3, :3] = [[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]]
    pose[:3, 3] = [3.0, -1.0, 0.25]
    boxes = [
        VisualGeom("a", "box", (0.5, 0.2, 0.25), (1, 0, 0, 1), pose),
        VisualGeom("b", "box", (1.0, 1.0, 1.0), (1, 0, 0, 1), np.eye(4)),
    ]
    vertices, faces = merged_boxes(boxes)
    assert vertices.shape == (48, 3) and faces.shape == (24, 3) and faces.max() == 47
    corners = np.unique(np.round(vertices[:24].astype(np.float64), 4), axis=0)
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
    expected = np.unique(np.round((signs * [0.5, 0.2, 0.25]) @ pose[:3, :3].T + pose[:3, 3], 4), axis=0)
    np.testing.assert_allclose(corners, expected, atol=2e-4)  # the first box's 8 corners, each on its 3 faces
    for k, f in enumerate(faces):
        a, b, c = vertices[f].astype(np.float64)
        normal = np.cross(b - a, c - a)
        centre = pose[:3, 3] if k < 12 else np.zeros(3)
        assert np.dot(normal, (a + b + c) / 3 - centre) > 0  # counter-clockwise seen from outside
    assert {int(i) for i in faces[:12].ravel()} == set(range(24))  # every face of the first box uses its own corners


def test_a_world_of_many_boxes_draws_one_mesh_per_colour(tmp_path: Path) -> None:
    from mjnav.sim.worldgen import write_scene_from_map
    from mjnav.viz.view import MERGE_ABOVE_GEOMS

    rows = ["".join("@" if r % 2 and c % 2 else "." for c in range(41)) for r in range(41)]  # 400 lone cells
    src = tmp_path / "dots.map"
    src.write_text("type octile\nheight 41\nwidth 41\nmap\n" + "\n".join(rows) + "\n", encoding="utf-8")
    write_scene_from_map(src, tmp_path / "dots.xml", resolution_m=1.0, start=Pose2D(0.5, 0.5, 0.0))
    model = load_visual_model(tmp_path / "dots.xml")
    boxes = [g for g in model.world_geoms if g.shape == "box"]
    assert len(model.world_geoms) > MERGE_ABOVE_GEOMS and len(boxes) >= 400
    scene = Scene()
    NavView(scene).draw_model(model)
    world = [p for p in scene.paths() if p.startswith(f"{ROOT}/world/")]
    merged = [p for p in world if p.startswith(f"{ROOT}/world/boxes_")]
    assert len(merged) == len({g.rgba for g in boxes})  # one mesh per colour of box
    assert not any(scene.has_object(f"{ROOT}/world/{g.name}") for g in boxes)
    planes = [g.name for g in model.world_geoms if g.shape != "box"]
    assert planes and all(scene.has_object(f"{ROOT}/world/{name}") for name in planes)  # the floor stays itself
    small = Scene()
    NavView(small).draw_model(load_visual_model("rooms"))
    assert not any("boxes_" in p for p in small.paths())  # a world of few geoms keeps them by name

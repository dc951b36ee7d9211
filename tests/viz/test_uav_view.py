"""The UAV meshcat view: the field's geoms and the quadrotor, the vehicle moved, the reference and the trail drawn."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mjnav.msgs import uav as uav_msgs
from mjnav.viz import Scene
from mjnav.viz.uav import ROOT, TRAIL_CHUNK, UavView, load_uav_visual


def test_uav_scene_reference_and_trail(tmp_path: Path) -> None:
    visual = load_uav_visual("field")
    names = {g.name for g in visual.uav_geoms}
    assert {"hull", "prop0", "arm3"} <= names and "pillar_ne" in {g.name for g in visual.world_geoms}
    scene = Scene()
    view = UavView(scene, trail_spacing_m=0.01)
    view.setup(visual)
    assert scene.has_object(f"{ROOT}/uav/hull") and scene.has_object(f"{ROOT}/world/pillar_ne")
    ts = np.arange(0.0, 2.0, 0.05)
    pts = np.column_stack([np.sin(ts), 0.5 * np.sin(2 * ts), np.full(ts.size, 1.5)])
    view.add_trajectory(uav_msgs.trajectory("map", ts, pts))
    view.add_trajectory(uav_msgs.trajectory("map", ts + 1.0, pts))  # overlapping sends merge by stamp
    assert len(view.reference) == ts.size + 20 and scene.has_object(f"{ROOT}/reference")
    for i in range(TRAIL_CHUNK + 50):
        view.set_pose(uav_msgs.pose_stamped3d(0.02 * i, "map", [0.02 * i, 0.0, 1.5]))
    assert scene.has_object(f"{ROOT}/trail/0") and scene.has_object(f"{ROOT}/trail/1")
    assert view.drawn["uav"] == TRAIL_CHUNK + 50
    html = scene.write_static_html(tmp_path / "uav.html")
    assert html.stat().st_size > 10_000


def test_a_batch_of_poses_extends_the_trail_but_moves_the_vehicle_once() -> None:
    sent: list[str] = []
    scene = Scene(lambda kind, path, packed: sent.append(kind))
    view = UavView(scene, trail_spacing_m=0.01)
    view.setup(load_uav_visual("field"))
    sent.clear()
    poses = [uav_msgs.pose_stamped3d(0.02 * i, "map", [0.02 * i, 0.0, 1.5]) for i in range(10)]
    for i, msg in enumerate(poses):
        last = i == len(poses) - 1
        view.set_pose(msg, redraw_trail=last, place=last)
    assert len(view.trail) == 10 and np.allclose(view.trail[-1], [0.18, 0.0, 1.5])
    assert view.drawn["uav"] == 1
    assert sorted(sent) == ["set_object", "set_transform"]  # the trail redrawn once, the vehicle moved once

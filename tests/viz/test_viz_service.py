"""The viz service over real Zenoh: it follows the sim's world, draws every topic live into meshcat, writes a
snapshot when it stops, and headless Chromium renders that snapshot with the robot and the map in their colours."""

from __future__ import annotations

import json
import logging
import os
import shutil
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mjnav.bus import Bus, wait_until
from mjnav.geometry import Pose2D
from mjnav.msgs import from_dict, msg_class, ros
from mjnav.services.viz import VizConfig, VizService
from mjnav.viz import BrowserUnavailable, NavView, Scene, find_chromium, load_visual_model, screenshot
from mjnav.viz.view import ROOT
from tests.conftest import REPO, free_port
from tests.viz.helpers import ViewerClient, goal_status, ring_scan, rooms_grid, snapshot_commands, straight_path

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers

STACK = REPO / "tests" / "viz" / "stack.toml"
Peer = Callable[..., Bus]
ROBOT_POSE = Pose2D(-2.0, -3.0, 0.5)


def _serve_sim_world(bus: Bus, world: str) -> None:
    """Answer ``<ns>/config/sim`` as the sim does, naming ``world``."""
    string = msg_class("std_msgs/msg/String")
    bus.serve("config", lambda _req: string(data=json.dumps({"world": world, "rtf": 1.0})), service="sim")


def test_viz_follows_the_sims_world_or_draws_the_robot_alone(peer: Peer) -> None:
    me, viz_bus = peer(), peer()
    log = logging.getLogger("test.viz")
    lonely = VizService(VizConfig(serve=False, world_timeout_s=0.3), viz_bus, log)
    lonely.configure()
    lonely.activate()
    assert wait_until(lambda: lonely.step(0.0) or lonely.view.model is not None, 10.0)
    assert lonely.view.model is not None and lonely.view.model.name == "diffbot"
    assert not lonely.view.model.world_geoms and lonely.view.model.robot_geoms

    _serve_sim_world(me, "maze")  # a live sim answers <ns>/config/sim
    follower = VizService(VizConfig(serve=False, world_timeout_s=30.0), viz_bus, log)
    follower.configure()
    follower.activate()
    assert wait_until(lambda: follower.step(0.0) or follower.view.model is not None, 20.0)
    assert follower.view.model is not None and follower.view.model.name == "maze"
    assert follower.scene.has_object(f"{ROOT}/world/floor")

    # A replayed bag has no sim to ask, but its sim_status names the world (and wins over the config).
    replay = VizService(VizConfig(serve=False, world_timeout_s=30.0), viz_bus, log)
    replay.configure()
    replay.activate()
    status = me.publisher("sim_status")
    assert status.wait_for_subscribers(10.0)
    status.put(from_dict("mjnav_msgs/msg/SimStatus", {"header": {"frame_id": "map"}, "world": "warehouse"}))
    assert replay.sim_world.sim_status.wait(10.0, lambda m: m.world == "warehouse") is not None
    assert wait_until(lambda: replay.step(0.0) or replay.view.model is not None, 20.0)
    assert replay.view.model is not None and replay.view.model.name == "warehouse"


def _colour_masks(png: Path) -> dict[str, np.ndarray]:
    from PIL import Image

    a = np.asarray(Image.open(png).convert("RGB")).astype(int)
    r, g, b = a[..., 0], a[..., 1], a[..., 2]
    return {
        "robot": (b > 110) & (b - r > 60) & (b - g > 35),  # chassis rgba 0.15 0.35 0.65, lit
        "map": (r >= 250) & (g >= 250) & (b >= 250),  # free cells: white, unlit (the lit floor stays below ~215)
        "scan": (r > 170) & (g < 90) & (b < 90),  # red returns
    }


def test_viz_service_draws_the_bus_live_and_its_snapshot_renders(
    router_endpoint: str, peer: Peer, tmp_path: Path
) -> None:
    me = peer()
    _serve_sim_world(me, "rooms")
    web_port, zmq_port = free_port(), free_port()
    snapshot = tmp_path / "scene.html"
    env = {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_ZENOH_")}
    env.update(MJNAV_HEADLESS="1", PYTHONPATH=str(REPO))
    overrides = [f"web_port={web_port}", f"zmq_port={zmq_port}", f"static_html={json.dumps(str(snapshot))}"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "mjnav", "run", "viz", "--stack", str(STACK), "--connect", router_endpoint]
        + [arg for item in overrides for arg in ("--set", item)],
        cwd=REPO,
        env=env,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    viewer: ViewerClient | None = None
    try:
        alive: dict[str, bool] = {}
        me.watch_alive(lambda name, up: alive.__setitem__(name, up))
        assert wait_until(lambda: alive.get("viz") is True, 30.0), "the viz service never came up"
        viewer = ViewerClient(f"http://127.0.0.1:{web_port}/static/")

        messages: list[tuple[str, Any]] = [
            ("truth", ros.pose_stamped(3.0, "map", ROBOT_POSE)),
            ("map", rooms_grid()),
            ("costmap", rooms_grid("costmap")),
            ("scan", ring_scan()),
            ("plan", straight_path(-2.0, -3.0, 3.8, 2.2)),
            ("path", straight_path(-2.0, -3.0, 3.8, 2.2)),
            ("goal", ros.pose_stamped(3.0, "map", Pose2D(3.8, 2.2, 1.57))),
            ("goal_status", goal_status(3, Pose2D(3.8, 2.2, 1.57))),
        ]
        for name, msg in messages:
            pub = me.publisher(name)
            assert pub.wait_for_subscribers(10.0), f"viz does not subscribe to {name}"
            pub.put(msg)

        layers = ["map", "costmap", "robot/laser/scan", "plan/line", "path/line", "goal/arrow", "world/sofa"]

        def robot_at_pose(commands: list[dict[str, Any]]) -> bool:
            for c in commands:
                if c.get("type") == "set_transform" and c["path"] == f"{ROOT}/robot":
                    m = np.array(c["matrix"]).reshape(4, 4).T
                    if np.allclose(m[:2, 3], [ROBOT_POSE.x, ROBOT_POSE.y]):
                        return True
            return False

        drawn = viewer.wait_for(
            lambda cs: robot_at_pose(cs) and {f"{ROOT}/{layer}" for layer in layers} <= {c["path"] for c in cs},
            60.0,  # a guard against hanging, not a speed check: two test suites may share the 2 cores
        )
        assert drawn, f"the live viewer got only {sorted(viewer.paths('set_object'))}"
    finally:
        if viewer is not None:
            viewer.close()
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
        try:
            code = proc.wait(15.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            code = None
        out = proc.communicate(timeout=10)[0]
    assert code == 0, out
    assert "meshcat viewer at http://127.0.0.1:" in out and "drawing world rooms" in out

    # The snapshot written at stop holds the same scene, offline.
    paths = {c["path"] for c in snapshot_commands(snapshot) if c["type"] == "set_object"}
    assert {f"{ROOT}/map", f"{ROOT}/robot/body/chassis", f"{ROOT}/robot/laser/scan", f"{ROOT}/goal/disk"} <= paths

    try:
        find_chromium()
    except BrowserUnavailable as exc:
        pytest.skip(f"browser check skipped: {exc} (make test installs it)")
    # Control: the same world and camera without robot, map or scan, rendered the same way.
    control_scene = Scene()
    view = NavView(control_scene)
    model = load_visual_model("rooms")
    view.setup_viewer(model.view_bounds())
    view.draw_model(model)
    control_scene.delete(f"{ROOT}/robot")
    control_html = control_scene.write_static_html(tmp_path / "control.html")

    shot = _colour_masks(screenshot(snapshot, tmp_path / "scene.png"))
    control = _colour_masks(screenshot(control_html, tmp_path / "control.png"))
    height, width = shot["map"].shape
    for layer, minimum in (("robot", 40), ("map", 5000), ("scan", 100)):
        assert shot[layer].sum() >= minimum + control[layer].sum(), (
            f"{layer}: {shot[layer].sum()} pixels in its colour, {control[layer].sum()} without it"
        )
    ys, xs = np.nonzero(shot["robot"] & ~control["robot"])
    # The robot at (-2, -3) is in the south-west quarter of the rooms world: lower left of the top-down view.
    assert xs.mean() < width / 2 and ys.mean() > height / 2, (xs.mean(), ys.mean())


def test_the_uav_viewer_draws_the_scene_its_sim_runs(peer: Peer, tmp_path: Path) -> None:
    """Nothing tells uav_viz its scene: it asks the UAV sim (its config, here naming a copy of the field scene) and
    draws what that sim runs, or field when no sim answers."""
    from mjnav.services.uav_viz import UavVizConfig, UavVizService

    me, viz_bus = peer("uav0"), peer("uav0")
    log = logging.getLogger("test.uav_viz")
    lonely = UavVizService(UavVizConfig(serve=False, world_timeout_s=0.3), viz_bus, log)
    lonely.configure()
    lonely.activate()
    assert wait_until(lambda: lonely.step(0.0) or lonely.drawn_world is not None, 10.0)
    assert lonely.drawn_world == "field"
    shutil.copytree(REPO / "mjcf", tmp_path / "mjcf")  # the scene's includes are relative to it
    copy = tmp_path / "mjcf" / "uav" / "copy_of_field.xml"
    (tmp_path / "mjcf" / "uav" / "field.xml").rename(copy)
    string = msg_class("std_msgs/msg/String")
    me.serve("config", lambda _req: string(data=json.dumps({"world": str(copy)})), service="uav_sim")
    follower = UavVizService(UavVizConfig(serve=False, world_timeout_s=30.0), viz_bus, log)
    follower.configure()
    follower.activate()
    assert wait_until(lambda: follower.step(0.0) or follower.drawn_world is not None, 20.0)
    assert follower.drawn_world == str(copy)

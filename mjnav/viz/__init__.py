"""meshcat visualisation of the navigation stack: scene building, a headless meshcat server, static snapshots.

* :class:`Scene` — the scene as meshcat drawing commands; mirrored live to a server and/or written as a
  self-contained HTML snapshot (:meth:`Scene.write_static_html`).
* :class:`NavView` — what goes where: MJCF world and robot, robot pose, occupancy map and costmap, scan points,
  plan and path, goal; :meth:`NavView.handle` draws a message received on a topic.
* :func:`load_visual_model` — the visible geoms of an MJCF world, split into world, moving bodies and robot.
* :class:`MeshcatServer` / :class:`MeshcatClient` — meshcat's web + ZMQ server on a thread, bound to loopback by
  default, and a client with timeouts.
* :func:`write_static_html` — one call from a world and a set of messages to an HTML file (no server needed).
* :func:`screenshot` — render an HTML snapshot to PNG with headless Chromium.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import mjnav.viz._meshcat  # noqa: F401  (first: imports meshcat without its pyzmq deprecation warning)
from mjnav.viz.browser import find_chromium, screenshot
from mjnav.viz.errors import BrowserUnavailable, MeshcatServerError, ScreenshotError, VizError
from mjnav.viz.model import MovingBody, VisualGeom, VisualModel, load_visual_model
from mjnav.viz.scene import Scene
from mjnav.viz.server import MeshcatClient, MeshcatServer
from mjnav.viz.view import NavView

__all__ = [
    "BrowserUnavailable",
    "MeshcatClient",
    "MeshcatServer",
    "MeshcatServerError",
    "MovingBody",
    "NavView",
    "Scene",
    "ScreenshotError",
    "VisualGeom",
    "VisualModel",
    "VizError",
    "find_chromium",
    "load_visual_model",
    "screenshot",
    "write_static_html",
]


def write_static_html(
    path: str | Path,
    *,
    world: str | Path | VisualModel | None = "rooms",
    messages: Iterable[tuple[str, Any]] = (),
    pose_topic: str = "truth",
    title: str = "mjnav",
) -> Path:
    """Draw a world and messages offline and write the self-contained HTML snapshot to ``path``.

    Args:
        path: output ``.html`` file (parent folders are created).
        world: bundled world name, MJCF path, an already loaded :class:`VisualModel`, or None (messages only).
        messages: ``(topic name, decoded message)`` pairs drawn in order, e.g.
            ``[("map", grid), ("truth", pose), ("path", path)]``; topics the view does not draw are skipped.
        pose_topic: the topic that moves the robot (one of :data:`mjnav.viz.view.POSE_TOPICS`).
        title: page title.

    Returns:
        The written path.
    """
    scene = Scene()
    view = NavView(scene, pose_topic=pose_topic)
    model = load_visual_model(world) if isinstance(world, str | Path) else world
    view.setup_viewer(model.view_bounds() if model is not None else None)
    if model is not None:
        view.draw_model(model)
    for topic_name, msg in messages:
        view.handle(topic_name, msg)
    return scene.write_static_html(path, title)

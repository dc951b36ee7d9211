"""Messages and scene inspection shared by the viz tests."""

from __future__ import annotations

import base64
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import umsgpack

from mjnav.geometry import Pose2D
from mjnav.msgs import from_dict, msg_class, ros

#: The rooms world spans x, y in [-5.05, 5.05]; a 0.05 m grid over [-5.2, 5.2].
MAP_ORIGIN = (-5.2, -5.2)
MAP_RES = 0.05
MAP_CELLS = 208


def rooms_grid(kind: str = "map") -> Any:
    """An OccupancyGrid of the rooms world's outer walls and the x = 0 partition; the rest free, a strip unknown."""
    n = MAP_CELLS
    cells = np.zeros((n, n), dtype=np.int8)
    xs = MAP_ORIGIN[0] + (np.arange(n) + 0.5) * MAP_RES
    ys = MAP_ORIGIN[1] + (np.arange(n) + 0.5) * MAP_RES
    X, Y = np.meshgrid(xs, ys)  # rows along y
    walls = (np.abs(np.abs(X) - 5.0) < 0.06) | (np.abs(np.abs(Y) - 5.0) < 0.06) | (np.abs(X) < 0.06)
    cells[walls] = 100
    cells[(np.abs(X) > 5.1) | (np.abs(Y) > 5.1)] = -1
    if kind == "costmap":
        cells = np.where(cells < 0, 0, cells).astype(np.int8)
    return from_dict(
        "nav_msgs/msg/OccupancyGrid",
        {
            "header": {"stamp": {"sec": 3}, "frame_id": "map"},
            "info": {
                "resolution": MAP_RES,
                "width": n,
                "height": n,
                "origin": {"position": {"x": MAP_ORIGIN[0], "y": MAP_ORIGIN[1]}, "orientation": {"w": 1.0}},
            },
            "data": cells.ravel().tolist(),
        },
    )


def ring_scan(radius_m: float = 1.5, beams: int = 360) -> Any:
    """A LaserScan seeing a circle of ``radius_m`` around the lidar."""
    return ros.laser_scan(
        3.0,
        "laser",
        angle_min_rad=-math.pi,
        angle_increment_rad=2 * math.pi / beams,
        scan_time_s=0.1,
        range_min_m=0.12,
        range_max_m=12.0,
        ranges_m=np.full(beams, radius_m),
    )


def straight_path(x0: float, y0: float, x1: float, y1: float, n: int = 20) -> Any:
    """A nav_msgs/Path of ``n`` poses on a segment, frame map."""
    poses = [
        {
            "header": {"frame_id": "map"},
            "pose": {
                "position": {"x": x0 + (x1 - x0) * i / (n - 1), "y": y0 + (y1 - y0) * i / (n - 1)},
                "orientation": {"w": 1.0},
            },
        }
        for i in range(n)
    ]
    return from_dict("nav_msgs/msg/Path", {"header": {"frame_id": "map"}, "poses": poses})


def goal_status(state: int, goal: Pose2D) -> Any:
    """An mjnav_msgs/GoalStatus for ``goal``."""
    return msg_class("mjnav_msgs/msg/GoalStatus")(
        header=ros.header(3.0, "map"),
        goal_id=1,
        state=state,
        error_code=0,
        error_text="",
        goal=ros.pose_stamped(3.0, "map", goal),
    )


def snapshot_commands(html_file: Path) -> list[dict[str, Any]]:
    """The decoded meshcat commands embedded in a static HTML snapshot."""
    text = html_file.read_text(encoding="utf-8")
    m = re.search(r"const commands = (\[.*?\]);", text, re.S)
    assert m, "no embedded commands in the snapshot"
    return [umsgpack.unpackb(base64.b64decode(c)) for c in json.loads(m.group(1))]


class ViewerClient:
    """A browser stand-in: holds the meshcat WebSocket open and decodes every command the server sends."""

    def __init__(self, web_url: str, timeout_s: float = 60.0) -> None:
        import asyncio
        import threading

        host_port = web_url.split("//", 1)[1].split("/", 1)[0]
        self.url = f"ws://{host_port}/"
        self.commands: list[dict[str, Any]] = []
        self._cond = threading.Condition()
        self._loop = asyncio.new_event_loop()
        self._connected = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._loop.run_until_complete, args=(self._run(),), daemon=True)
        self._thread.start()
        if not self._connected.wait(timeout_s) or self._error is not None:
            raise AssertionError(f"could not open {self.url}: {self._error}")

    async def _run(self) -> None:
        from tornado.websocket import websocket_connect

        try:
            self._conn = await websocket_connect(self.url)
        except Exception as exc:
            self._error = exc
            self._connected.set()
            return
        self._connected.set()
        while True:
            message = await self._conn.read_message()
            if message is None:
                break
            data = umsgpack.unpackb(message if isinstance(message, bytes) else message.encode())
            with self._cond:
                self.commands.append(data)
                self._cond.notify_all()

    def wait_for(self, predicate: Any, timeout_s: float) -> bool:
        """Wait until ``predicate(commands)`` holds (checked on every new command)."""
        import time

        deadline = time.monotonic() + timeout_s
        with self._cond:
            while not predicate(self.commands):
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._cond.wait(remaining)
            return True

    def paths(self, kind: str) -> set[str]:
        """Paths of the received commands of ``kind``."""
        with self._cond:
            return {c["path"] for c in self.commands if c.get("type") == kind}

    def close(self) -> None:
        """Close the connection."""
        conn = getattr(self, "_conn", None)
        if conn is not None:
            self._loop.call_soon_threadsafe(conn.close)
        self._thread.join(5.0)

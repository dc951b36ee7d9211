"""World (scene) resolution: bundled names, MJCF paths and the per-world start and goal.

Bundled worlds are the top-level ``*.xml`` files of ``mjcf/`` (except the robot models), so ``--world rooms``
means ``mjcf/rooms.xml``. Any other argument naming an existing file is used as an MJCF path.

Start and goal convention (documented here, used by every scene in ``mjcf/``):

* **Start**: where the scene attaches the robot, ``<frame name="start" pos="X Y 0" euler="0 0 YAW">`` around
  ``<attach model="diffbot" body="base_link" prefix="robot/"/>``. The compiled model's initial free-joint pose
  *is* the start pose, so the scene also opens correctly in MuJoCo's own viewer.
* **Goal**: ``<custom><numeric name="mjnav_goal" data="X Y [YAW]"/></custom>``, metres and radians, map
  frame.
  Optional; :attr:`WorldInfo.goal` is ``None`` without it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import mjnav
from mjnav.geometry import Pose2D
from mjnav.sim.errors import UnknownWorldError

#: Folder of the bundled MJCF models (robot, scenes, assets).
MJCF_DIR: Path = mjnav.REPO_ROOT / "mjcf"

#: Top-level files of ``mjcf/`` that are robot models, not worlds.
ROBOT_MODELS: frozenset[str] = frozenset({"diffbot", "quadrotor"})

#: Name of the custom numeric holding the default goal (x, y[, yaw]).
GOAL_NUMERIC = "mjnav_goal"


def available_worlds() -> tuple[str, ...]:
    """Names of the bundled worlds (stems of ``mjcf/*.xml`` minus the robot models), sorted."""
    if not MJCF_DIR.is_dir():
        return ()
    return tuple(sorted(p.stem for p in MJCF_DIR.glob("*.xml") if p.stem not in ROBOT_MODELS))


def resolve_world(world: str | Path) -> Path:
    """Turn a world name or an MJCF path into the path of an existing MJCF file.

    Args:
        world: a bundled world name (``"rooms"``) or a path to any MJCF file that contains the robot.

    Returns:
        Absolute path of the MJCF file.

    Raises:
        UnknownWorldError: neither a bundled name nor an existing file; the message lists the bundled names.
    """
    text = str(world)
    if text in available_worlds():
        return (MJCF_DIR / f"{text}.xml").resolve()
    path = Path(text).expanduser()
    if path.is_file():
        return path.resolve()
    raise UnknownWorldError(text, available_worlds())


@dataclass(frozen=True, slots=True)
class WorldInfo:
    """What a navigation demo needs to know about a world before simulating it.

    Attributes:
        name: world name (file stem).
        path: absolute MJCF path.
        start: robot start pose in the map frame (metres, radians).
        goal: default goal in the map frame, or ``None`` when the scene defines none.
        bounds_m: (x_min, y_min, x_max, y_max) of the static non-plane geoms (walls, shelves), metres,
            or ``None`` for a world without any (``empty``).
        robot_radius_m: radius of the smallest vertical cylinder about ``base_link`` holding every colliding robot
            geom (the footprint the costmap and the controller use), metres.
        lidar_offset_m: (x, y, z) of the robot's ``lidar`` site in ``base_link`` (the ``base_link → laser``
            transform), metres.
    """

    name: str
    path: Path
    start: Pose2D
    goal: Pose2D | None
    bounds_m: tuple[float, float, float, float] | None
    robot_radius_m: float
    lidar_offset_m: tuple[float, float, float]


def goal_from_numeric(data: list[float] | tuple[float, ...]) -> Pose2D:
    """Pose of an ``mjnav_goal`` numeric: 2 values (x, y) or 3 values (x, y, yaw).

    Raises:
        ValueError: wrong length or non-finite values.
    """
    values = [float(v) for v in data]
    if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{GOAL_NUMERIC} needs 2 or 3 finite numbers (x y [yaw]), got {values}")
    return Pose2D(values[0], values[1], values[2] if len(values) == 3 else 0.0)


def world_info(world: str | Path) -> WorldInfo:
    """Compile a world and report its start, goal and bounds (no simulation state is kept).

    Args:
        world: bundled name or MJCF path, as for :func:`resolve_world`.

    Raises:
        UnknownWorldError: see :func:`resolve_world`.
        ModelLoadError: the MJCF does not compile.
        RobotNotFoundError: the MJCF contains no mjnav robot.
    """
    from mjnav.sim.model import load_world  # imports mujoco

    return load_world(world).info

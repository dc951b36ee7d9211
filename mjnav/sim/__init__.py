"""MuJoCo simulation of the mjnav diff-drive robot: worlds, sensors, stepping, recording.

Main entry points (imported lazily, so ``import mjnav.sim.glbackend`` does not import MuJoCo and can still
choose ``MUJOCO_GL`` first):

* :class:`Simulator` — load a world, command (v, ω), step at 2 ms, read lidar, odometry, IMU, encoders and
  the ground truth.
* :class:`SimRunner` — run a simulator at a real-time factor with periodic hooks (the ``mjnav sim`` loop).
* :class:`Recorder` — offscreen MP4 recording, usable as a runner hook.
* :func:`resolve_world`, :func:`available_worlds`, :func:`world_info` — bundled worlds and their start/goal.
* :func:`write_scene_from_map` — occupancy map → world (``mjnav world from-map``).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

_EXPORTS: dict[str, str] = {
    "Simulator": "mjnav.sim.simulator",
    "WheelStates": "mjnav.sim.simulator",
    "BodyPose": "mjnav.sim.simulator",
    "ImuReading": "mjnav.sim.simulator",
    "DEFAULT_LIDAR": "mjnav.sim.simulator",
    "DEFAULT_ODOMETRY": "mjnav.sim.simulator",
    "LidarConfig": "mjnav.sim.lidar",
    "LidarScan": "mjnav.sim.lidar",
    "OdometryConfig": "mjnav.sim.odometry",
    "OdometryEstimate": "mjnav.sim.odometry",
    "SimRunner": "mjnav.sim.runner",
    "RunStats": "mjnav.sim.runner",
    "Hook": "mjnav.sim.runner",
    "Recorder": "mjnav.sim.recording",
    "select_gl_backend": "mjnav.sim.glbackend",
    "WorldInfo": "mjnav.sim.worlds",
    "available_worlds": "mjnav.sim.worlds",
    "resolve_world": "mjnav.sim.worlds",
    "world_info": "mjnav.sim.worlds",
    "write_scene_from_map": "mjnav.sim.worldgen",
    "SimError": "mjnav.sim.errors",
    "UnknownWorldError": "mjnav.sim.errors",
    "ModelLoadError": "mjnav.sim.errors",
    "RobotNotFoundError": "mjnav.sim.errors",
    "InvalidCommandError": "mjnav.sim.errors",
    "RenderBackendUnavailableError": "mjnav.sim.errors",
    "RecordingError": "mjnav.sim.errors",
    "MapConversionError": "mjnav.sim.errors",
}

__all__ = [
    "DEFAULT_LIDAR",
    "DEFAULT_ODOMETRY",
    "BodyPose",
    "Hook",
    "ImuReading",
    "InvalidCommandError",
    "LidarConfig",
    "LidarScan",
    "MapConversionError",
    "ModelLoadError",
    "OdometryConfig",
    "OdometryEstimate",
    "Recorder",
    "RecordingError",
    "RenderBackendUnavailableError",
    "RobotNotFoundError",
    "RunStats",
    "SimError",
    "SimRunner",
    "Simulator",
    "UnknownWorldError",
    "WheelStates",
    "WorldInfo",
    "available_worlds",
    "resolve_world",
    "select_gl_backend",
    "world_info",
    "write_scene_from_map",
]

if TYPE_CHECKING:
    from mjnav.sim.errors import (
        InvalidCommandError,
        MapConversionError,
        ModelLoadError,
        RecordingError,
        RenderBackendUnavailableError,
        RobotNotFoundError,
        SimError,
        UnknownWorldError,
    )
    from mjnav.sim.glbackend import select_gl_backend
    from mjnav.sim.lidar import LidarConfig, LidarScan
    from mjnav.sim.odometry import OdometryConfig, OdometryEstimate
    from mjnav.sim.recording import Recorder
    from mjnav.sim.runner import Hook, RunStats, SimRunner
    from mjnav.sim.simulator import DEFAULT_LIDAR, DEFAULT_ODOMETRY, BodyPose, ImuReading, Simulator, WheelStates
    from mjnav.sim.worldgen import write_scene_from_map
    from mjnav.sim.worlds import WorldInfo, available_worlds, resolve_world, world_info


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'mjnav.sim' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))

"""Closed-loop simulation of an ideal unicycle (exact arcs, no MuJoCo) for the tracker tests."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy.spatial import cKDTree

from mjnav.motion import velocity_motion

DT = 0.05  # 20 Hz


class Tracker(Protocol):
    goal_reached: bool

    def compute(self, pose: np.ndarray, speed_mps: float, path: np.ndarray) -> tuple[float, float]: ...


@dataclass
class Run:
    times: np.ndarray  # (K,) s
    poses: np.ndarray  # (K, 3)
    commands: np.ndarray  # (K, 2) v, ω
    cross_track: np.ndarray  # (K,) distance to the dense reference curve, m
    reached: bool
    final_goal_distance: float


def s_curve(n: int = 801, sign: float = 1.0) -> np.ndarray:
    """x = t, y = ±2 sin(t/3), t in [0, 20]."""
    t = np.linspace(0.0, 20.0, n)
    return np.c_[t, sign * 2.0 * np.sin(t / 3.0)]


def start_pose_off_path(offset_m: float = 0.4, sign: float = 1.0) -> np.ndarray:
    """On the start tangent of the S-curve, shifted ``offset_m`` to the right of the path."""
    th = math.atan2(sign * 2.0 / 3.0, 1.0)
    return np.array([offset_m * math.sin(th), -offset_m * math.cos(th), th])


def run(tracker: Tracker, path: np.ndarray, pose: np.ndarray, reference: np.ndarray, max_s: float = 120.0) -> Run:
    tree = cKDTree(reference)
    v = 0.0
    times, poses, cmds = [], [], []
    for k in range(int(max_s / DT)):
        v, w = tracker.compute(pose, v, path)
        times.append(k * DT)
        poses.append(pose)
        cmds.append((v, w))
        if tracker.goal_reached:
            break
        pose = velocity_motion(pose, v, w, DT)
    poses_a = np.array(poses)
    dist, _ = tree.query(poses_a[:, :2])
    return Run(
        np.array(times),
        poses_a,
        np.array(cmds),
        dist,
        tracker.goal_reached,
        float(np.hypot(*(poses_a[-1, :2] - path[-1]))),
    )


def dense_reference(sign: float = 1.0) -> np.ndarray:
    return s_curve(200_001, sign)

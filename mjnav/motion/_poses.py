"""Pose-array helpers shared by the motion models."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mjnav.geometry import Pose2D

FloatArray = NDArray[np.float64]
PoseLike = Pose2D | ArrayLike


def as_poses(pose: PoseLike, name: str = "pose") -> FloatArray:
    """A (3,) or (N, 3) float64 array of (x, y, θ) from a Pose2D or array-like; rejects NaN/inf."""
    if isinstance(pose, Pose2D):
        return pose.as_array()
    arr = np.asarray(pose, dtype=np.float64)
    if arr.shape[-1:] != (3,) or arr.ndim not in (1, 2):
        raise ValueError(f"{name} must be (3,) or (N, 3) (x, y, theta), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} contains non-finite values")
    return arr


def check_alphas(alphas: ArrayLike, count: int) -> FloatArray:
    """Validate ``count`` non-negative finite noise parameters."""
    a = np.asarray(alphas, dtype=np.float64).reshape(-1)
    if a.shape != (count,):
        raise ValueError(f"expected {count} alpha noise parameters, got {a.shape[0]}")
    if not np.isfinite(a).all() or (a < 0.0).any():
        raise ValueError(f"alpha noise parameters must be finite and >= 0, got {a.tolist()}")
    return a

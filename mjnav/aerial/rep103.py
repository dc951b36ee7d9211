"""REP-103 boundary conversions: local ENU / body FLU (ROS, MuJoCo) ↔ local NED / body FRD (the flight software).

``ENU → NED``: ``(n, e, d) = (y, x, -z)``; ``FLU → FRD``: ``(x, -y, -z)``. Both are proper rotations by π
(about (1, 1, 0)/√2 and about x), so each conversion is its own inverse. Quaternions are (w, x, y, z), body → world.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from mjnav.aerial.frames import quat_multiply

__all__ = [
    "enu_to_ned",
    "flu_to_frd",
    "kinematic_accel_ned",
    "ned_to_enu",
    "quat_enu_flu_to_ned_frd",
    "quat_ned_frd_to_enu_flu",
]

_Q_ENU_NED = np.array([0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0])  # rotation by π about (1, 1, 0)/√2
_Q_FLU_FRD = np.array([0.0, 1.0, 0.0, 0.0])  # rotation by π about x


def enu_to_ned(v: Any) -> np.ndarray:
    """(…, 3) ENU vectors (m, m/s, …) as NED: ``(y, x, -z)``."""
    a = np.asarray(v, dtype=np.float64)
    if a.ndim == 1:  # one vector: np.stack's generality costs more than the swap itself
        return np.array((a[1], a[0], -a[2]))
    return np.stack([a[..., 1], a[..., 0], -a[..., 2]], axis=-1)


def ned_to_enu(v: Any) -> np.ndarray:
    """(…, 3) NED vectors as ENU: ``(e, n, -d)`` (the same swap as `enu_to_ned`)."""
    return enu_to_ned(v)


def flu_to_frd(v: Any) -> np.ndarray:
    """(…, 3) body FLU vectors (rad/s, m/s², …) as FRD, ``(x, -y, -z)``; also FRD → FLU."""
    a = np.asarray(v, dtype=np.float64)
    if a.ndim == 1:
        return np.array((a[0], -a[1], -a[2]))
    return np.stack([a[..., 0], -a[..., 1], -a[..., 2]], axis=-1)


def quat_enu_flu_to_ned_frd(q: Any) -> np.ndarray:
    """(4,) attitude quaternion (w, x, y, z), body FLU → ENU, as body FRD → NED (w >= 0)."""
    out = quat_multiply(quat_multiply(_Q_ENU_NED, np.asarray(q, dtype=np.float64)), _Q_FLU_FRD)
    return out if out[0] >= 0.0 else -out


def quat_ned_frd_to_enu_flu(q: Any) -> np.ndarray:
    """(4,) attitude quaternion, body FRD → NED, as body FLU → ENU (w >= 0); inverse of `quat_enu_flu_to_ned_frd`."""
    return quat_enu_flu_to_ned_frd(q)


def kinematic_accel_ned(quat_wxyz: Any, specific_force_flu: Any, gravity_mps2: float) -> np.ndarray:
    """Kinematic accelerations (N, 3) NED m/s² of IMU samples given in REP-103 conventions.

    ``a_ned = swap(R(q) f_flu) + g ẑ``: the specific force (body FLU) rotated into ENU by the attitude (body FLU →
    ENU), converted to NED, with gravity added back (a vehicle at rest reads ``f = [0, 0, +g]`` in FLU). The same
    as rotating the FRD force by the NED/FRD attitude, without converting each quaternion.

    Args:
        quat_wxyz: (N, 4) attitudes (w, x, y, z), body FLU → ENU.
        specific_force_flu: (N, 3) accelerometer readings, body FLU, m/s².
        gravity_mps2: gravity, m/s².
    """
    q = np.ascontiguousarray(quat_wxyz, dtype=np.float64).reshape(-1, 4)
    f = np.ascontiguousarray(specific_force_flu, dtype=np.float64).reshape(-1, 3)
    if len(q) != len(f):
        raise ValueError(f"as many attitudes as specific forces needed, got {len(q)} and {len(f)}")
    return _kinematic_accel_ned(q, f, float(gravity_mps2))


@njit(cache=True)
def _kinematic_accel_ned(q: np.ndarray, f: np.ndarray, g: float) -> np.ndarray:
    out = np.empty((q.shape[0], 3))
    for i in range(q.shape[0]):
        n = math.sqrt(q[i, 0] ** 2 + q[i, 1] ** 2 + q[i, 2] ** 2 + q[i, 3] ** 2)
        w, x, y, z = q[i, 0] / n, q[i, 1] / n, q[i, 2] / n, q[i, 3] / n
        fx, fy, fz = f[i, 0], f[i, 1], f[i, 2]
        e = (1 - 2 * (y * y + z * z)) * fx + 2 * (x * y - w * z) * fy + 2 * (x * z + w * y) * fz
        nn = 2 * (x * y + w * z) * fx + (1 - 2 * (x * x + z * z)) * fy + 2 * (y * z - w * x) * fz
        u = 2 * (x * z - w * y) * fx + 2 * (y * z + w * x) * fy + (1 - 2 * (x * x + y * y)) * fz
        out[i, 0], out[i, 1], out[i, 2] = nn, e, g - u
    return out

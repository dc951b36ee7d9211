"""REP-103 boundary conversions: local ENU / body FLU (ROS, MuJoCo) ↔ local NED / body FRD (the flight software).

``ENU → NED``: ``(n, e, d) = (y, x, -z)``; ``FLU → FRD``: ``(x, -y, -z)``. Both are proper rotations by π
(about (1, 1, 0)/√2 and about x), so each conversion is its own inverse. Quaternions are (w, x, y, z), body → world.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mjnav.aerial.frames import quat_multiply

__all__ = ["enu_to_ned", "flu_to_frd", "ned_to_enu", "quat_enu_flu_to_ned_frd", "quat_ned_frd_to_enu_flu"]

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

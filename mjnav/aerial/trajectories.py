"""Flight plans: a UAV's reference position as a function of time (ENU, metres) — take-off from the pad, the
trajectory, then rest for the landing.

:func:`figure8_plan`, :func:`hover_plan` and :func:`waypoints_plan` build the three of ``mjnav fly``; every segment
is a quintic (zero velocity and acceleration at both ends) or eases in and out with one.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np


def _smoothstep(s: np.ndarray) -> np.ndarray:
    """Quintic 0 → 1 on [0, 1] with zero velocity and acceleration at both ends."""
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10.0 - 15.0 * s + 6.0 * s * s)


@dataclass(frozen=True)
class FlightPlan:
    """The reference of one flight (sim time relative to the flight's start, ENU metres).

    Attributes:
        name: ``figure8``, ``hover`` or ``waypoints``.
        reference: maps times (N,) s → positions (N, 3) m.
        start_s, end_s: the stretch the reference covers (take-off at ``start_s``), s.
        measure_from_s, measure_to_s: the scored stretch (after take-off), s.
    """

    name: str
    reference: Callable[[np.ndarray], np.ndarray]
    start_s: float
    end_s: float
    measure_from_s: float
    measure_to_s: float


def _takeoff(pad: np.ndarray, altitude_m: float, t0: float, climb_s: float) -> Callable[[np.ndarray], np.ndarray]:
    def ref(t: np.ndarray) -> np.ndarray:
        s = _smoothstep((t - t0) / climb_s)
        out = np.repeat(pad[None, :], len(t), axis=0)
        out[:, 2] = pad[2] + s * (altitude_m - pad[2])
        return out

    return ref


def figure8_plan(
    pad: Any, t0: float, periods: int = 3, period_s: float = 8.0, altitude_m: float = 1.5, lead_in_s: float = 2.0
) -> FlightPlan:
    """Take off at ``t0`` (3 s climb, 2 s hover), then ``x = sin(2πτ/T)``, ``y = 0.5 sin(4πτ/T)``, z = 1.5 m,
    centred on the pad. The figure's time τ speeds up smoothly from rest over a ``lead_in_s`` lead-in
    (``dτ/dt`` from 0 to 1, quintic: the formula starts at full speed), then runs ``periods`` full periods, which are
    scored, and comes to rest the same way."""
    p = np.asarray(pad, dtype=np.float64)
    climb = _takeoff(p, altitude_m, t0, 3.0)
    t1 = t0 + 5.0
    t2 = t1 + lead_in_s  # scored from here ...
    t3 = t2 + periods * period_s  # ... to here
    t4 = t3 + lead_in_s

    def warp(u: np.ndarray) -> np.ndarray:  # ∫₀ᵘ smoothstep: 2.5u⁴ - 3u⁵ + u⁶
        u = np.clip(u, 0.0, 1.0)
        return u**4 * (2.5 - 3.0 * u + u * u)

    def ref(t: np.ndarray) -> np.ndarray:
        out = climb(t)
        tau = lead_in_s * warp((t - t1) / lead_in_s) + np.clip(t - t2, 0.0, t3 - t2)
        tau += lead_in_s * (0.5 - warp(1.0 - (t - t3) / lead_in_s)) * (t > t3)
        fly = t > t1
        out[fly, 0] = p[0] + np.sin(2.0 * math.pi * tau[fly] / period_s)
        out[fly, 1] = p[1] + 0.5 * np.sin(4.0 * math.pi * tau[fly] / period_s)
        return out

    return FlightPlan("figure8", ref, t0, t4 + 1.0, t2, t3)


def hover_plan(pad: Any, t0: float, hover_s: float = 10.0, altitude_m: float = 1.5) -> FlightPlan:
    """Take off at ``t0`` (3 s climb) and hover ``hover_s`` at ``altitude_m`` over the pad; the hover after a 2 s
    settling time is scored."""
    p = np.asarray(pad, dtype=np.float64)
    return FlightPlan("hover", _takeoff(p, altitude_m, t0, 3.0), t0, t0 + 5.0 + hover_s, t0 + 5.0, t0 + 5.0 + hover_s)


def waypoints_plan(pad: Any, t0: float, waypoints: Any, speed_mps: float = 1.0, altitude_m: float = 1.5) -> FlightPlan:
    """Take off at ``t0``, then fly through ``waypoints`` (K, 3) ENU m in order, each leg a quintic at an average
    ``speed_mps``, with a 1 s pause at every waypoint; everything after the take-off is scored."""
    p = np.asarray(pad, dtype=np.float64)
    wps = np.asarray(waypoints, dtype=np.float64).reshape(-1, 3)
    if not np.all(np.isfinite(wps)) or len(wps) == 0:
        raise ValueError("waypoints must be a non-empty list of finite [x, y, z] points")
    if not speed_mps > 0.0:
        raise ValueError(f"speed_mps must be > 0, got {speed_mps}")
    climb = _takeoff(p, altitude_m, t0, 3.0)
    t1 = t0 + 5.0
    points = [np.array([p[0], p[1], altitude_m]), *wps]
    legs = []  # (t_start, t_end, from, to)
    t = t1
    for a, b in itertools.pairwise(points):
        dur = max(1.0, 1.875 * float(np.linalg.norm(b - a)) / speed_mps)  # quintic peak speed = 1.875 x average
        legs.append((t, t + dur, a, b))
        t += dur + 1.0

    def ref(ts: np.ndarray) -> np.ndarray:
        out = climb(ts)
        for ta, tb, a, b in legs:
            on = ts >= ta
            out[on] = a + _smoothstep((ts[on] - ta) / (tb - ta))[:, None] * (b - a)
        return out

    return FlightPlan("waypoints", ref, t0, t, t1, t)

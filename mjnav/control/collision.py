"""Last-line collision check on the commanded arc, against the robot's own scan (moving obstacles included).

A command (v, ω) is checked by rolling the robot forward on its arc and the scan's points forward at their own
velocities; the first time the robot's disc (radius + margin, growing with the prediction time for moving points)
reaches a point is the time to collision (TTC).
Static points are checked over a short horizon — the distance the robot needs to stop, not the whole route, so a
path that curves away from a wall is not mistaken for a collision — and moving points over a longer one, so the
robot can wait at the edge of an aisle for a cart to pass, or clear it at full speed rather than stop in its way.

Point velocities come from two consecutive scans expressed in one fixed frame: each current point's
displacement to the nearest previous point, per second. That sees motion along a surface's normal (a face
approaching the robot) and not along it (the aperture problem), which is the part that matters here; speeds below
``moving_speed_mps`` are noise and count as static. Only points that violate the previous scan's free space can
move (:func:`free_space_violations`: the previous beam in their direction passed beyond them): a face that came
closer does, a wall revealed behind a corner as the robot drove on does not; and only returns from surfaces that
face the sensor (:func:`facing_returns`): a wall seen at a grazing angle seems to slide along itself.

:func:`safe_command` picks, among the pursuit command and slower, faster (up to ``max_speed_mps``) or stopped
versions of it on the same curvature, the first that is collision-free, or else the one whose collision is
furthest away (Nav2's collision monitor stops or slows; this also lets the robot escape a crossing obstacle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from mjnav.control._track import check_params

FloatArray = NDArray[np.float64]

#: Slower speeds tried on the command's curvature, as fractions of it (the last one stops).
_FRACTIONS = (0.75, 0.5, 0.25, 0.0)


@dataclass(frozen=True, slots=True)
class CollisionCheckParams:
    """Settings of the collision check.

    Attributes:
        robot_radius_m: radius of the robot's footprint disc, metres, > 0.
        margin_m: extra clearance the check keeps, metres, >= 0.
        static_horizon_s: how far ahead static points are checked, seconds, > 0.
        moving_horizon_s: how far ahead moving points are checked, seconds, >= static_horizon_s.
        step_s: time step of the roll-out, seconds, > 0.
        moving_speed_mps: points moving slower than this are static, m/s, > 0.
        uncertainty_growth_mps: the clearance kept from a moving point grows by this per second of prediction (its
            velocity is a two-scan estimate and obstacles accelerate), m/s, >= 0.
        max_speed_mps: fastest speed an escape may use (forward; backing off uses half of it), m/s, > 0.
        range_m: points further than this from the robot are ignored, metres, > 0.
    """

    robot_radius_m: float = 0.18
    margin_m: float = 0.03
    static_horizon_s: float = 0.6
    moving_horizon_s: float = 4.0
    step_s: float = 0.05
    moving_speed_mps: float = 0.25
    uncertainty_growth_mps: float = 0.1
    max_speed_mps: float = 0.5
    range_m: float = 4.0

    def __post_init__(self) -> None:
        check_params(
            self,
            positive=(
                "robot_radius_m",
                "static_horizon_s",
                "moving_horizon_s",
                "step_s",
                "moving_speed_mps",
                "max_speed_mps",
                "range_m",
            ),
            non_negative=("margin_m", "uncertainty_growth_mps"),
        )
        if self.moving_horizon_s < self.static_horizon_s:
            raise ValueError("CollisionCheckParams.moving_horizon_s must be >= static_horizon_s")


def scan_points(angles_rad: ArrayLike, ranges_m: ArrayLike, range_min_m: float, range_max_m: float) -> FloatArray:
    """(M, 2) sensor-frame points of the valid returns (finite, within [range_min, range_max)), metres."""
    a = np.asarray(angles_rad, dtype=np.float64)
    r = np.asarray(ranges_m, dtype=np.float64)
    ok = np.isfinite(r) & (r >= range_min_m) & (r < range_max_m)
    return np.column_stack((r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])))


def point_velocities(
    points_xy: ArrayLike,
    previous_xy: ArrayLike,
    dt_s: float,
    min_speed_mps: float,
    max_speed_mps: float = 1.5,
    neighbours: int = 5,
    can_move: ArrayLike | None = None,
) -> FloatArray:
    """(M, 2) velocity of each current point: displacement from its nearest previous point per second, as the
    component-wise median over the point and its ``neighbours - 1`` nearest current neighbours.

    Both point sets must be in one fixed frame. The median keeps a surface's common motion and drops lone jumps;
    speeds below ``min_speed_mps`` (noise, motion along a surface) and above ``max_speed_mps`` (a point that
    appeared from behind an edge as the robot moved, not an obstacle that moved) count as static, zero, and so do
    points where ``can_move`` (M,) is False (see :func:`free_space_violations`). With no previous points every
    velocity is zero.
    """
    p = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
    q = np.asarray(previous_xy, dtype=np.float64).reshape(-1, 2)
    if len(p) == 0 or len(q) == 0 or not dt_s > 0:
        return np.zeros_like(p)
    _, idx = cKDTree(q).query(p)
    raw = (p - q[idx]) / dt_s
    k = min(neighbours, len(p))
    if k > 1:
        _, near = cKDTree(p).query(p, k=k)
        raw = np.median(raw[near], axis=1)
    speed = np.hypot(raw[:, 0], raw[:, 1])
    raw[(speed < min_speed_mps) | (speed > max_speed_mps)] = 0.0
    if can_move is not None:
        raw[~np.asarray(can_move, dtype=bool)] = 0.0
    return raw


def facing_returns(points_xy: ArrayLike, max_gap_m: float = 0.3, min_incidence_rad: float = 0.35) -> NDArray[np.bool_]:
    """(M,) True for the returns of a scan whose surface faces the sensor: the beam meets the local surface (the
    line through the neighbouring returns, both within ``max_gap_m``) at more than ``min_incidence_rad``.

    Grazing returns (a wall seen along its length) and isolated or edge returns slide along their surface from one
    scan to the next as the robot moves: their apparent motion is not an obstacle's.

    Args:
        points_xy: (M, 2) the scan's valid returns in the sensor frame, in beam order, metres.
    """
    p = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
    out = np.zeros(len(p), dtype=bool)
    if len(p) < 3:
        return out
    prev, nxt = p[:-2], p[2:]
    mid = p[1:-1]
    tangent = nxt - prev
    gaps_ok = (np.hypot(*(mid - prev).T) <= max_gap_m) & (np.hypot(*(nxt - mid).T) <= max_gap_m)
    cross = np.abs(tangent[:, 0] * mid[:, 1] - tangent[:, 1] * mid[:, 0])
    norms = np.hypot(*tangent.T) * np.hypot(*mid.T)
    with np.errstate(invalid="ignore", divide="ignore"):
        out[1:-1] = gaps_ok & (cross > np.sin(min_incidence_rad) * norms)
    return out


def free_space_violations(
    points_xy: ArrayLike,
    previous_pose: tuple[float, float, float],
    angle_min_rad: float,
    angle_increment_rad: float,
    previous_ranges_m: ArrayLike,
    tolerance_m: float = 0.05,
) -> NDArray[np.bool_]:
    """(M,) True where a point lies in space the previous scan saw free: its beam passed beyond the point.

    Args:
        points_xy: (M, 2) current points in the fixed frame, metres.
        previous_pose: (x, y, θ) of the previous scan's sensor in that frame.
        angle_min_rad, angle_increment_rad: the previous scan's beam angles.
        previous_ranges_m: (N,) its ranges; non-finite ranges (no return) saw free space to the horizon.
        tolerance_m: how much nearer than the previous return a point must be (noise), metres.
    """
    p = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
    r = np.asarray(previous_ranges_m, dtype=np.float64)
    x0, y0, th = previous_pose
    dx, dy = p[:, 0] - x0, p[:, 1] - y0
    rho = np.hypot(dx, dy)
    beam = np.arctan2(dy, dx) - th
    idx = np.rint(np.mod(beam - angle_min_rad, 2.0 * np.pi) / angle_increment_rad).astype(np.int64)
    if len(r) and abs(len(r) * angle_increment_rad - 2.0 * np.pi) < angle_increment_rad:
        idx %= len(r)  # a full circle: the last beam's neighbour is the first
    inside = (idx >= 0) & (idx < len(r))
    seen = np.where(inside, r[np.clip(idx, 0, max(len(r) - 1, 0))], -np.inf) if len(r) else np.full(len(p), -np.inf)
    seen = np.where(np.isfinite(seen) | ~inside, seen, np.inf)
    return np.asarray(seen > rho + tolerance_m)


def _arc(v_mps: float, omega_radps: float, t: FloatArray) -> FloatArray:
    """(K, 2) positions of a robot starting at the origin facing +x, on the arc (v, ω), at times t."""
    if abs(omega_radps) < 1e-9:
        return np.column_stack((v_mps * t, np.zeros_like(t)))
    r = v_mps / omega_radps
    return np.column_stack((r * np.sin(omega_radps * t), r * (1.0 - np.cos(omega_radps * t))))


def _within_range(points_xy: ArrayLike, velocities_mps: ArrayLike, range_m: float) -> tuple[FloatArray, FloatArray]:
    """The (M', 2) points within ``range_m`` of the robot and their velocities."""
    p = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
    u = np.asarray(velocities_mps, dtype=np.float64).reshape(-1, 2)
    near = np.hypot(p[:, 0], p[:, 1]) <= range_m
    return p[near], u[near]


def _squared_distances(p: FloatArray, u: FloatArray, t: FloatArray, robot: FloatArray) -> FloatArray:
    """(M, K) squared distances between points p moving at u and the robot's positions ``robot`` at times t."""
    return (p[:, None, 0] + u[:, None, 0] * t[None, :] - robot[None, :, 0]) ** 2 + (
        p[:, None, 1] + u[:, None, 1] * t[None, :] - robot[None, :, 1]
    ) ** 2


def time_to_collision(
    v_mps: float, omega_radps: float, points_xy: ArrayLike, velocities_mps: ArrayLike, params: CollisionCheckParams
) -> float:
    """Seconds until the robot on the arc (v, ω) first comes within radius + margin of a (moving) point.

    Args:
        v_mps, omega_radps: the command.
        points_xy: (M, 2) points in the robot frame (x forward), metres.
        velocities_mps: (M, 2) their velocities in the same frame, m/s (zero for static points).
        params: radius, margin and horizons.

    Returns:
        The time, seconds (0 when already in contact); ``inf`` when no contact within the horizons.
    """
    p, u = _within_range(points_xy, velocities_mps, params.range_m)
    if len(p) == 0:
        return math.inf
    reach = params.robot_radius_m + params.margin_m
    t = np.arange(0.0, params.moving_horizon_s + 1e-9, params.step_s)
    robot = _arc(v_mps, omega_radps, t)  # (K, 2)
    moving = np.any(u != 0.0, axis=1)
    # Static points only count within the static horizon, moving ones (a disc that grows with the time ahead)
    # within the moving horizon: each set is tested over its own times, (M_set, K_set) distances.
    ks = int(np.searchsorted(t, params.static_horizon_s + 1e-9, side="right"))
    hit = np.zeros(len(t), dtype=bool)
    ps = p[~moving]
    if len(ps) and ks:
        d2 = (ps[:, None, 0] - robot[None, :ks, 0]) ** 2 + (ps[:, None, 1] - robot[None, :ks, 1]) ** 2
        hit[:ks] |= (d2 < reach * reach).any(axis=0)
    pm, um = p[moving], u[moving]
    if len(pm):
        d2 = _squared_distances(pm, um, t, robot)
        hit |= (d2 < (reach + params.uncertainty_growth_mps * t[None, :]) ** 2).any(axis=0)
    k = np.flatnonzero(hit)
    return float(t[k[0]]) if len(k) else math.inf


def safe_command(
    v_mps: float, omega_radps: float, points_xy: ArrayLike, velocities_mps: ArrayLike, params: CollisionCheckParams
) -> tuple[float, float, float]:
    """The command to send instead of (v, ω): the same curvature at the first collision-free speed of v,
    ``max_speed_mps``, 0.75 v, 0.5 v, 0.25 v, 0 and, last, straight back at half ``max_speed_mps`` (out of a
    crossing obstacle's way), else the one whose collision is furthest away. A robot already within radius +
    margin of a point gets the first of those commands that moves without bringing it closer (backing out,
    typically), else a stop.

    Args:
        v_mps, omega_radps: the tracker's command (forward speed >= 0).
        points_xy, velocities_mps: the scan's points and their velocities in the robot frame (see
            :func:`time_to_collision`).
        params: the check's settings.

    Returns:
        (v m/s, ω rad/s, time to collision of the chosen command in s: inf when it is collision-free).
    """
    kappa = omega_radps / v_mps if v_mps > 1e-9 else 0.0
    candidates = [(v_mps, omega_radps)]
    candidates += [(s, kappa * s) for s in (params.max_speed_mps, *(f * v_mps for f in _FRACTIONS))]
    candidates.append((-0.5 * params.max_speed_mps, 0.0))
    best: tuple[float, float, float] | None = None
    for s, w in candidates:
        ttc = time_to_collision(s, w, points_xy, velocities_mps, params)
        if math.isinf(ttc):
            return s, w, ttc
        if best is None or ttc > best[2]:
            best = (s, w, ttc)
    assert best is not None
    if best[2] > 0.0:
        return best
    # Already within radius + margin of a point: every command "collides" at once. Only a command that does not
    # bring the robot any closer over the static horizon may go (the first in the order above: moving away keeps
    # the robot going; standing still never frees it), else it stops — never the original command into the
    # obstacle.
    now = _closest_approach(0.0, 0.0, points_xy, velocities_mps, params)
    for s, w in candidates:
        if (s, w) != (0.0, 0.0) and _closest_approach(s, w, points_xy, velocities_mps, params) >= now - 1e-9:
            return s, w, 0.0
    return 0.0, 0.0, 0.0


def _closest_approach(
    v_mps: float, omega_radps: float, points_xy: ArrayLike, velocities_mps: ArrayLike, params: CollisionCheckParams
) -> float:
    """Smallest distance (m) between the robot centre on the arc (v, ω) and any point within ``range_m`` (moving
    ones at their velocities) over the static horizon; inf without points."""
    p, u = _within_range(points_xy, velocities_mps, params.range_m)
    if len(p) == 0:
        return math.inf
    t = np.arange(0.0, params.static_horizon_s + 1e-9, params.step_s)
    return float(math.sqrt(_squared_distances(p, u, t, _arc(v_mps, omega_radps, t)).min()))

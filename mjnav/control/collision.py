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
from collections.abc import Callable
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
        robot_radius_m: radius of the robot's footprint disc, metres, > 0 (the robot's own: from its description,
            :attr:`mjnav.robot.RobotDescription.radius_m`; no default).
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

    robot_radius_m: float
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


@dataclass(frozen=True, slots=True)
class TrackedScan:
    """A scan's valid returns in a fixed frame, with each return's velocity (see :func:`track_scan`).

    Attributes:
        stamp_s: the scan's time, seconds.
        pose: (x, y, θ) of the sensor in the fixed frame.
        angle_min_rad, angle_increment_rad: the scan's beam angles.
        ranges_m: (N,) its ranges, metres.
        beams: (M,) index of the beam each return came from.
        points: (M, 2) the returns in the fixed frame, metres.
        velocities: (M, 2) their velocities in the fixed frame, m/s (zero: static).
        unseen_s: (M,) for a moving return, how long its motion has gone without being seen (carried over from
            earlier scans), seconds.
    """

    stamp_s: float
    pose: tuple[float, float, float]
    angle_min_rad: float
    angle_increment_rad: float
    ranges_m: FloatArray
    beams: NDArray[np.int64]
    points: FloatArray
    velocities: FloatArray
    unseen_s: FloatArray

    def moving(self) -> NDArray[np.bool_]:
        """(M,) True for the returns of a moving obstacle."""
        return np.asarray(np.any(self.velocities != 0.0, axis=1))


@dataclass(frozen=True, slots=True)
class TrackingParams:
    """Settings of :func:`track_scan`.

    Attributes:
        moving_speed_mps: slower returns and objects count as static, m/s.
        max_gap_s: the longest time between two scans compared, seconds.
        track_tolerance_m: a return this close to where a moving return of the previous scan has moved to
            continues it, metres.
        max_unseen_s: an object whose motion has not been seen for this long stops, seconds (a cart that parks
            where only its side is in view must not move for ever).
        object_gap_m: consecutive returns this close (or within three beam spacings at their range) belong to one
            object, metres.
        max_object_m: objects wider than this (walls) do not move as a whole, metres.
        min_moving_share: an object moves when this share of its returns (and at least 3) move or continue a
            moving return.
        min_constraint_share: a direction of motion counts as seen when the returns' surface normals constrain it
            with at least this share of their weight (the rest of the velocity is carried over).
        surface_radius_m: a return's surface normal is the line fitted to the previous scan's returns within this
            radius of it (or within two and a half beam spacings at its range, if more), metres.
    """

    moving_speed_mps: float = 0.25
    max_gap_s: float = 0.5
    track_tolerance_m: float = 0.1
    max_unseen_s: float = 2.0
    object_gap_m: float = 0.2
    max_object_m: float = 2.0
    min_moving_share: float = 0.2
    min_constraint_share: float = 0.3
    surface_radius_m: float = 0.1

    def __post_init__(self) -> None:
        check_params(
            self,
            positive=(
                "moving_speed_mps",
                "max_gap_s",
                "track_tolerance_m",
                "max_unseen_s",
                "object_gap_m",
                "surface_radius_m",
            ),
            non_negative=("max_object_m", "min_moving_share", "min_constraint_share"),
        )


def track_scan(
    stamp_s: float,
    sensor_pose: tuple[float, float, float],
    angle_min_rad: float,
    angle_increment_rad: float,
    ranges_m: ArrayLike,
    range_min_m: float,
    range_max_m: float,
    previous: TrackedScan | None,
    params: TrackingParams,
    static: Callable[[FloatArray], NDArray[np.bool_]] | None = None,
) -> TrackedScan:
    """A new scan's returns in the fixed frame and their velocities against the previous scan.

    1. A return may move only where it lies in the previous scan's free space (:func:`free_space_violations`),
       on a surface facing the sensor (:func:`facing_returns`) and, with ``static``, not where that says it is
       static (e.g. on a mapped wall); its velocity is then :func:`point_velocities`'.
    2. Two scans see only the motion along a surface's normal (the aperture problem): a cart crossing the
       robot's view shows its leading face moving, while its side slides along itself and its back face recedes
       into space the previous scan did not see. So a return close to where a moving return of the previous scan
       has moved to continues it, and the returns are grouped into objects (:func:`_move_objects`): a small
       object moves as a whole, at the velocity its returns' normal flow and the carried motion give.
    3. An object whose motion has gone unseen for ``max_unseen_s`` stops.

    Without a previous scan, or one older than ``max_gap_s`` (or not older at all), every return is static.

    Args:
        stamp_s: the scan's time, seconds.
        sensor_pose: (x, y, θ) of the sensor in the fixed frame at that time.
        angle_min_rad, angle_increment_rad, ranges_m, range_min_m, range_max_m: the scan.
        previous: the previous scan as this function returned it, or None.
        params: the tracking's settings.
        static: (M, 2) fixed-frame points → (M,) True where a point is known to be static.
    """
    r = np.asarray(ranges_m, dtype=np.float64)
    angles = angle_min_rad + angle_increment_rad * np.arange(len(r))
    ok = np.isfinite(r) & (r >= range_min_m) & (r < range_max_m)
    beams = np.flatnonzero(ok)
    local = np.column_stack((r[ok] * np.cos(angles[ok]), r[ok] * np.sin(angles[ok])))
    x, y, th = sensor_pose
    c, s = math.cos(th), math.sin(th)
    points = local @ np.array([[c, s], [-s, c]]) + np.array([x, y])
    velocities = np.zeros_like(points)
    unseen = np.zeros(len(points))
    dt = stamp_s - previous.stamp_s if previous is not None else 0.0
    if previous is not None and 0.0 < dt <= params.max_gap_s and len(points):
        can_move = free_space_violations(
            points, previous.pose, previous.angle_min_rad, previous.angle_increment_rad, previous.ranges_m
        )
        can_move &= facing_returns(local)
        fixed = static(points) if static is not None else np.zeros(len(points), dtype=bool)
        can_move &= ~fixed
        if can_move.any():  # most scans of a static scene: nothing to measure
            velocities = point_velocities(points, previous.points, dt, params.moving_speed_mps, can_move=can_move)
        objects = _objects(points, r[ok], angle_increment_rad, beams, len(r), params)
        carried = _Carried(np.zeros_like(velocities), np.zeros(len(points)), np.zeros((0, 2)), np.zeros(0, int), dt)
        was_moving = previous.moving()
        if was_moving.any():
            predicted = previous.points[was_moving] + dt * previous.velocities[was_moving]
            distance, nearest = cKDTree(predicted).query(points)
            near = (distance <= params.track_tolerance_m) & ~fixed
            carried.velocities[near] = previous.velocities[was_moving][nearest[near]]
            carried.unseen_s[near] = previous.unseen_s[was_moving][nearest[near]] + dt
            # And the other way round: the previous moving returns whose motion lands on a return of this scan,
            # with that return's object.
            distance, nearest = cKDTree(points).query(predicted)
            landed = distance <= params.track_tolerance_m
            carried = _Carried(
                carried.velocities, carried.unseen_s, previous.points[was_moving][landed], objects[nearest[landed]], dt
            )
        unseen = _move_objects(objects, velocities, carried, previous, fixed, points, params)
    return TrackedScan(
        stamp_s, (x, y, th), float(angle_min_rad), float(angle_increment_rad), r, beams, points, velocities, unseen
    )


def _objects(
    points: FloatArray,
    ranges: FloatArray,
    angle_increment: float,
    beams: NDArray[np.int64],
    n_beams: int,
    params: TrackingParams,
) -> NDArray[np.int64]:
    """(M,) object label of each return: consecutive returns of neighbouring beams closer than ``object_gap_m``
    or three beam spacings at their range (a full circle's last object continues into its first)."""
    spacing = 3.0 * abs(angle_increment) * ranges
    step = np.hypot(*np.diff(points, axis=0).T)
    adjacent = (step <= np.maximum(params.object_gap_m, np.maximum(spacing[:-1], spacing[1:]))) & (np.diff(beams) == 1)
    label = np.concatenate(([0], np.cumsum(~adjacent)))
    full_circle = abs(n_beams * angle_increment - 2.0 * math.pi) < abs(angle_increment)
    if (
        full_circle
        and label[-1] > 0
        and beams[0] == 0
        and beams[-1] == n_beams - 1
        and math.hypot(*(points[0] - points[-1])) <= max(params.object_gap_m, spacing[0], spacing[-1])
    ):
        label[label == label[-1]] = 0
    return np.asarray(label, dtype=np.int64)


def _surface_normals(
    points: FloatArray, sensor_xy: tuple[float, float], angle_increment_rad: float, min_radius_m: float
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """(M, 2) unit normal of the surface through each of a scan's points, and (M,) whether there is one.

    The surface is the least-squares line through the points around it (within ``min_radius_m``, or two and a
    half beam spacings at its range if more, and at least the returns next to it in the scan if they are less
    than 0.5 m away): its normal is the direction of least spread, and it is a surface
    when at least three points spread along a line (across it at most a third of along it, in standard
    deviation). A tangent through the two neighbouring returns alone is noise where they are about as far apart
    as the range noise (1 cm apart at 0.55 m for a 1° lidar with 1 cm noise): a face sliding along itself close
    to the robot then seems to face every way, and its zero normal flow drowns the real motion of the faces that
    show it.

    Args:
        points: (M, 2) the scan's returns in the fixed frame, metres.
        sensor_xy: the scan's sensor position in that frame, metres.
        angle_increment_rad: the scan's beam spacing.
        min_radius_m: the smallest neighbourhood radius, metres.
    """
    ranges = np.hypot(points[:, 0] - sensor_xy[0], points[:, 1] - sensor_xy[1])
    radius = np.maximum(min_radius_m, 2.5 * abs(angle_increment_rad) * ranges)
    neighbours = cKDTree(points).query_ball_point(points, radius)
    counts = np.array([len(n) for n in neighbours])
    j = np.concatenate(neighbours).astype(np.int64)  # each point is its own neighbour
    i = np.repeat(np.arange(len(points)), counts)
    # Sparse returns (far away, or on a surface seen at a slant) also take the returns next to them in the scan,
    # up to 0.5 m away, when the radius left them out.
    k = np.arange(len(points) - 1)
    step = np.hypot(*np.diff(points, axis=0).T)
    for a, b in ((k, k + 1), (k + 1, k)):
        extra = (step > radius[a]) & (step < 0.5)
        i, j = np.concatenate((i, a[extra])), np.concatenate((j, b[extra]))
        counts = counts + np.bincount(a[extra], minlength=len(points))
    n = np.maximum(counts, 1).astype(np.float64)
    px, py = points[j, 0], points[j, 1]
    mx, my = np.bincount(i, px, len(points)) / n, np.bincount(i, py, len(points)) / n
    dx, dy = px - mx[i], py - my[i]
    cxx, cxy, cyy = (np.bincount(i, w, len(points)) / n for w in (dx * dx, dx * dy, dy * dy))
    heading = 0.5 * np.arctan2(2.0 * cxy, cxx - cyy)  # direction of most spread
    normals = np.column_stack((-np.sin(heading), np.cos(heading)))
    half_trace = 0.5 * (cxx + cyy)
    root = np.sqrt(np.maximum(half_trace**2 - (cxx * cyy - cxy * cxy), 0.0))
    is_surface = (counts >= 3) & (half_trace - root <= (half_trace + root) / 9.0)
    normals[~is_surface] = 0.0
    return normals, is_surface


def _normal_flow(points: FloatArray, previous: FloatArray, normals: FloatArray, dt_s: float) -> FloatArray:
    """(M, 3) rows (n_x, n_y, d) per point: the previous scan's surface normal at the nearest previous point
    (``normals``, (P, 2), zero where there is no surface: :func:`_surface_normals`) and the point's displacement
    along it per second (n·v = d is all two scans tell of its velocity); zero rows where the previous scan has
    no surface there or no point within 0.3 m."""
    out = np.zeros((len(points), 3))
    if len(previous) == 0 or len(points) == 0:
        return out
    distance, j = cKDTree(previous).query(points)
    n = np.where((distance < 0.3)[:, None], normals[j], 0.0)
    out[:, :2] = n
    out[:, 2] = np.sum((points - previous[j]) * n, axis=1) / dt_s
    return out


def _object_velocity(
    flow: FloatArray, prior: FloatArray, min_share: float
) -> tuple[FloatArray, float, FloatArray | None]:
    """An object's velocity from its returns' normal flow rows (n_x, n_y, d), and the speed seen.

    Least squares of n·v = d in the directions the normals constrain (an eigenvalue of Σ n nᵀ of at least
    ``min_share`` of the rows: the side of a cart sliding along itself says its normal component is 0), and
    ``prior`` (the velocity the object had, or zero) in the direction they leave open (a single face's
    tangential motion, which noisy normals would otherwise pull towards zero). Also returns the speed seen (of
    the constrained part alone) and the open direction (a unit vector; None when the normals constrain both).
    """
    n, d = flow[:, :2], flow[:, 2]
    values, vectors = np.linalg.eigh(n.T @ n)
    rhs = vectors.T @ (n.T @ d)
    strong = values >= max(min_share * len(flow), 1e-9)
    seen = np.where(strong, rhs / np.where(strong, values, 1.0), 0.0)
    coords = np.where(strong, seen, vectors.T @ prior)
    open_direction = None if strong.all() else np.asarray(vectors[:, 0])  # eigh sorts ascending: weakest first
    return np.asarray(vectors @ coords), float(np.hypot(*seen)), open_direction


@dataclass(frozen=True, slots=True)
class _Carried:
    """What a scan carries over from the previous scan's moving returns: per return ((M, …), zero where none)
    the velocity and the time its motion has gone unseen (plus ``dt_s``); and the previous moving returns that
    land on one of this scan's returns, (P, 2), with that return's object label, (P,)."""

    velocities: FloatArray
    unseen_s: FloatArray
    origins: FloatArray
    origin_objects: NDArray[np.int64]
    dt_s: float


def _slid_along(points: FloatArray, origins: FloatArray, direction: FloatArray, expected_m: float) -> bool | None:
    """Whether a face seen moving along itself still does: True when one of its visible ends (``points`` now,
    ``origins`` in the previous scan) moved at least half the ``expected_m`` shift along ``direction``, False
    when neither moved a quarter of it (it stopped), None in between or without origins."""
    if len(origins) == 0:
        return None
    now, before = points @ direction, origins @ direction
    shifts = np.array([now.min() - before.min(), now.max() - before.max()]) * math.copysign(1.0, expected_m)
    if shifts.max() >= 0.5 * abs(expected_m):
        return True
    if shifts.max() < 0.25 * abs(expected_m):
        return False
    return None


def _move_objects(
    label: NDArray[np.int64],
    velocities: FloatArray,
    carried: _Carried,
    previous: TrackedScan,
    fixed: NDArray[np.bool_],
    points: FloatArray,
    params: TrackingParams,
) -> FloatArray:
    """Objects no wider than ``max_object_m`` move as a whole when at least 3 and ``min_moving_share`` of their
    returns move (``velocities``) or continue a previous moving return, or when all of an object's one or two
    returns continue one (a face seen edge-on breaks into such fragments), else not at all; at the velocity
    :func:`_object_velocity` fits to its returns' :func:`_normal_flow`, while it is at least
    ``moving_speed_mps``. Motion the normals leave open (a side sliding along itself) is carried over while the
    face's ends still slide (:func:`_slid_along`), and for at most ``max_unseen_s`` when they cannot tell.
    Larger objects (walls) keep their returns' own velocities: a wall sliding along itself fits any carried
    velocity. Updates ``velocities`` in place; returns the (M,) unseen times."""
    unseen = np.zeros(len(points))
    own = np.any(velocities != 0.0, axis=1)
    continues = np.any(carried.velocities != 0.0, axis=1)
    normals: FloatArray | None = None
    for k in np.unique(label[own | continues]):  # an object without either stays static
        members = label == k
        extent = points[members].max(axis=0) - points[members].min(axis=0)
        if math.hypot(*extent) > params.max_object_m:
            continue
        size = int(members.sum())
        count = int((own | continues)[members].sum())
        fragment = size < 3 and bool(continues[members].all())
        velocities[members] = 0.0
        if not ((count >= 3 and count >= params.min_moving_share * size) or fragment):
            continue
        linked = members & continues
        prior = np.median(carried.velocities[linked], axis=0) if linked.any() else np.zeros(2)
        if normals is None:  # the previous scan's surfaces, once per scan and only when an object may move
            normals, _ = _surface_normals(
                previous.points, previous.pose[:2], previous.angle_increment_rad, params.surface_radius_m
            )
        flow = _normal_flow(points[members], previous.points, normals, carried.dt_s)
        velocity, seen_speed, open_direction = _object_velocity(flow, prior, params.min_constraint_share)
        age = 0.0
        if int(own[members].sum()) < 3 and seen_speed < params.moving_speed_mps and linked.any():
            slid = None
            if open_direction is not None:
                expected = float(prior @ open_direction) * carried.dt_s
                origins = carried.origins[carried.origin_objects == k]
                slid = _slid_along(points[members], origins, open_direction, expected)
            if slid is False:
                continue
            age = 0.0 if slid else float(np.max(carried.unseen_s[linked]))
        if age > params.max_unseen_s or math.hypot(*velocity) < params.moving_speed_mps:
            continue
        velocities[members & ~fixed] = velocity
        unseen[members & ~fixed] = age
    return unseen


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

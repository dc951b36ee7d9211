"""Collision monitor: stop, slow-down and approach zones under every velocity command, on the raw scan.

Nav2's collision_monitor, as a pure function of the newest scan and the command about to be applied. Zones are
convex polygons in the base frame that move with the robot (:func:`default_zones` grows the robot's footprint by a
margin for each); a zone with a lead (:attr:`Zone.lead_m`) reaches that much further in the direction of travel
while the command translates (ahead, or behind when reversing), as a safety scanner's speed-switched fields. Each
tick :meth:`CollisionMonitor.check` takes the scan's points (base frame), optionally their velocities (below), and
the command (v, ω) and returns the command to apply, scaled by one factor s in [0, 1] (same curvature; a standing
command passes):

* **stop** — at least ``min_points`` points inside the zone: s = 0, unless the command moves out (below).
* **slowdown** — at least ``min_points`` points inside: s = ``slowdown_ratio`` (Nav2's rule as it is: slowing is
  not a bound, and held steady it does not flicker on lidar noise as a "moving in" test would). Given a lead, the
  zone is a box ahead in the direction of travel, so what the robot drives away from or beside does not slow it.
* **approach** — the zone (the footprint with a margin) is rolled forward along the command's arc (a pure spin
  turns it in place, v < 0 backs it up) in steps of ``simulation_step_s``, up to ``time_before_collision_s`` = T.
  If step k is the first at which ``min_points`` points are inside, the time to collision is t = (k − 1)·dt, the
  last collision-free step (Nav2's), and s = t / T: v' = v·t/T keeps the collision at least T away, and a command
  whose first step already collides stops. Between steps the roll-out is sampled finely enough (no zone vertex moves
  more than 4 cm from one sample to the next) that a corner sweeping past a point in a fast turn is not missed.

The most restrictive zone wins (smallest s; on a tie stop, then approach, then slowdown, then zone order), and the
result names it (:class:`MonitorResult`).

**Moving out is always allowed.** A stop or approach zone that already holds ``min_points`` points limits only a
command that takes them deeper: its depth D — how far the ``min_points``-th deepest point lies inside the polygon,
metres — must not grow by more than ``escape_tolerance_m`` (stop: over the first step; approach: at any step of the
roll-out, which then ends there). So a robot stopped against a wall backs off, turns away or drives along it, while
any command further in is held: the robot gets no closer than it already is. The tolerance covers the facets of a
polygonal disc turning in place; a command so slow that its steps take the points deeper by less passes, and inside
the approach zone that creep stays under tolerance / T per second (2 mm/s by default). On a noisy scan a command
along a wall inside the zone is held now and then (a new return a little deeper than the deepest so far).

**Moving points.** Points given a velocity u (over the ground, in the base frame's axes, e.g. from two scans:
:func:`mjnav.control.collision.track_scan`; zero: static) are checked apart from the static ones (each set counts
its own ``min_points``) by the stop and approach zones; slowdown counts them where they are. The approach zone's
roll-out moves each by u·t at step time t, up to ``moving_horizon_s`` (longer than T: a cart that would cross the
robot's way must be seen before the robot enters its lane), the zone grown against them by
``uncertainty_growth_mps`` per second ahead. Where it meets them, slowing alone does not help: once the robot is in
a crossing cart's lane the collision comes when the cart does, however slowly the robot moves. So t is the time to
the first pose on the arc that the robot could not hold: a moving point would enter its zone there (held from when
the robot gets there; on the point's straight track, the zone grown as on the roll-out) within the horizon, and,
where one would enter the zone of the robot standing where it is (exactly: without the growth, nor the lead, so a
robot held at a lane's edge is not in the lane), more than one step sooner than there (both zones grown). Any one
point's track counts (the contact took ``min_points``): a cart's lane starts at its first return. Without such a
pose the moving points do not limit the command. The robot approaches a crossing cart's lane as it would a wall,
waits at its edge, and drives on once the roll-out is clear (the cart has passed, or is far enough that the command
crosses ahead of it); in a cart's lane it drives on out of it (standing there is no better); it may back away from
a cart coming at it, not drive towards it.

Moving points already inside a stop or approach zone: the command may not take them deeper than the deeper of now
and where they get with the robot standing (by more than ``escape_tolerance_m``; the stop zone over its first step,
the approach zone over its roll-out), so it may back away from a cart pushing in or follow one that draws away.
Moving points never relax the static rules: a command that takes static points deeper is held whatever moves
(escaping a cart does not drive the robot into a wall). Nothing the monitor does to the command keeps a moving
obstacle from running into a robot that cannot get out of its way.

Every depth is measured in the zone polygon, so user-drawn zones (a box ahead) follow the same rules. Non-finite
points (no return) are ignored. Points are taken as they are: a caller whose scan is older than the command should
move it to the command's time (odometry since the scan, and moving points by u·age), or count its age in the margins
(see :class:`CollisionMonitorParams`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import ConvexHull

from mjnav.control._track import check_params
from mjnav.control.collision import _arc
from mjnav.control.errors import MonitorInputError

FloatArray = NDArray[np.float64]

#: Between two simulation steps the roll-out is sampled so that no zone vertex moves more than this, metres (twice
#: the default approach margin: the sampled approach zones then cover the footprint's swept area).
_SWEEP_STEP_M = 0.04
#: Largest angle one facet of a grown corner spans in :func:`offset_polygon`, radians (32 facets per turn, as the
#: robot description's round outlines).
_ARC_STEP_RAD = 2.0 * math.pi / 32


class MonitorAction(StrEnum):
    """What a zone does (and what limited a command: :attr:`MonitorResult.action`)."""

    NONE = "none"
    STOP = "stop"
    SLOWDOWN = "slowdown"
    APPROACH = "approach"


#: Tie-break among zones that scale a command equally: the more severe action names the result.
_SEVERITY = {MonitorAction.STOP: 0, MonitorAction.APPROACH: 1, MonitorAction.SLOWDOWN: 2}


def convex_polygon(polygon_m: ArrayLike, what: str = "polygon") -> FloatArray:
    """The polygon as a read-only (K, 2) float64 array, checked: K >= 3 finite vertices, no repeated consecutive
    vertex, convex and counter-clockwise, turning once (collinear vertices are allowed).

    Raises:
        MonitorInputError: what is wrong, naming ``what``.
    """
    try:
        p = np.array(polygon_m, dtype=np.float64)
    except (TypeError, ValueError):
        raise MonitorInputError(f"{what} must be a (K, 2) array of numbers") from None
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 3:
        raise MonitorInputError(f"{what} must be a (K, 2) array with K >= 3, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise MonitorInputError(f"{what} has non-finite vertices")
    e = np.roll(p, -1, axis=0) - p
    length = np.hypot(e[:, 0], e[:, 1])
    if np.any(length <= 1e-12):
        raise MonitorInputError(f"{what} repeats a vertex")
    nxt = np.roll(e, -1, axis=0)
    cross = e[:, 0] * nxt[:, 1] - e[:, 1] * nxt[:, 0]
    turns = np.arctan2(cross, np.einsum("ij,ij->i", e, nxt))
    if np.any(cross < -1e-12 * length * np.roll(length, -1)) or not math.isclose(
        float(turns.sum()), 2.0 * math.pi, abs_tol=1e-6
    ):
        raise MonitorInputError(f"{what} must be convex and counter-clockwise")
    p.flags.writeable = False
    return p


def offset_polygon(polygon_m: ArrayLike, margin_m: float) -> FloatArray:
    """A convex polygon grown outward by ``margin_m``: every point within ``margin_m`` of it lies inside.

    Edges move out along their normals; each corner becomes an arc of facets no wider than 2π/32, circumscribed
    (the facets touch the arc), so the result exceeds the exact offset by at most 0.5 % of the margin. A corner of a
    32-gon (the robot description's round outlines) gets one facet: a disc's zone is a larger 32-gon.

    Args:
        polygon_m: (K, 2) convex counter-clockwise polygon, metres.
        margin_m: how far to grow it, metres, >= 0 (0: the polygon itself).

    Returns:
        (M, 2) convex counter-clockwise polygon, metres.

    Raises:
        MonitorInputError: the polygon is not convex and counter-clockwise.
        ValueError: the margin is negative or not finite.
    """
    p = convex_polygon(polygon_m)
    if not (math.isfinite(margin_m) and margin_m >= 0.0):
        raise ValueError(f"offset_polygon: margin_m must be finite and >= 0, got {margin_m}")
    if margin_m == 0.0:
        return p
    e = np.roll(p, -1, axis=0) - p
    normal = np.arctan2(-e[:, 0], e[:, 1])  # outward normal of edge i (from vertex i to i + 1), CCW polygon
    out: list[FloatArray] = []
    for i in range(len(p)):
        start = normal[i - 1]  # the edge into vertex i
        turn = max(0.0, (normal[i] - start + math.pi) % (2.0 * math.pi) - math.pi)  # a collinear vertex: 0
        facets = max(1, math.ceil(turn / _ARC_STEP_RAD - 1e-9))
        half = 0.5 * turn / facets
        angles = start + (2 * np.arange(facets) + 1) * half
        out.append(p[i] + (margin_m / math.cos(half)) * np.column_stack((np.cos(angles), np.sin(angles))))
    grown = np.vstack(out)
    grown.flags.writeable = False
    return grown


@dataclass(frozen=True, slots=True)
class _Shape:
    """A convex polygon as half-planes: inward unit normals (E, 2), offsets (E,) (inside: n·p >= offset), the
    farthest vertex's distance from the origin, and how far a vertex moves per metre the edges move out (1 /
    cos of half the largest exterior angle: the polygon grown by δ lies within radius_m + miter·δ)."""

    normals: FloatArray
    offsets: FloatArray
    radius_m: float
    miter: float

    @staticmethod
    def of(polygon: FloatArray) -> _Shape:
        """The half-planes of a (K, 2) convex counter-clockwise polygon."""
        e = np.roll(polygon, -1, axis=0) - polygon
        n = np.column_stack((-e[:, 1], e[:, 0])) / np.hypot(e[:, 0], e[:, 1])[:, None]
        turn = float(np.clip(np.einsum("ij,ij->i", n, np.roll(n, 1, axis=0)), -1.0, 1.0).min())
        return _Shape(
            n,
            np.einsum("ij,ij->i", n, polygon),
            float(np.hypot(polygon[:, 0], polygon[:, 1]).max()),
            math.sqrt(2.0 / (1.0 + turn)),
        )

    def nth_depth(self, points: FloatArray, poses: FloatArray, n: int, grown_m: FloatArray | None = None) -> FloatArray:
        """(S,) the n-th largest depth of ``points`` in the shape placed at each of the (S, 3) poses (x, y, θ in the
        current base frame), metres; -inf with fewer than n points.

        Args:
            points: (N, 2), or (S, N, 2) where they are at each pose's time (moving points).
            poses: (S, 3) poses.
            n: which depth.
            grown_m: (S,) the shape at each pose grown by this (every edge moved out: each depth gains it), metres;
                points beyond the grown shape's reach count as -inf (their depth is negative: only the sign of a
                negative n-th depth is meant).
        """
        count = points.shape[-2]
        if count < n:
            return np.full(len(poses), -math.inf)
        c, s = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])  # (S, 1)
        dx, dy = points[..., 0] - poses[:, 0:1], points[..., 1] - poses[:, 1:2]  # (S, N)
        if grown_m is None:
            local = np.stack((c * dx + s * dy, c * dy - s * dx), axis=-1)  # (S, N, 2): in the shape's frame
            depth = (local @ self.normals.T - self.offsets).min(axis=2)  # (S, N)
        else:
            reach = self.radius_m + self.miter * grown_m[:, None]
            near = dx * dx + dy * dy <= reach * reach  # (S, N): only these can be inside the grown shape
            depth = np.full(dx.shape, -math.inf)
            c, s, g = (np.broadcast_to(a, dx.shape)[near] for a in (c, s, grown_m[:, None]))
            dx, dy = dx[near], dy[near]
            local = np.column_stack((c * dx + s * dy, c * dy - s * dx))
            depth[near] = (local @ self.normals.T - self.offsets).min(axis=1) + g
        k = count - n
        return np.asarray(np.partition(depth, k, axis=1)[:, k])

    def entry_times(
        self,
        points: FloatArray,
        velocities: FloatArray,
        poses: FloatArray,
        t: FloatArray,
        horizon_s: float,
        n: int,
        growth_mps: float = 0.0,
    ) -> FloatArray:
        """(S,) when the n-th of the points would enter the shape placed at pose s (x, y, θ) and held there from
        time t_s, each moving on its straight track from ``points`` (N, 2) at time 0 at its velocity (N, 2), m/s:
        the n-th earliest time a point enters it in [t_s, ``horizon_s``], seconds from now; inf when fewer enter.
        The shape grows by ``growth_mps`` per second from time 0 (every depth gains growth·time).

        Exact (Cyrus-Beck clipping of each track against the half-planes), not sampled.
        """
        if len(points) < n:
            return np.full(len(poses), math.inf)
        span = (horizon_s - t)[:, None]  # (S, 1) the window's length
        px = points[:, 0] + velocities[:, 0] * t[:, None] - poses[:, 0:1]  # (S, N): where they are at t_s
        py = points[:, 1] + velocities[:, 1] * t[:, None] - poses[:, 1:2]
        ux, uy = np.broadcast_to(velocities[:, 0], px.shape), np.broadcast_to(velocities[:, 1], px.shape)
        # Only tracks that come within the shape's reach of the pose in the window can enter it.
        closest = np.clip(-(px * ux + py * uy) / np.maximum(ux * ux + uy * uy, 1e-300), 0.0, span)
        reach = self.radius_m + self.miter * growth_mps * horizon_s
        near = (px + ux * closest) ** 2 + (py + uy * closest) ** 2 <= reach * reach
        row = np.nonzero(near)[0]
        c, s = np.cos(poses[row, 2:3]), np.sin(poses[row, 2:3])  # (K, 1)
        px, py, ux, uy = px[near][:, None], py[near][:, None], ux[near][:, None], uy[near][:, None]
        alpha = (c * px + s * py) * self.normals[:, 0] + (c * py - s * px) * self.normals[:, 1] - self.offsets
        alpha += growth_mps * t[row, None]  # (K, E) the depths behind each edge at t_s, m
        beta = (c * ux + s * uy) * self.normals[:, 0] + (c * uy - s * ux) * self.normals[:, 1] + growth_mps  # m/s
        with np.errstate(divide="ignore", invalid="ignore"):
            cross = -alpha / beta  # seconds after t_s at which the point crosses each edge's line
        enter = np.maximum(np.where(beta > 0.0, cross, -math.inf).max(axis=1), 0.0)
        leave = np.minimum(np.where(beta < 0.0, cross, math.inf).min(axis=1), span[row, 0])
        inside = (enter <= leave) & ~((beta == 0.0) & (alpha < 0.0)).any(axis=1)
        times = np.full(px.shape[0], math.inf)
        times[inside] = enter[inside] + t[row[inside]]
        table = np.full((len(poses), len(points)), math.inf)
        table[near] = times
        return np.asarray(np.partition(table, n - 1, axis=1)[:, n - 1])


@dataclass(frozen=True, eq=False)
class Zone:
    """One zone of the monitor: a convex polygon in the base frame that moves with the robot.

    Attributes:
        name: the zone's name, reported when it limits a command (e.g. ``stop``).
        action: :attr:`MonitorAction.STOP`, ``SLOWDOWN`` or ``APPROACH``.
        polygon_m: (K, 2) convex counter-clockwise polygon, base frame, metres (stored read-only).
        min_points: the zone acts when at least this many points are inside it, >= 1.
        slowdown_ratio: what a slowdown zone scales the command by, in [0, 1].
        time_before_collision_s: an approach zone keeps the collision at least this far ahead (T), seconds, > 0;
            it is also the roll-out's horizon.
        lead_m: while the command translates, the zone reaches this much further in the direction of travel
            (stretched ahead for v > 0, behind for v < 0; a pure spin uses the polygon as it is), metres, >= 0.
    """

    name: str
    action: MonitorAction
    polygon_m: FloatArray
    min_points: int = 1
    slowdown_ratio: float = 0.5
    time_before_collision_s: float = 1.0
    lead_m: float = 0.0
    _shapes: dict[int, _Shape] = field(init=False, repr=False)
    _polygons: dict[int, FloatArray] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise MonitorInputError("Zone.name must be a non-empty string")
        if self.action not in _SEVERITY:
            raise MonitorInputError(f"Zone {self.name!r}: action must be stop, slowdown or approach, got {self.action}")
        if isinstance(self.min_points, bool) or not isinstance(self.min_points, int) or self.min_points < 1:
            raise MonitorInputError(f"Zone {self.name!r}: min_points must be an integer >= 1, got {self.min_points}")
        check_params(self, positive=("time_before_collision_s",), non_negative=("slowdown_ratio", "lead_m"))
        if self.slowdown_ratio > 1.0:
            raise MonitorInputError(f"Zone {self.name!r}: slowdown_ratio must be in [0, 1], got {self.slowdown_ratio}")
        p = convex_polygon(self.polygon_m, f"Zone {self.name!r} polygon")
        polygons = {0: p}
        for sign in (-1, 1):
            stretched = p
            if self.lead_m > 0.0:
                both = np.vstack((p, p + np.array([sign * self.lead_m, 0.0])))
                stretched = both[ConvexHull(both).vertices]  # counter-clockwise in 2-D
                stretched.flags.writeable = False
            polygons[sign] = stretched
        object.__setattr__(self, "action", MonitorAction(self.action))
        object.__setattr__(self, "polygon_m", p)
        object.__setattr__(self, "_polygons", polygons)
        object.__setattr__(self, "_shapes", {k: _Shape.of(q) for k, q in polygons.items()})

    def polygon_for(self, v_mps: float = 0.0) -> FloatArray:
        """(M, 2) the zone's polygon for a command of forward speed ``v_mps`` (stretched by ``lead_m`` along the
        direction of travel when it is not 0), base frame, metres."""
        return self._polygons[_sign(v_mps)]

    def depth_m(self, points_xy: ArrayLike, v_mps: float = 0.0) -> FloatArray:
        """(N,) how far each point lies inside :meth:`polygon_for` ``v_mps`` (distance to its nearest edge's
        line), metres: >= 0 inside or on the boundary, < 0 outside.

        Args:
            points_xy: (N, 2) points in the base frame, metres.
            v_mps: the command's forward speed, m/s.
        """
        p = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
        shape = self._shapes[_sign(v_mps)]
        return np.asarray((p @ shape.normals.T - shape.offsets).min(axis=1) if len(p) else np.zeros(0))

    def contains(self, points_xy: ArrayLike, v_mps: float = 0.0) -> NDArray[np.bool_]:
        """(N,) True for the points inside :meth:`polygon_for` ``v_mps`` or on its boundary (base frame, m)."""
        return np.asarray(self.depth_m(points_xy, v_mps) >= 0.0)


def _sign(v: float) -> int:
    return 1 if v > 0.0 else -1 if v < 0.0 else 0


@dataclass(frozen=True, slots=True)
class CollisionMonitorParams:
    """Settings of the collision monitor and of its default zones (:func:`default_zones`).

    The defaults are for the diffbot (a 0.18 m disc) at 0.5 m/s braking at 1-1.5 m/s², under a 20 Hz command on a
    10 Hz scan (up to 0.16 s from a scan to the wheels: its age, the command's hold, the actuation delay):

    * T = 1 s: v' = v·t/T falls with the distance d left to the approach zone as about d/T, which asks for at most
      v/T = 0.5 m/s² of braking, half the robot's, and tolerates the 0.16 s delay (a delay well under T keeps the
      approach monotone).
    * dt = 0.1 s (Nav2's): a command stops once its first step (|v|·dt, 5 cm at full speed) would reach the approach
      zone, and the last crawl before that (|v|·dt/T) overshoots by less than that step in the delay; so the robot
      comes to rest between the zone's reach and |v|·dt beyond it.
    * approach margin 0.02 m all round, the navigation controller's own collision margin (beyond the robot's
      circumscribed radius, which holds the footprint): what that controller passes beside an obstacle stays out
      of the zone (a pursuit command held would be repeated for ever); lead 0.03 m: head-on, while translating,
      the zone reaches 0.05 m, so the robot stops at least 0.05 m (at 0.5 m/s about 0.1 m) from what it drives
      at, backwards too; a spin is checked with the margin alone. At a slant the lead counts less: 0.063 m at 60°
      from the wall's normal, 0.04 m at 80° (the kinematic test's unicycle).
    * stop margin 0.01 m: the last resort, nearly touching: no command may take the robot further in.
    * slowdown: a box the approach zone's width reaching 0.5 m ahead in the direction of travel (behind when
      reversing), at half speed: something straight ahead halves the command before the approach's roll-out (0.5 m
      at full speed) slows it further, and nothing beside the robot slows it (a ring 0.3 m wide around the robot
      slowed every tick of driving 0.1 m from a wall).
    * min_points 3: one or two stray returns do not stop the robot; a 4 cm post within the approach's reach
      (0.55 m at full speed) returns at least 4 of 360 beams.
    * escape tolerance 2 mm: a 32-gon of radius 0.4 m (the diffbot's approach zone is one of 0.2 m) turning in place
      moves its facets by up to 1.9 mm.
    * moving horizon 4 s: T plus the 2.9 s the diffbot needs at 0.5 m/s to cross a 1 m lane (its front at the
      lane's near edge to its zone clear of the far one: 1 m + 0.38 m + 0.07 m), so a cart that would reach the
      robot while it crosses is seen while the robot is still T from the lane. In the kinematic test (a 1.0 x 0.7 m
      box crossing at 0.79 m/s) 3 s let a robot arriving at the lane 2.9 s ahead of the box enter it and be hit;
      of 2, 2.5, 3 and 3.5 s, 3.5 s was the shortest that kept it clear at every timing tried (the box 1 s before
      to 3.5 s after the robot, at 0.4, 0.79 and 1.2 m/s).
    * growth 0.1 m/s (the navigation controller's): a cart's face 3 m away is sampled by a return every 5 cm, its
      velocity is a two-scan estimate, carts accelerate. Without it the same loop's robot, arriving 2.5 s ahead of
      the box, clipped its corner (the roll-out outran the face's last returns and saw no contact); with it the
      robot waits 0.1 m further back per second until the cart comes, and a velocity off by 10 % and 5° (drawn
      afresh every scan) still kept it clear.

    Attributes:
        stop_margin_m: the stop zone is the footprint grown by this, metres, >= 0.
        slowdown_margin_m: the slowdown zone is the footprint grown by this, metres, >= 0.
        slowdown_lead_m: the slowdown zone's :attr:`Zone.lead_m`, metres, >= 0.
        slowdown_ratio: the slowdown zone's scale, in [0, 1].
        approach_margin_m: the approach zone (the shape rolled out) is the footprint grown by this, metres, >= 0.
        approach_lead_m: the approach zone's :attr:`Zone.lead_m`, metres, >= 0.
        time_before_collision_s: the approach zone's T, seconds, > 0.
        moving_horizon_s: how far ahead an approach zone's roll-out follows moving points (the longer of this and
            the zone's T), seconds, >= time_before_collision_s.
        uncertainty_growth_mps: against moving points the approach zone grows by this per second ahead, on the
            roll-out and at the poses the robot could not hold (a velocity is a two-scan estimate, obstacles
            accelerate, a surface is sampled by a few returns), m/s, >= 0.
        simulation_step_s: the roll-out's step dt, seconds, in (0, T].
        min_points: points inside a zone before it acts, >= 1.
        escape_tolerance_m: how much deeper a stop or approach zone's points may get before a command counts as
            moving in, metres, >= 0.
    """

    stop_margin_m: float = 0.01
    slowdown_margin_m: float = 0.02
    slowdown_lead_m: float = 0.5
    slowdown_ratio: float = 0.5
    approach_margin_m: float = 0.02
    approach_lead_m: float = 0.03
    time_before_collision_s: float = 1.0
    moving_horizon_s: float = 4.0
    uncertainty_growth_mps: float = 0.1
    simulation_step_s: float = 0.1
    min_points: int = 3
    escape_tolerance_m: float = 0.002

    def __post_init__(self) -> None:
        check_params(
            self,
            positive=("time_before_collision_s", "moving_horizon_s", "simulation_step_s"),
            non_negative=(
                "stop_margin_m",
                "slowdown_margin_m",
                "slowdown_lead_m",
                "approach_margin_m",
                "approach_lead_m",
                "slowdown_ratio",
                "escape_tolerance_m",
                "uncertainty_growth_mps",
            ),
        )
        if self.slowdown_ratio > 1.0:
            raise ValueError(f"CollisionMonitorParams.slowdown_ratio must be in [0, 1], got {self.slowdown_ratio}")
        if self.simulation_step_s > self.time_before_collision_s:
            raise ValueError("CollisionMonitorParams.simulation_step_s must be <= time_before_collision_s")
        if self.moving_horizon_s < self.time_before_collision_s:
            raise ValueError("CollisionMonitorParams.moving_horizon_s must be >= time_before_collision_s")
        if isinstance(self.min_points, bool) or not isinstance(self.min_points, int) or self.min_points < 1:
            raise ValueError(f"CollisionMonitorParams.min_points must be an integer >= 1, got {self.min_points}")


def default_zones(footprint_m: ArrayLike, params: CollisionMonitorParams | None = None) -> tuple[Zone, Zone, Zone]:
    """The stop, slowdown and approach zones of a footprint: it grown by each zone's margin (:func:`offset_polygon`),
    the slowdown and approach zones with their leads.

    Args:
        footprint_m: (K, 2) convex counter-clockwise footprint in the base frame, metres
            (:attr:`mjnav.robot.RobotDescription.footprint_m`).
        params: margins, ratio, T and ``min_points`` (defaults: :class:`CollisionMonitorParams`).

    Returns:
        Zones named ``stop``, ``slowdown`` and ``approach``.

    Raises:
        MonitorInputError: the footprint is not a convex counter-clockwise polygon.
    """
    p = params or CollisionMonitorParams()
    fp = convex_polygon(footprint_m, "footprint")
    n = p.min_points
    return (
        Zone("stop", MonitorAction.STOP, offset_polygon(fp, p.stop_margin_m), n),
        Zone(
            "slowdown",
            MonitorAction.SLOWDOWN,
            offset_polygon(fp, p.slowdown_margin_m),
            n,
            p.slowdown_ratio,
            lead_m=p.slowdown_lead_m,
        ),
        Zone(
            "approach",
            MonitorAction.APPROACH,
            offset_polygon(fp, p.approach_margin_m),
            n,
            time_before_collision_s=p.time_before_collision_s,
            lead_m=p.approach_lead_m,
        ),
    )


@dataclass(frozen=True, slots=True)
class MonitorResult:
    """What the monitor made of a command.

    Attributes:
        v_mps: the forward speed to apply, m/s (the command's times ``scale``).
        omega_radps: the yaw rate to apply, rad/s (the command's times ``scale``).
        scale: the factor applied, in [0, 1] (1: the command passes unchanged).
        action: what limited it (:attr:`MonitorAction.NONE`: nothing did).
        zone: the name of the zone that limited it, or None.
        time_to_collision_s: the shortest time to collision an approach zone found on the command's arc (the last
            collision-free step), seconds, whether or not that zone limited the command; inf when none collides
            within its horizon or when the command was checked against no approach zone. Against moving points: to
            the first pose on the arc the robot could not hold (see the module docstring).
    """

    v_mps: float
    omega_radps: float
    scale: float
    action: MonitorAction
    zone: str | None
    time_to_collision_s: float

    @property
    def limited(self) -> bool:
        """True when a zone acted on the command."""
        return self.action is not MonitorAction.NONE


class CollisionMonitor:
    """Checks each command against the zones on the newest scan (see the module docstring for the rules).

    Args:
        zones: the zones, names unique (e.g. :func:`default_zones`).
        params: ``simulation_step_s`` and ``escape_tolerance_m`` are read from it (the margins only build default
            zones; defaults: :class:`CollisionMonitorParams`).

    Raises:
        MonitorInputError: two zones share a name.
    """

    def __init__(self, zones: Sequence[Zone], params: CollisionMonitorParams | None = None) -> None:
        names = [z.name for z in zones]
        if len(set(names)) != len(names):
            raise MonitorInputError(f"zone names must be unique, got {names}")
        self.zones: tuple[Zone, ...] = tuple(zones)
        self.params = params or CollisionMonitorParams()

    @classmethod
    def for_footprint(cls, footprint_m: ArrayLike, params: CollisionMonitorParams | None = None) -> CollisionMonitor:
        """A monitor with the :func:`default_zones` of ``footprint_m`` ((K, 2) convex CCW, base frame, metres)."""
        return cls(default_zones(footprint_m, params), params)

    def check(
        self, v_mps: float, omega_radps: float, points_xy: ArrayLike, velocities_mps: ArrayLike | None = None
    ) -> MonitorResult:
        """The command to apply instead of (v, ω), given the newest scan.

        Args:
            v_mps: forward speed the robot is about to apply, m/s (negative: reversing).
            omega_radps: yaw rate, rad/s (counter-clockwise positive).
            points_xy: (N, 2) scan points in the base frame, metres; rows with a NaN or inf are ignored.
            velocities_mps: (N, 2) each point's velocity over the ground, expressed in the base frame's axes, m/s
                (0: static; not relative to the robot, whose own motion the roll-out adds), or None: all static.
                Must be finite where the point is.

        Returns:
            The scaled command and what limited it.

        Raises:
            MonitorInputError: the command is not finite, the points are not an (N, 2) array, or the velocities not
                an (N, 2) array of the points' N rows, finite where the points are.
        """
        v, w = float(v_mps), float(omega_radps)
        if not (math.isfinite(v) and math.isfinite(w)):
            raise MonitorInputError(f"command must be finite, got v={v_mps} m/s, omega={omega_radps} rad/s")
        pts, vel = _finite_points(points_xy, velocities_mps)
        moving = np.any(vel != 0.0, axis=1)
        static, mov, mov_vel = pts[~moving], pts[moving], vel[moving]
        best = (1.0, 3, -1)  # (scale, severity, zone index): the most restrictive so far
        ttc = math.inf
        if (v == 0.0 and w == 0.0) or not self.zones:
            return MonitorResult(v, w, 1.0, MonitorAction.NONE, None, ttc)
        for i, zone in enumerate(self.zones):
            shape = zone._shapes[_sign(v)]
            if zone.action is MonitorAction.SLOWDOWN:
                if shape.nth_depth(pts, np.zeros((1, 3)), zone.min_points)[0] < 0.0:
                    continue
                scale = zone.slowdown_ratio
            else:
                hits = (
                    self._first_hit(zone, shape, v, w, static),
                    self._first_moving_hit(zone, shape, v, w, mov, mov_vel),
                )
                if hits == (None, None):
                    continue
                t_hit = min(h for h in hits if h is not None)
                scale = 0.0
                if zone.action is MonitorAction.APPROACH:
                    ttc = min(ttc, t_hit)
                    scale = min(1.0, t_hit / zone.time_before_collision_s)
            best = min(best, (scale, _SEVERITY[zone.action], i))
        scale, _, index = best
        if index < 0:
            return MonitorResult(v, w, 1.0, MonitorAction.NONE, None, ttc)
        zone = self.zones[index]
        return MonitorResult(v * scale, w * scale, scale, zone.action, zone.name, ttc)

    def _first_hit(self, zone: Zone, shape: _Shape, v: float, w: float, pts: FloatArray) -> float | None:
        """The last collision-free step's time (s) of a stop or approach zone on the arc (v, ω), or None when the
        command passes: a stop zone looks one step ahead and only at points already inside it, an approach zone up
        to its T; a zone that holds points now collides only where they get deeper (the escape rule)."""
        dt = self.params.simulation_step_s
        approach = zone.action is MonitorAction.APPROACH
        steps = math.ceil(zone.time_before_collision_s / dt - 1e-9) if approach else 1
        near = pts[np.hypot(pts[:, 0], pts[:, 1]) <= shape.radius_m + abs(v) * steps * dt]
        now = float(shape.nth_depth(near, np.zeros((1, 3)), zone.min_points)[0])
        if now < 0.0 and not approach:
            return None
        # Samples per step: no vertex of the zone moves more than _SWEEP_STEP_M from one sample to the next.
        sub = max(1, math.ceil((abs(v) + abs(w) * shape.radius_m) * dt / _SWEEP_STEP_M))
        t = np.arange(1, steps * sub + 1, dtype=np.float64) * (dt / sub)
        poses: FloatArray = np.column_stack((_arc(v, w, t), w * t))
        # Only points within the zone's reach of some sample's centre can be inside it there.
        gap2 = ((near[:, None, :] - poses[None, :, :2]) ** 2).sum(axis=2).min(axis=1) if len(near) else near[:, 0]
        swept = near[gap2 <= (shape.radius_m + 1e-9) ** 2]
        ahead = shape.nth_depth(swept, poses, zone.min_points).reshape(steps, sub).max(axis=1)
        hit = ahead > now + self.params.escape_tolerance_m if now >= 0.0 else ahead >= 0.0
        return float(np.argmax(hit)) * dt if hit.any() else None

    def _first_moving_hit(
        self, zone: Zone, shape: _Shape, v: float, w: float, pts: FloatArray, vel: FloatArray
    ) -> float | None:
        """The last collision-free step's time (s) of a stop or approach zone on the arc (v, ω) against the moving
        points ``pts`` (M, 2) at ``vel`` (M, 2), or None when they do not limit the command (the rules: the module
        docstring's *Moving points*)."""
        n = zone.min_points
        if len(pts) < n:
            return None
        dt = self.params.simulation_step_s
        approach = zone.action is MonitorAction.APPROACH
        horizon = max(zone.time_before_collision_s, self.params.moving_horizon_s) if approach else dt
        steps = math.ceil(horizon / dt - 1e-9)
        speed = np.hypot(vel[:, 0], vel[:, 1])
        growth = self.params.uncertainty_growth_mps
        reach = shape.radius_m + (abs(v) + speed + shape.miter * growth) * steps * dt  # (M,) of the arc's zones
        near = np.hypot(pts[:, 0], pts[:, 1]) <= reach
        pts, vel, speed = pts[near], vel[near], speed[near]
        if len(pts) < n:
            return None
        # Samples per step: no vertex of the zone moves more than _SWEEP_STEP_M relative to a point per sample.
        sub = max(1, math.ceil((abs(v) + abs(w) * shape.radius_m + float(speed.max())) * dt / _SWEEP_STEP_M))
        t = np.arange(steps * sub + 1, dtype=np.float64) * (dt / sub)  # from 0: the robot where it stands
        poses: FloatArray = np.column_stack((_arc(v, w, t), w * t))
        moved = pts[None, :, :] + vel[None, :, :] * t[:, None, None]  # (S, M, 2): the points at each sample
        grown = growth * t
        ahead = shape.nth_depth(moved, poses, n, grown)
        standing = shape.nth_depth(moved, np.zeros_like(poses), n, np.zeros_like(t))
        if standing[0] >= 0.0:
            # Inside now: the command may not take them deeper than the deeper of now and where they get with the
            # robot standing (the growth is for contact ahead: compared here without it).
            tol = self.params.escape_tolerance_m
            deeper = ahead[1:] - grown[1:] > np.maximum(standing[1:], standing[0]) + tol
            return float(int(np.argmax(deeper)) // sub) * dt if deeper.any() else None
        if not approach:
            return None
        if not (ahead[1:] >= 0.0).any():  # no contact on the roll-out (the growth counts here, for the estimate)
            return None
        # A pose the robot could not hold: a moving point would enter its zone there, held from when the robot gets
        # there, within the horizon (on its track, the zone grown as on the roll-out), and — if one would enter the
        # zone of the robot standing where it is (exactly, and without the lead: a robot held at a lane's edge is
        # not in the lane) — more than a step sooner than there (both grown). Any one point counts (the contact took
        # min_points), so a cart's lane starts at its first return, not at its min_points-th (5 cm apart at 3 m).
        # The poses are those of the static roll-out (no zone vertex moves more than _SWEEP_STEP_M from one to the
        # next: the tracks are followed exactly, so the points' speeds do not count here).
        horizon_s, still, origin = steps * dt, zone._shapes[0], np.zeros((1, 3))
        here = still.entry_times(pts, vel, origin, t[:1], horizon_s, 1)[0]
        if here < math.inf:
            here = still.entry_times(pts, vel, origin, t[:1], horizon_s, 1, growth)[0]
        held = max(1, math.ceil((abs(v) + abs(w) * shape.radius_m) * dt / _SWEEP_STEP_M))
        th = np.arange(1, steps * held + 1, dtype=np.float64) * (dt / held)
        entry = shape.entry_times(pts, vel, np.column_stack((_arc(v, w, th), w * th)), th, horizon_s, 1, growth)
        worse = entry < here - dt
        return float(int(np.argmax(worse)) // held) * dt if worse.any() else None


def _finite_points(points_xy: ArrayLike, velocities_mps: ArrayLike | None) -> tuple[FloatArray, FloatArray]:
    """(M, 2) the rows of ``points_xy`` that are finite, and (M, 2) their velocities (zero when None)."""
    try:
        p = np.asarray(points_xy, dtype=np.float64)
    except (TypeError, ValueError):
        raise MonitorInputError("points must be an (N, 2) array of numbers") from None
    if p.size == 0:
        p = np.zeros((0, 2))
    if p.ndim != 2 or p.shape[1] != 2:
        raise MonitorInputError(f"points must be an (N, 2) array, got shape {p.shape}")
    ok = np.isfinite(p).all(axis=1)
    if velocities_mps is None:
        return p[ok], np.zeros((int(ok.sum()), 2))
    try:
        u = np.asarray(velocities_mps, dtype=np.float64)
    except (TypeError, ValueError):
        raise MonitorInputError("velocities must be an (N, 2) array of numbers") from None
    if u.size == 0 and len(p) == 0:
        u = np.zeros((0, 2))
    if u.shape != p.shape:
        raise MonitorInputError(f"velocities must be an (N, 2) array as the points {p.shape}, got shape {u.shape}")
    if not np.isfinite(u[ok]).all():
        raise MonitorInputError("velocities must be finite where the points are")
    return p[ok], u[ok]

"""How well a scan-matching localiser is doing, scan by scan: ``OK``, ``DEGRADED`` or ``LOST``.

A scan is *good* when it has enough returns to match (``min_returns``), was matched, and its match quality (the
share of its points with a correspondence, :class:`~mjnav.estimation.slam.PoseEstimate` ``score``) reaches
``min_score``. While scans are not good the pose follows the odometry alone: after ``degraded_scans`` of them in
a row the localisation is ``DEGRADED``; once the odometry alone has carried the robot ``lost_distance_m`` (or
turned it ``lost_angle_rad``) since the last good scan, it is ``LOST`` — wheel odometry drifts by a per cent or
two of the distance, and 10 m of it can put the robot on the wrong side of a thin wall (the defaults: 10 m, a
full turn; the gyro-aided heading drifts little). The first good scan makes it ``OK`` again. A *degenerate*
match (a long corridor pins the pose across it, not along it) is a good scan here: the odometry carries the
pose along the corridor, and slowing down there only adds scans, each a little noise along it (the slam
service reports degeneracy beside the level). The levels are those of ROS's
``diagnostic_msgs/DiagnosticStatus`` (OK, WARN, ERROR).

A report also says whether the newest scan was bad for want of returns (:attr:`HealthReport.starved`): lost in
open space, with nothing in the lidar's range, is another matter than lost among returns that do not match the
map — nothing is near to collide with, and standing still brings no return that could localise the robot again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

from mjnav.estimation.errors import InvalidModel


class Health(IntEnum):
    """Localisation health, valued as ``diagnostic_msgs/DiagnosticStatus`` levels."""

    OK = 0
    DEGRADED = 1
    LOST = 2


@dataclass(frozen=True)
class HealthConfig:
    """Thresholds of :class:`HealthMonitor`.

    Attributes:
        min_returns: a scan with fewer valid returns is not good (a big open hall: the walls out of range).
        min_score: a match whose quality is below this is not good.
        degraded_scans: this many scans in a row that are not good make the localisation ``DEGRADED``.
        lost_distance_m: driven on odometry alone since the last good scan: ``LOST``.
        lost_angle_rad: turned on odometry alone since the last good scan: ``LOST``.
    """

    min_returns: int = 30
    min_score: float = 0.5
    degraded_scans: int = 3
    lost_distance_m: float = 10.0
    lost_angle_rad: float = 2.0 * math.pi

    def __post_init__(self) -> None:
        if not self.min_returns >= 3:
            raise InvalidModel(f"min_returns must be >= 3, got {self.min_returns}")
        if not 0.0 <= self.min_score <= 1.0:
            raise InvalidModel(f"min_score must be in [0, 1], got {self.min_score}")
        if not self.degraded_scans >= 1:
            raise InvalidModel(f"degraded_scans must be >= 1, got {self.degraded_scans}")
        if not (self.lost_distance_m > 0 and self.lost_angle_rad > 0):
            raise InvalidModel("lost_distance_m and lost_angle_rad must be > 0")


@dataclass(frozen=True)
class HealthReport:
    """The localisation's health after a scan.

    Attributes:
        level: OK, DEGRADED or LOST.
        reason: why it is not OK, in words ("" when OK).
        returns: valid returns of the newest scan.
        score: match quality of the newest scan (0 when not matched).
        bad_scans: scans in a row that were not good.
        unmatched_m: distance driven on odometry alone since the last good scan, metres.
        unmatched_rad: angle turned meanwhile, radians.
        starved: the newest scan was not good for want of returns (fewer than ``min_returns``).
    """

    level: Health
    reason: str
    returns: int
    score: float
    bad_scans: int
    unmatched_m: float
    unmatched_rad: float
    starved: bool = False


class HealthMonitor:
    """Follows the localiser scan by scan (:meth:`update`) and says how well it is doing."""

    def __init__(self, config: HealthConfig | None = None) -> None:
        self.config = config or HealthConfig()
        self._bad = 0
        self._distance = 0.0
        self._angle = 0.0
        self._odom: tuple[float, float, float] | None = None
        self.report = HealthReport(Health.OK, "", 0, 1.0, 0, 0.0, 0.0)

    def update(
        self,
        odom_xyt: tuple[float, float, float],
        returns: int,
        score: float,
        matched: bool,
    ) -> HealthReport:
        """Account for one scan: the odometry pose (x, y, θ) at its time, its valid returns, the match's quality
        and whether it was matched. Returns the health after it (also kept in :attr:`report`)."""
        cfg = self.config
        if self._odom is not None:
            self._distance += math.hypot(odom_xyt[0] - self._odom[0], odom_xyt[1] - self._odom[1])
            self._angle += abs(math.remainder(odom_xyt[2] - self._odom[2], math.tau))
        self._odom = odom_xyt
        problem = ""
        if returns < cfg.min_returns:
            problem = f"{returns} lidar returns, fewer than {cfg.min_returns}"
        elif not matched:
            problem = "the scan did not match the map"
        elif score < cfg.min_score:
            problem = f"match quality {score:.2f}, below {cfg.min_score:g}"
        if not problem:
            self._bad, self._distance, self._angle = 0, 0.0, 0.0
            self.report = HealthReport(Health.OK, "", returns, score, 0, 0.0, 0.0)
            return self.report
        self._bad += 1
        level = Health.OK
        if self._distance >= cfg.lost_distance_m or self._angle >= cfg.lost_angle_rad:
            level = Health.LOST
        elif self._bad >= cfg.degraded_scans:
            level = Health.DEGRADED
        reason = (
            f"{problem}; {self._bad} scan(s) in a row, {self._distance:.2f} m and "
            f"{math.degrees(self._angle):.0f} deg on odometry alone"
        )
        starved = returns < cfg.min_returns
        self.report = HealthReport(
            level, reason, returns, score if matched else 0.0, self._bad, self._distance, self._angle, starved
        )
        return self.report

"""Planar lidar: one ``mj_multiRay`` call per scan from the robot's ``laser`` site (:data:`mjnav.robot.LIDAR_SITE`).

Beams lie in the lidar site's x-y plane (the robot's base plane), counter-clockwise from ``angle_min_rad``
(REP-103: 0 rad = straight ahead, +π/2 = left). The robot never sees itself: its geoms are all in geom
group :data:`~mjnav.sim.model.ROBOT_GEOM_GROUP`, which the ray's geomgroup mask leaves out, and its root body
is passed as ``bodyexclude``.

Range values follow REP-117 (``sensor_msgs/LaserScan``):

* a hit in [range_min, range_max] is reported with additive Gaussian noise N(0, noise_std_m²) (seeded), and
  the noisy value is classified again (noise can push a reading past a limit);
* no hit, or a hit beyond ``range_max_m``: ``+inf``;
* a hit closer than ``range_min_m``: ``-inf``.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjnav.robot.lidar import LidarConfig
from mjnav.sim.model import ROBOT_GEOM_GROUP

__all__ = ["Lidar", "LidarConfig", "LidarScan"]


@dataclass(frozen=True, slots=True)
class LidarScan:
    """One planar scan.

    Attributes:
        stamp_s: sim time at which the rays were cast, seconds.
        angles_rad: (N,) beam angles in the lidar frame, radians.
        ranges_m: (N,) ranges, metres; ``+inf`` = nothing within range_max, ``-inf`` = closer than range_min.
        config: the lidar configuration (range limits, rate, angle layout for ``LaserScan``).
    """

    stamp_s: float
    angles_rad: NDArray[np.float64]
    ranges_m: NDArray[np.float64]
    config: LidarConfig

    def points(self) -> NDArray[np.float64]:
        """(M, 2) hit points in the lidar frame, metres, for the finite ranges only."""
        ok = np.isfinite(self.ranges_m)
        r = self.ranges_m[ok]
        a = self.angles_rad[ok]
        return np.column_stack((r * np.cos(a), r * np.sin(a)))


class Lidar:
    """Casts the scans of one :class:`LidarConfig` from a site of a MuJoCo model.

    Buffers are allocated once; :meth:`cast` does one ``mj_multiRay`` call plus a few vector operations.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        site_id: int,
        exclude_body: int,
        config: LidarConfig,
        rng: np.random.Generator,
    ) -> None:
        """Prepare the ray buffers.

        Args:
            model: compiled model.
            data: its data; ``cast`` uses its current kinematics (``site_xpos``/``site_xmat``/``geom_x*``).
            site_id: id of the site the rays start from; beams lie in its x-y plane.
            exclude_body: body id whose geoms are ignored (the robot root), or -1.
            config: beam layout, limits and noise.
            rng: generator for the range noise.
        """
        self._model = model
        self._data = data
        self._site = site_id
        self._exclude = exclude_body
        self.config = config
        self._rng = rng
        self.angles = config.angles()
        self.angles.setflags(write=False)
        n = config.num_beams
        self._local = np.column_stack((np.cos(self.angles), np.sin(self.angles), np.zeros(n)))
        self._vec = np.empty(3 * n, dtype=np.float64)
        self._dist = np.empty(n, dtype=np.float64)
        self._geomid = np.empty(n, dtype=np.int32)
        self._pnt = np.empty(3, dtype=np.float64)
        group = np.ones(6, dtype=np.uint8)
        group[ROBOT_GEOM_GROUP] = 0
        self._geomgroup = group

    def cast(self, stamp_s: float) -> LidarScan:
        """Cast every beam from the current kinematics of ``data`` and return the noisy scan.

        Args:
            stamp_s: time stamp to put on the scan, seconds.
        """
        cfg = self.config
        d = self._data
        rot = d.site_xmat[self._site].reshape(3, 3)
        np.dot(self._local, rot.T, out=self._vec.reshape(-1, 3))
        self._pnt[:] = d.site_xpos[self._site]
        mujoco.mj_multiRay(
            self._model,
            d,
            self._pnt,
            self._vec,
            self._geomgroup,
            1,
            self._exclude,
            self._geomid,
            self._dist,
            None,
            cfg.num_beams,
            cfg.range_max_m,
        )
        dist = self._dist
        # one noise draw per beam, hit or not, so the noise stream does not depend on the world
        noisy = cfg.noise_std_m > 0.0
        ranges = dist + self._rng.normal(0.0, cfg.noise_std_m, cfg.num_beams) if noisy else dist.copy()
        ranges[ranges > cfg.range_max_m] = np.inf
        ranges[ranges < cfg.range_min_m] = -np.inf
        ranges[dist < 0.0] = np.inf  # mj_multiRay reports "no hit" as -1
        return LidarScan(stamp_s=stamp_s, angles_rad=self.angles, ranges_m=ranges, config=cfg)

"""Planar lidar: one ``mj_multiRay`` call per scan from the robot's ``lidar`` site.

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

import math
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjnav.sim.model import ROBOT_GEOM_GROUP

_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, slots=True)
class LidarConfig:
    """Planar lidar parameters.

    Attributes:
        num_beams: number of beams per scan.
        rate_hz: scans per second of sim time (the scan schedule of :class:`~mjnav.sim.Simulator`).
        range_min_m: shortest measurable range, metres.
        range_max_m: longest measurable range, metres.
        noise_std_m: standard deviation of the additive Gaussian range noise, metres (0 = exact).
        fov_rad: angular field of view, radians, centred on +x; 2π = full circle (no duplicated beam).
    """

    num_beams: int = 360
    rate_hz: float = 10.0
    range_min_m: float = 0.12
    range_max_m: float = 12.0
    noise_std_m: float = 0.01
    fov_rad: float = _TWO_PI

    def __post_init__(self) -> None:
        if self.num_beams < 1:
            raise ValueError(f"num_beams must be >= 1, got {self.num_beams}")
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0.0):
            raise ValueError(f"rate_hz must be positive, got {self.rate_hz}")
        if not (0.0 <= self.range_min_m < self.range_max_m and math.isfinite(self.range_max_m)):
            raise ValueError(f"need 0 <= range_min_m < range_max_m < inf, got {self.range_min_m}, {self.range_max_m}")
        if not (math.isfinite(self.noise_std_m) and self.noise_std_m >= 0.0):
            raise ValueError(f"noise_std_m must be >= 0, got {self.noise_std_m}")
        if not (0.0 < self.fov_rad <= _TWO_PI + 1e-12):
            raise ValueError(f"fov_rad must be in (0, 2π], got {self.fov_rad}")

    @property
    def full_circle(self) -> bool:
        """True when the field of view is a whole turn."""
        return self.fov_rad >= _TWO_PI - 1e-9

    @property
    def angle_min_rad(self) -> float:
        """Angle of the first beam, radians (−fov/2)."""
        return -0.5 * self.fov_rad

    @property
    def angle_increment_rad(self) -> float:
        """Angle between neighbouring beams, radians (fov/n for a full circle, fov/(n−1) otherwise)."""
        if self.full_circle:
            return self.fov_rad / self.num_beams
        return self.fov_rad / (self.num_beams - 1) if self.num_beams > 1 else 0.0

    @property
    def angle_max_rad(self) -> float:
        """Angle of the last beam, radians (REP-117 ``angle_max``)."""
        return self.angle_min_rad + (self.num_beams - 1) * self.angle_increment_rad

    def angles(self) -> NDArray[np.float64]:
        """(num_beams,) beam angles in the lidar frame, radians, increasing counter-clockwise."""
        return self.angle_min_rad + self.angle_increment_rad * np.arange(self.num_beams, dtype=np.float64)


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


#: Numerics of the robot model that set the lidar (``mjcf/diffbot.xml``), by :class:`LidarConfig` field.
LIDAR_NUMERICS: dict[str, str] = {
    "num_beams": "lidar_beams",
    "rate_hz": "lidar_rate_hz",
    "range_min_m": "lidar_range_min_m",
    "range_max_m": "lidar_range_max_m",
    "noise_std_m": "lidar_noise_std_m",
    "fov_rad": "lidar_fov_rad",
}


def lidar_config_from_model(model: mujoco.MjModel, prefix: str = "") -> LidarConfig:
    """The lidar the robot model declares: its ``lidar_*`` custom numerics (:data:`LIDAR_NUMERICS`, each one
    value, names carrying the robot's attach ``prefix``); a numeric the model lacks keeps :class:`LidarConfig`'s
    default.

    Raises:
        ValueError: a numeric with other than one value, or values :class:`LidarConfig` rejects.
    """
    values: dict[str, float] = {}
    for field_name, numeric in LIDAR_NUMERICS.items():
        nid = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, prefix + numeric))
        if nid < 0:
            continue
        if int(model.numeric_size[nid]) != 1:
            raise ValueError(f"numeric {prefix + numeric} needs exactly one value")
        values[field_name] = float(model.numeric_data[int(model.numeric_adr[nid])])
    default = LidarConfig()
    if _TWO_PI < values.get("fov_rad", 0.0) <= _TWO_PI + 1e-4:  # 2π as a file rounds it (MjSpec.to_xml: 6.28319)
        values["fov_rad"] = _TWO_PI
    beams = values.get("num_beams", float(default.num_beams))
    if beams != int(beams):
        raise ValueError(f"numeric {prefix}lidar_beams must be a whole number, got {beams}")
    return LidarConfig(
        num_beams=int(beams),
        rate_hz=values.get("rate_hz", default.rate_hz),
        range_min_m=values.get("range_min_m", default.range_min_m),
        range_max_m=values.get("range_max_m", default.range_max_m),
        noise_std_m=values.get("noise_std_m", default.noise_std_m),
        fov_rad=values.get("fov_rad", default.fov_rad),
    )


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

"""The planar lidar a robot model declares: beam layout, rate, range limits and noise (REP-117 conventions)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, slots=True)
class LidarConfig:
    """Planar lidar parameters.

    Attributes:
        num_beams: number of beams per scan.
        rate_hz: scans per second of sim time.
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


#: Custom numerics of a robot model that set its lidar, by :class:`LidarConfig` field (each holds one value; a
#: numeric the model lacks keeps the field's default).
LIDAR_NUMERICS: dict[str, str] = {
    "num_beams": "lidar_beams",
    "rate_hz": "lidar_rate_hz",
    "range_min_m": "lidar_range_min_m",
    "range_max_m": "lidar_range_max_m",
    "noise_std_m": "lidar_noise_std_m",
    "fov_rad": "lidar_fov_rad",
}


def lidar_config_from_numerics(numerics: dict[str, list[float]]) -> LidarConfig:
    """The lidar that a model's custom numerics declare (:data:`LIDAR_NUMERICS`; names without a prefix).

    Raises:
        ValueError: a numeric with other than one value, a fractional beam count, or values :class:`LidarConfig`
            rejects.
    """
    values: dict[str, float] = {}
    for field_name, numeric in LIDAR_NUMERICS.items():
        if numeric not in numerics:
            continue
        data = numerics[numeric]
        if len(data) != 1:
            raise ValueError(f"numeric {numeric} needs exactly one value, got {len(data)}")
        values[field_name] = float(data[0])
    default = LidarConfig()
    if _TWO_PI < values.get("fov_rad", 0.0) <= _TWO_PI + 1e-4:  # 2π as a file rounds it (MjSpec.to_xml: 6.28319)
        values["fov_rad"] = _TWO_PI
    beams = values.get("num_beams", float(default.num_beams))
    if beams != int(beams):
        raise ValueError(f"numeric lidar_beams must be a whole number, got {beams}")
    return LidarConfig(
        num_beams=int(beams),
        rate_hz=values.get("rate_hz", default.rate_hz),
        range_min_m=values.get("range_min_m", default.range_min_m),
        range_max_m=values.get("range_max_m", default.range_max_m),
        noise_std_m=values.get("noise_std_m", default.noise_std_m),
        fov_rad=values.get("fov_rad", default.fov_rad),
    )

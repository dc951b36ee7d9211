"""The quadrotor in MuJoCo: rotors, wind with gusts, IMU, GPS, barometer and ground truth.

World frame ENU (MuJoCo z up), body FLU; the flight software's NED / FRD conversions happen in the services
(:mod:`mjnav.aerial.rep103`). The model is ``mjcf/quadrotor.xml`` attached (prefix ``uav/``) to a scene of
``mjcf/uav/`` (``field`` by default).

* **Rotors**: :meth:`UavSimulator.set_rotor_speeds` takes speed commands (rad/s) and sets each actuator's control to
  the rotor thrust ``k_f ω²`` (N, clipped to the rotor's maximum); the actuator's first-order filter (20 ms) is the
  motor lag, its gear adds the reaction torque (see the MJCF).
* **Wind** (:class:`Wind`, seeded): a mean wind of ``mean_mps`` from a random heading plus "1 − cos" gusts of peak
  ``gust_mps`` (1–3 s long, random horizontal direction, one at a time, a pause of 3 s on average between them).
  The vehicle feels the quadratic drag ``½ ρ C_dA |w − v| (w − v)`` at its centre of mass.
* **Sensors** (one seeded ``numpy.random.Generator``, drawn in call order): IMU specific force (the mean over the
  last step call, from the change of velocity: a delta-velocity IMU) and rate (FLU) with white noise and a constant
  accelerometer bias, attitude from the frame-orientation sensor with white noise
  (the AHRS output); GPS (WGS84 latitude/longitude/altitude of the true position about a geodetic origin, white
  noise per axis); barometric pressure (ISA troposphere, white noise).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

import mjnav
from mjnav.aerial import QuadrotorParams, enu_to_geodetic
from mjnav.sim.errors import InvalidCommandError, ModelLoadError, UnknownWorldError

__all__ = [
    "UAV_WORLDS_DIR",
    "GeodeticOrigin",
    "ImuReading",
    "UavNoise",
    "UavSimulator",
    "UavTruth",
    "Wind",
    "pressure_at_altitude",
    "resolve_uav_world",
    "uav_worlds",
]

#: Folder of the UAV scenes (``mjcf/uav/*.xml``); the quadrotor itself is ``mjcf/quadrotor.xml``.
UAV_WORLDS_DIR: Path = mjnav.REPO_ROOT / "mjcf" / "uav"
#: Prefix of the quadrotor's names in a scene (``<attach … prefix="uav/"/>``).
PREFIX = "uav/"
#: Air density, kg/m³ (ISA sea level).
RHO_AIR = 1.225
#: ISA sea-level pressure (Pa), temperature (K), lapse rate (K/m), and the exponent g M / (R L).
_P0_PA, _T0_K, _LAPSE, _EXP = 101325.0, 288.15, 0.0065, 5.25588


def uav_worlds() -> tuple[str, ...]:
    """Names of the bundled UAV scenes (stems of ``mjcf/uav/*.xml``), sorted."""
    return tuple(sorted(p.stem for p in UAV_WORLDS_DIR.glob("*.xml"))) if UAV_WORLDS_DIR.is_dir() else ()


def resolve_uav_world(world: str | Path) -> Path:
    """A bundled UAV scene name (``field``) or an MJCF path → absolute path; UnknownWorldError otherwise."""
    text = str(world)
    if text in uav_worlds():
        return (UAV_WORLDS_DIR / f"{text}.xml").resolve()
    path = Path(text).expanduser()
    if path.is_file():
        return path.resolve()
    raise UnknownWorldError(text, uav_worlds())


def pressure_at_altitude(h_m: float) -> float:
    """ISA troposphere static pressure (Pa) at geometric altitude ``h_m`` (m above mean sea level)."""
    return _P0_PA * (1.0 - _LAPSE * h_m / _T0_K) ** _EXP


@dataclass(frozen=True)
class GeodeticOrigin:
    """Where the scene's ENU origin lies on the WGS84 ellipsoid (default: PX4 SITL's Zurich home)."""

    lat_deg: float = 47.397742
    lon_deg: float = 8.545594
    alt_m: float = 488.0


@dataclass(frozen=True)
class UavNoise:
    """Sensor noise (standard deviations; per sample, per axis).

    Attributes:
        accel_mps2: accelerometer white noise, m/s².
        accel_bias_mps2: spread of the constant accelerometer bias drawn per run, m/s².
        gyro_radps: gyro white noise, rad/s.
        attitude_rad: AHRS attitude noise (small rotation about each axis), rad.
        gps_m: GPS position noise, m.
        baro_pa: barometer noise, Pa.
    """

    accel_mps2: float = 0.02
    accel_bias_mps2: float = 0.05
    gyro_radps: float = 0.002
    attitude_rad: float = 0.002
    gps_m: float = 1.0
    baro_pa: float = 2.0

    def __post_init__(self) -> None:
        for name, v in self.__dict__.items():
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"noise {name} must be finite and >= 0, got {v}")


class Wind:
    """Mean wind plus seeded "1 − cos" gusts (ENU, m/s).

    Args:
        mean_mps: mean wind speed, m/s, blowing from a heading drawn from ``rng``.
        gust_mps: peak gust speed added on top, m/s (0: no gusts).
        rng: the generator the heading and the gust schedule are drawn from.
        horizon_s: how long a schedule to draw, s (no gusts after it).
        mean_interval_s: mean pause between the end of a gust and the start of the next, s.
    """

    def __init__(
        self,
        mean_mps: float,
        gust_mps: float,
        rng: np.random.Generator,
        horizon_s: float = 3600.0,
        mean_interval_s: float = 3.0,
    ) -> None:
        if not (math.isfinite(mean_mps) and mean_mps >= 0.0 and math.isfinite(gust_mps) and gust_mps >= 0.0):
            raise InvalidCommandError(f"wind and gust speeds must be finite and >= 0, got {mean_mps}, {gust_mps}")
        heading = rng.uniform(0.0, 2.0 * math.pi)
        self.mean = mean_mps * np.array([math.cos(heading), math.sin(heading), 0.0])
        self.gust_mps = gust_mps
        starts, durations, dirs = [], [], []
        t = 0.0
        while gust_mps > 0.0:
            t += rng.exponential(mean_interval_s)
            if t >= horizon_s:
                break
            starts.append(t)
            durations.append(rng.uniform(1.0, 3.0))
            a = rng.uniform(0.0, 2.0 * math.pi)
            dirs.append((math.cos(a), math.sin(a), 0.0))
            t += durations[-1]  # gusts never overlap: each peaks at gust_mps
        self._start = np.array(starts)
        self._dur = np.array(durations)
        self._dir = np.array(dirs).reshape(-1, 3)
        self._start_list, self._dur_list = list(starts), list(durations)  # scalar look-ups in velocity()

    def velocity(self, t_s: float) -> np.ndarray:
        """(3,) wind velocity (ENU, m/s) at sim time ``t_s``."""
        w = self.mean.copy()
        i = bisect.bisect_right(self._start_list, t_s) - 1  # gusts never overlap: the latest started is the one
        if i >= 0:
            s, dur = t_s - self._start_list[i], self._dur_list[i]
            if s < dur:
                w += 0.5 * self.gust_mps * (1.0 - math.cos(2.0 * math.pi * s / dur)) * self._dir[i]
        return w


@dataclass(frozen=True)
class ImuReading:
    """One IMU sample (body FLU): specific force (3,) m/s², angular rate (3,) rad/s, attitude (x, y, z, w)."""

    specific_force_mps2: np.ndarray
    angular_velocity_radps: np.ndarray
    orientation_xyzw: np.ndarray


@dataclass(frozen=True)
class UavTruth:
    """True state: position (3,) ENU m, attitude (w, x, y, z) FLU → ENU, velocity (3,) ENU m/s, body rates (3,)
    FLU rad/s."""

    position_m: np.ndarray
    quat_wxyz: np.ndarray
    velocity_mps: np.ndarray
    angular_velocity_radps: np.ndarray


class UavSimulator:
    """The quadrotor scene stepped in MuJoCo, with wind and noisy sensors.

    Args:
        world: UAV scene name (``field``) or MJCF path with the quadrotor attached under prefix ``uav/``.
        seed: seed of the wind and every sensor's noise.
        wind_mps, gust_mps: mean wind and peak gust speed, m/s.
        drag_area_m2: C_d·A of the airframe, m² (quadratic drag against the relative wind).
        noise: sensor noise.
        origin: geodetic position of the ENU origin.
        params: the vehicle's rotor constants (k_f, maximum speed); the MJCF carries mass, inertia and k_m / k_f.

    Raises:
        UnknownWorldError, ModelLoadError: the scene cannot be found or compiled, or lacks the quadrotor.
    """

    def __init__(
        self,
        world: str | Path = "field",
        *,
        seed: int = 0,
        wind_mps: float = 0.0,
        gust_mps: float = 0.0,
        drag_area_m2: float = 0.05,
        noise: UavNoise | None = None,
        origin: GeodeticOrigin | None = None,
        params: QuadrotorParams | None = None,
    ) -> None:
        self.path = resolve_uav_world(world)
        try:
            self.model = mujoco.MjSpec.from_file(str(self.path)).compile()
        except Exception as exc:  # MuJoCo raises ValueError with the parser's message
            raise ModelLoadError(f"{self.path}: {exc}") from exc
        m = self.model
        self.data = mujoco.MjData(m)
        self.rng = np.random.default_rng(seed)
        self.params = params or QuadrotorParams()
        self.noise = noise or UavNoise()
        self.origin = origin or GeodeticOrigin()
        if not (math.isfinite(drag_area_m2) and drag_area_m2 >= 0.0):
            raise InvalidCommandError(f"drag_area_m2 must be finite and >= 0, got {drag_area_m2}")
        self.drag_area_m2 = drag_area_m2
        self.wind = Wind(wind_mps, gust_mps, self.rng)

        def ident(kind: mujoco.mjtObj, name: str) -> int:
            i = int(mujoco.mj_name2id(m, kind, PREFIX + name))
            if i < 0:
                raise ModelLoadError(f"{self.path}: no {kind.name[6:].lower()} {PREFIX + name} (the quadrotor)")
            return i

        obj = mujoco.mjtObj
        self.body_id = ident(obj.mjOBJ_BODY, "base_link")
        joint = ident(obj.mjOBJ_JOINT, "root")
        self._qpos = int(m.jnt_qposadr[joint])
        self._qvel = int(m.jnt_dofadr[joint])
        self.rotor_ids = np.array([ident(obj.mjOBJ_ACTUATOR, f"rotor{i}") for i in range(4)])
        self._sensor = {
            name: int(m.sensor_adr[ident(obj.mjOBJ_SENSOR, name)]) for name in ("imu_accel", "imu_gyro", "imu_quat")
        }
        self._uav_geoms = {g for g in range(m.ngeom) if int(m.geom_bodyid[g]) == self.body_id}
        floor = int(mujoco.mj_name2id(m, obj.mjOBJ_GEOM, "floor"))
        self._floor = floor
        self.camera = PREFIX + "chase"
        self.accel_bias = self.rng.normal(size=3) * self.noise.accel_bias_mps2
        self.rotor_speed_cmd = np.zeros(4)
        self.collisions = 0
        self._touching = False
        self._v_before: np.ndarray | None = None
        self._t_before = 0.0
        mujoco.mj_forward(m, self.data)
        o = self.origin
        enu_to_geodetic(0.0, 0.0, 0.0, o.lat_deg, o.lon_deg, o.alt_m)  # load the compiled kernel now, not mid-flight

    @property
    def time_s(self) -> float:
        """Sim time, seconds."""
        return float(self.data.time)

    @property
    def timestep_s(self) -> float:
        """Physics step, seconds."""
        return float(self.model.opt.timestep)

    def set_rotor_speeds(self, speeds_rad_s: np.ndarray) -> None:
        """Command the four rotor speeds (rad/s, PX4 quad-X order), clipped to [0, max]; thrust ``k_f ω²``.

        Raises:
            InvalidCommandError: not four finite numbers.
        """
        w = np.asarray(speeds_rad_s, dtype=np.float64)
        if w.shape != (4,) or not np.all(np.isfinite(w)):
            raise InvalidCommandError(f"rotor speeds must be four finite numbers, got {speeds_rad_s!r}")
        p = self.params
        self.rotor_speed_cmd = np.clip(w, 0.0, p.max_rotor_speed_rad_s)
        self.data.ctrl[self.rotor_ids] = p.thrust_coeff * self.rotor_speed_cmd**2

    def step(self, n: int = 1) -> None:
        """Advance ``n`` physics steps with the wind force of the current time held."""
        d = self.data
        v = d.qvel[self._qvel : self._qvel + 3]
        rel = self.wind.velocity(self.time_s) - v
        d.xfrc_applied[self.body_id, 0:3] = 0.5 * RHO_AIR * self.drag_area_m2 * float(np.linalg.norm(rel)) * rel
        self._v_before = d.qvel[self._qvel : self._qvel + 3].copy()
        self._t_before = self.time_s
        mujoco.mj_step(self.model, d, nstep=n)
        touching = self._touches_obstacle()
        if touching and not self._touching:
            self.collisions += 1
        self._touching = touching

    def _touches_obstacle(self) -> bool:
        d = self.data
        for i in range(d.ncon):
            c = d.contact[i]
            g1, g2 = int(c.geom1), int(c.geom2)
            if (g1 in self._uav_geoms) != (g2 in self._uav_geoms) and self._floor not in (g1, g2):
                return True
        return False

    def truth(self) -> UavTruth:
        """The true state now."""
        d = self.data
        q = d.qpos[self._qpos : self._qpos + 7]
        v = d.qvel[self._qvel : self._qvel + 6]
        return UavTruth(q[0:3].copy(), q[3:7].copy(), v[0:3].copy(), v[3:6].copy())

    def imu(self) -> ImuReading:
        """Noisy IMU sample now (specific force with bias, rate, attitude), body FLU.

        The specific force is the mean over the last :meth:`step` call — from the change of velocity, like the
        delta-velocity output of a real IMU — so a filter predicting at the sample rate integrates the true
        motion; before the first step it is the accelerometer sensor's reading.
        """
        d, n, s = self.data, self.noise, self._sensor
        if self._v_before is None:
            acc = d.sensordata[s["imu_accel"] : s["imu_accel"] + 3].copy()
        else:
            dt = self.time_s - self._t_before
            mean_world = (d.qvel[self._qvel : self._qvel + 3] - self._v_before) / dt - self.model.opt.gravity
            xmat = d.xmat[self.body_id].reshape(3, 3)  # body → world
            acc = xmat.T @ mean_world
        z9 = self.rng.normal(size=9)  # accelerometer, gyro, attitude noise
        acc = acc + self.accel_bias + z9[0:3] * n.accel_mps2
        gyro = d.sensordata[s["imu_gyro"] : s["imu_gyro"] + 3] + z9[3:6] * n.gyro_radps
        w, x, y, z = (float(v) for v in d.sensordata[s["imu_quat"] : s["imu_quat"] + 4])
        ha = 0.5 * n.attitude_rad  # small body-frame rotation error
        ew, ex, ey, ez = 1.0, ha * float(z9[6]), ha * float(z9[7]), ha * float(z9[8])
        qw = w * ew - x * ex - y * ey - z * ez
        qx = w * ex + x * ew + y * ez - z * ey
        qy = w * ey - x * ez + y * ew + z * ex
        qz = w * ez + x * ey - y * ex + z * ew
        norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        return ImuReading(acc, gyro, np.array([qx, qy, qz, qw]) / norm)

    def gps_fix(self) -> tuple[float, float, float]:
        """Noisy GPS fix of the true position now: (latitude deg, longitude deg, altitude m above the ellipsoid)."""
        e, n, u = self.truth().position_m + self.rng.normal(size=3) * self.noise.gps_m
        o = self.origin
        lat, lon, alt = enu_to_geodetic(e, n, u, o.lat_deg, o.lon_deg, o.alt_m)
        return float(lat), float(lon), float(alt)

    def baro_pa(self) -> float:
        """Noisy static pressure (Pa) at the true altitude (origin altitude + z)."""
        h = self.origin.alt_m + float(self.data.qpos[self._qpos + 2])
        return pressure_at_altitude(h) + float(self.rng.normal()) * self.noise.baro_pa

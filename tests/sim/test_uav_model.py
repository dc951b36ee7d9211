"""The quadrotor MJCF and the UAV simulator: compiles, thrust and reaction-torque signs, sensors, wind."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from mjnav.aerial import QuadrotorParams, geodetic_to_enu, mixer_matrix
from mjnav.aerial.rep103 import flu_to_frd
from mjnav.sim.errors import InvalidCommandError, UnknownWorldError
from mjnav.sim.uav import UavNoise, UavSimulator, Wind, pressure_at_altitude, uav_worlds
from mjnav.sim.worlds import MJCF_DIR, available_worlds

QUIET = UavNoise(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def _free_flyer() -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The quadrotor alone, gravity off, so a rotor's wrench shows in the accelerations."""
    spec = mujoco.MjSpec.from_file(str(MJCF_DIR / "quadrotor.xml"))
    model = spec.compile()
    model.opt.gravity[:] = 0.0
    return model, mujoco.MjData(model)


def test_the_quadrotor_and_its_field_compile_and_are_not_ground_worlds() -> None:
    model, _ = _free_flyer()
    assert model.nu == 4 and model.nbody == 2 and model.body_mass[1] == pytest.approx(1.0)
    np.testing.assert_allclose(model.body_inertia[1], QuadrotorParams().inertia_kgm2)
    assert {model.sensor(i).name for i in range(model.nsensor)} == {"imu_accel", "imu_gyro", "imu_quat"}
    assert "field" in uav_worlds()
    assert "quadrotor" not in available_worlds() and "field" not in available_worlds()
    with pytest.raises(UnknownWorldError):
        UavSimulator("no_such_field")


@pytest.mark.parametrize("rotor", [0, 1, 2, 3])
def test_each_rotor_pushes_up_and_twists_the_body_like_the_mixer(rotor: int) -> None:
    """One rotor's thrust T: force +z (FLU), torque = the library mixer's column (FRD) converted to FLU."""
    model, data = _free_flyer()
    p = QuadrotorParams()
    thrust = 2.0
    data.ctrl[rotor] = thrust
    data.act[rotor] = thrust  # the motor lag's state: the force follows it
    mujoco.mj_forward(model, data)
    acc = data.qacc.copy()  # free joint: linear (world = body at rest), then angular (body frame)
    np.testing.assert_allclose(acc[0:3], [0.0, 0.0, thrust / p.mass_kg], atol=1e-9)
    torque_flu = np.asarray(p.inertia_kgm2) * acc[3:6]
    expected_frd = mixer_matrix(p)[1:4, rotor] * thrust
    np.testing.assert_allclose(flu_to_frd(torque_flu), expected_frd, rtol=1e-5, atol=1e-9)
    # the reaction torque opposes the spin: counter-clockwise rotors 0 and 1 yaw the body clockwise (-z up)
    assert math.copysign(1.0, torque_flu[2]) == (-1.0 if rotor in (0, 1) else 1.0)


def test_hover_thrust_holds_the_vehicle_and_the_imu_reads_gravity() -> None:
    sim = UavSimulator("field", noise=QUIET)
    p = sim.params
    sim.set_rotor_speeds(np.full(4, p.hover_rotor_speed_rad_s))
    sim.step(50)
    start = sim.truth()
    # lift off the pad first so contact forces do not enter; then hover thrust keeps the velocity
    sim.step(500)
    a = sim.truth()
    sim.step(250)
    b = sim.truth()
    assert abs(b.velocity_mps[2] - a.velocity_mps[2]) < 1e-3 and start.position_m[2] > 0.05
    imu = sim.imu()
    np.testing.assert_allclose(imu.specific_force_mps2, [0.0, 0.0, p.gravity_mps2], atol=1e-3)
    np.testing.assert_allclose(imu.orientation_xyzw, [0.0, 0.0, 0.0, 1.0], atol=1e-9)
    with pytest.raises(InvalidCommandError):
        sim.set_rotor_speeds([1.0, 2.0, math.nan, 3.0])


def test_gps_and_baro_read_the_true_position_about_the_origin() -> None:
    sim = UavSimulator("field", noise=QUIET)
    lat, lon, alt = sim.gps_fix()
    o = sim.origin
    e, n, u = geodetic_to_enu(lat, lon, alt, o.lat_deg, o.lon_deg, o.alt_m)
    np.testing.assert_allclose([e, n, u], sim.truth().position_m, atol=1e-6)
    assert sim.baro_pa() == pytest.approx(pressure_at_altitude(o.alt_m + sim.truth().position_m[2]))
    assert pressure_at_altitude(0.0) == pytest.approx(101325.0) and pressure_at_altitude(1000.0) == pytest.approx(
        89874.6, rel=1e-4
    )  # ISA table


def test_wind_is_seeded_and_gusts_peak_at_their_amplitude() -> None:
    a = Wind(3.0, 6.0, np.random.default_rng(5))
    b = Wind(3.0, 6.0, np.random.default_rng(5))
    ts = np.arange(0.0, 60.0, 0.01)
    wa = np.array([a.velocity(t) for t in ts])
    np.testing.assert_array_equal(wa, np.array([b.velocity(t) for t in ts]))
    gust = np.linalg.norm(wa - a.mean, axis=1)
    assert np.linalg.norm(a.mean) == pytest.approx(3.0) and 5.9 < gust.max() <= 6.0 + 1e-9
    assert np.all(wa[:, 2] == 0.0)
    calm = Wind(0.0, 0.0, np.random.default_rng(0))
    assert not calm.velocity(10.0).any()
    with pytest.raises(InvalidCommandError):
        Wind(-1.0, 0.0, np.random.default_rng(0))
